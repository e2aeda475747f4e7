#pragma once
// `calib compare-optimizers SPEC --out DIR [--threads N]`: several
// optimisers and seeds on one objective, each run a job of one results
// store, and a report with statistics (docs/compare.md).

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
/// nullopt otherwise. Bad input throws (the caller prints it, exit 2).
std::optional<int> RunChosenCompareSubcommand(CompareCli& cli);

}  // namespace calib::cli
