#pragma once
// `calib compare-optimizers SPEC --out DIR [--threads N] [--status]`:
// several optimisers and seeds on one objective, each run a job of one
// results store, and a report with statistics (docs/compare.md). Under an
// MPI launcher rank 0 runs the comparison and the other ranks evaluate.

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>

namespace calib::cli {

struct CompareCli;

/// Adds `compare-optimizers` to `app`; the returned object holds its
/// options and must outlive parsing.
std::shared_ptr<CompareCli> AddCompareSubcommand(CLI::App& app);

/// After parsing: when `compare-optimizers` was chosen, runs (or continues)
/// the comparison, prints the verdict and where the report is, and returns
/// 0, or 4 when a run was stopped resumably (run it again to continue);
/// with --status prints where each run stands instead; nullopt when another
/// subcommand was chosen. Bad input throws (the caller prints it, exit 2).
/// argc and argv are MPI_Init's.
std::optional<int> RunChosenCompareSubcommand(CompareCli& cli, int argc, char** argv);

}  // namespace calib::cli
