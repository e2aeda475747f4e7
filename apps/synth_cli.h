#pragma once
// The synth subcommand of calib: one synthetic recording from a scenario
// (`calib synth SCENARIO --out DIR`) or a scene family from a family spec
// (`calib synth --family SPEC --count N --seed S --out DIR`), docs/scenario.md.

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>

namespace calib::cli {

struct SynthCli;

/// Adds `synth` to `app`; the returned object holds its options and must
/// outlive parsing.
std::shared_ptr<SynthCli> AddSynthSubcommand(CLI::App& app);

/// After parsing: when `synth` was chosen, makes the recording or family,
/// prints where it wrote and how long it took, and returns 0; nullopt
/// otherwise. Bad input throws (the caller prints it and exits 2).
std::optional<int> RunChosenSynthSubcommand(SynthCli& cli);

}  // namespace calib::cli
