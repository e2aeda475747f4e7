#pragma once
// The work behind `calib compare-optimizers` (docs/compare.md): every run of
// a comparison spec (comparison_spec.h) as an ordinary job of one results
// store, then the analysis and the report.
//
// Resume. Running a comparison again continues it: a run whose job is
// finished or aborted is not run again (but its spec and recordings must be
// the ones it ran with, else the error names the job and what changed), a job left stopped or interrupted
// (a kill) is resumed exactly (job_commands.h), the others are run. Each
// run's history depends only on its spec and seed, so a comparison killed
// at any moment and run again gives the results of an uninterrupted one, at
// any thread count.
//
// MPI. Under an MPI launcher (ComparisonOptions::mpi with several ranks)
// the runs still go one after the other, each spread over every rank as a
// job under MPI is (mpi_evaluator.h): rank 0 runs the optimisers, the store
// and the report, and tells the other ranks which run comes next. A run's
// history is the one threads give, so the comparison's numbers are too.

#include "calib/jobs/comparison_spec.h"
#include "calib/jobs/job_commands.h"
#include "calib/results/comparison_analysis.h"
#include "calib/results/comparison_report.h"

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace calib {

struct ComparisonOptions {
  /// OpenMP threads per run, overriding the spec's `threads`.
  std::optional<int> threads;
  /// Segmentation cache: the default folder, another, or none.
  std::optional<std::filesystem::path> cache_dir;
  bool no_cache = false;
  ProgressMode progress = ProgressMode::kAuto;
  double progress_interval_s = 10.0;
  JobLockOptions lock;
  /// Null: the training recordings, prepared once for every run. Tests pass
  /// analytic objectives.
  ObjectiveFactory make_objective;
  ComparisonReportOptions report;
  /// As JobCommandOptions': whether the runs stop on SIGINT / SIGTERM /
  /// SIGHUP (handlers installed while each runs), and a poll that stops the
  /// run in progress resumably (ComparisonResult::stopped) when true.
  bool handle_signals = true;
  std::function<bool()> interrupted;
  /// Recorded with each run of a job (JobCommandOptions::program_version),
  /// the command as "compare-optimizers".
  std::string program_version = "calib";
  /// Set when launched by MPI with several ranks (MpiSession); the same
  /// spec on every rank.
  const MpiSession* mpi = nullptr;
};

struct ComparisonResult {
  std::filesystem::path store;
  int runs = 0;          ///< in the spec
  int already_done = 0;  ///< finished or aborted before this invocation
  int run_now = 0;       ///< run or resumed by this invocation
  /// A run stopped resumably (a signal, the wall time): the comparison
  /// stopped there, without a report.
  bool stopped = false;
  std::optional<ComparisonAnalysis> analysis;  ///< set when every run is done
  std::optional<ComparisonReportSummary> report;
  /// This process was an MPI worker rank: it evaluated, and has nothing to
  /// report.
  bool mpi_worker = false;
};

/// Runs (or continues) the comparison and, once every run is done, writes
/// the report into `out_dir` with `comparison.json` (ComparisonSpec::ToJson).
/// Errors as RunJob's.
ComparisonResult RunComparison(const ComparisonSpec& spec, const std::filesystem::path& out_dir,
                               const ComparisonOptions& options);

/// Where the comparison stands, without running anything: a line per run
/// ("cmaes seed 3 (job NAME.cmaes.s3): finished (...), 480 evaluations",
/// the status as `calib results` gives it: a run left running by a process
/// that has stopped is "interrupted") and a last line counting the runs by
/// status ("109 runs: 40 finished, 1 running, 68 not started").
std::string ComparisonStatusText(const ComparisonSpec& spec);

/// Every run's evaluations from the comparison's store, in spec order; a
/// run not in the store has none.
std::vector<ComparisonRunData> LoadComparisonRuns(const ComparisonSpec& spec);

/// The analysis options a spec asks for.
ComparisonAnalysisOptions AnalysisOptions(const ComparisonSpec& spec);

}  // namespace calib
