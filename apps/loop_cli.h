#pragma once
// The loop subcommand of calib: `calib loop --train REC... [--holdout REC...]
// --out DIR` (jobs/include/calib/discovery/loop.h, docs/loop.md).

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>

namespace calib::cli {

struct LoopCli;

/// Adds `loop` to `app`; the returned object holds its options and must
/// outlive parsing.
std::shared_ptr<LoopCli> AddLoopSubcommand(CLI::App& app);

/// After parsing: when `loop` was chosen, runs it, prints the before / after
/// table and where the report is, and returns 0; nullopt otherwise. Bad
/// input throws (the caller prints it and exits 2).
std::optional<int> RunChosenLoopSubcommand(LoopCli& cli, int argc, char** argv);

}  // namespace calib::cli
