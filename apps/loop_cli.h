#pragma once
// The loop subcommands of calib: `calib loop --train REC... [--holdout REC...]
// --out DIR` (discovery/include/calib/discovery/loop.h) and `calib
// loop-benchmark FAMILY_DIR --out DIR` (loop_benchmark.h), which share the
// loop's options (docs/loop.md).

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

struct LoopBenchmarkCli;

/// Adds `loop-benchmark` to `app`, as AddLoopSubcommand.
std::shared_ptr<LoopBenchmarkCli> AddLoopBenchmarkSubcommand(CLI::App& app);

/// After parsing: when `loop-benchmark` was chosen, runs it, prints the
/// main rates and where the outputs are, and returns 0; nullopt otherwise.
/// Bad input throws (the caller prints it and exits 2).
std::optional<int> RunChosenLoopBenchmarkSubcommand(LoopBenchmarkCli& cli, int argc, char** argv);

}  // namespace calib::cli
