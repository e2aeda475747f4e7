#pragma once
// The job subcommands of calib: run, resume, results, best, validate. Kept apart from
// calib_main.cpp so that each subcommand family owns its options.

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>
#include <string>

namespace calib::cli {

struct JobCli;

/// --progress, --progress-interval, --cache-dir and --no-cache, as `run`
/// and `resume` take them (compare-optimizers too).
void AddProgressAndCacheOptions(CLI::App* cmd, std::string* progress, double* progress_interval_s,
                                std::string* cache_dir, bool* no_cache);

/// Adds run, resume, results and best to `app`; the returned object holds
/// their options and must outlive parsing.
std::shared_ptr<JobCli> AddJobSubcommands(CLI::App& app);

/// After parsing: when one of the job subcommands was chosen, does it and
/// returns the exit status (0 finished, 3 aborted by the failure policy,
/// 4 stopped resumably: wall time or a signal); nullopt otherwise. Bad
/// input throws (the caller prints it and exits 2). Initialises MPI for
/// run and resume when started by an MPI launcher.
std::optional<int> RunChosenJobSubcommand(JobCli& cli, int argc, char** argv);

}  // namespace calib::cli
