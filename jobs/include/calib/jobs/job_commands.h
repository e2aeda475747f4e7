#pragma once
// The work behind `calib run`, `calib resume`, `calib results` and
// `calib best`: plain options in, a summary out; apps/calib_main.cpp only
// parses and prints. Bad input throws (JobSpecError, StoreError,
// std::invalid_argument, std::runtime_error) with a message naming the file,
// job or field.
//
// run:    creates the job in the store (an existing job of that name with
//         evaluations is an error: resume it), records the fingerprints of
//         its recordings (job_inputs.h), then runs it.
//         With `fresh`, a job of that name is deleted first (refused while
//         a live process holds it).
// resume: finds the job, checks that the spec is the one it was started
//         with (only threads, processes, checkpoint, budget.wall_time_s and
//         results may change: they do not change the history; and
//         budget.evaluations may grow, with the optimiser's own budget
//         setting, for the optimisers search::BudgetExtendsExactly names)
//         and that its recordings are unchanged (naming every file that
//         changed), and continues from the newest intact checkpoint. A
//         finished or aborted job is left as it is (its report is written
//         again), unless its budget grew: a finished job then continues to
//         the history a run with the larger budget gives.
// Both record the run (program version, host, time, command) in the store.
// Both hold the job's lock (job_lock.h) from before they change anything
// until they end: a job another live process works on is refused, naming
// that process.
// Under an MPI launcher with several ranks, rank 0 manages (optimiser,
// store, progress, report) and the other ranks evaluate (mpi_evaluator.h).

#include "calib/jobs/job_lock.h"
#include "calib/jobs/job_report.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/objective.h"
#include "calib/jobs/progress.h"
#include "calib/jobs/runner.h"
#include "calib/results/store.h"

#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace calib {

class MpiSession;

/// Builds a job's objective. The default (null) prepares every training
/// recording (RecordingObjective); tests pass synthetic objectives.
using ObjectiveFactory =
    std::function<std::unique_ptr<Objective>(const JobSpec& spec, const PreparationOptions&)>;

/// The default: CheckRecordings, PrepareRecording of each train recording
/// with `preparation`, a RecordingObjective with the spec's simulation options.
std::unique_ptr<Objective> MakeRecordingObjective(const JobSpec& spec,
                                                  const PreparationOptions& preparation);

enum class JobStart { kRun, kResume };

struct JobCommandOptions {
  /// OpenMP threads, overriding the spec's `threads` (0: all cores); unset:
  /// the spec's.
  std::optional<int> threads;
  /// Overrides the spec's results.store when set.
  std::optional<std::filesystem::path> store;
  /// Overrides the spec's budget.wall_time_s for this invocation when set.
  std::optional<double> wall_time_s;
  /// Segmentation cache: the default folder, another, or none.
  std::optional<std::filesystem::path> cache_dir;
  bool no_cache = false;
  /// Write the out_dir report (job_report.h) when the job stops.
  bool write_report = true;
  /// Simulate the best parameters on every recording for the report.
  bool report_simulations = true;
  /// Write overlay videos with those simulations.
  bool report_video = true;
  ProgressMode progress = ProgressMode::kAuto;
  /// Seconds between progress lines when progress is logged (not a terminal).
  double progress_interval_s = 10.0;
  int batch_size = kDefaultBatchSize;
  /// Heartbeat period and the silence after which a holder is taken over.
  JobLockOptions lock;
  /// Null: MakeRecordingObjective.
  ObjectiveFactory make_objective;
  /// Set when launched by MPI with several ranks (see MpiSession).
  const MpiSession* mpi = nullptr;
  /// run: delete a job of the same name first (start over).
  bool fresh = false;
  /// Recorded with the run (ResultStore::RecordJobRun): "calib 0.1.0", and
  /// what started it ("run", "resume", "serve").
  std::string program_version = "calib";
  std::string command;
  /// SIGINT, SIGTERM and SIGHUP stop the run resumably. False: they are left
  /// alone (a server that runs several jobs handles them itself).
  bool handle_signals = true;
  /// Polled between candidates: true stops the run resumably. Null: never.
  std::function<bool()> interrupted;
};

struct JobCommandResult {
  /// This process was an MPI worker rank: nothing ran here to report.
  bool mpi_worker = false;
  std::filesystem::path store;
  int64_t job = 0;
  /// Status kCreated (never run) when resume found the job finished or
  /// aborted and left it alone.
  RunSummary run;
  std::optional<JobReport> report;
  std::string objective;  ///< Objective::Describe()
};

/// `calib run` / `calib resume`. SIGINT, SIGTERM and SIGHUP stop the run
/// resumably (a second signal kills at once). The job is marked failed when
/// the run throws; the exception propagates. A job held by another live
/// process: JobLockedError, and nothing of the job changes.
JobCommandResult RunJob(const JobSpec& spec, JobStart start, const JobCommandOptions& options);

/// The store of `spec`: `store` when given, else the spec's results.store,
/// or, when the spec gives none and that store does not exist, the store at
/// the default place of earlier builds (results/<name>.sqlite beside the
/// spec) when it holds the job.
std::filesystem::path ResolveStorePath(const JobSpec& spec,
                                       const std::optional<std::filesystem::path>& store);

/// Where a job lives for `calib results` / `calib best`: JOB is a job spec
/// file (its results.store and name) or a job name with `store` given.
struct JobLocation {
  std::filesystem::path store;
  std::string name;
};
/// Throws std::invalid_argument when JOB is not a spec file and no store is
/// given; JobSpecError for a bad spec.
/// `overrides` as the job was run with (its --name decides its default store).
JobLocation LocateJob(const std::string& job, const std::optional<std::filesystem::path>& store,
                      const JobSpecOverrides& overrides = {});

/// Opens the store read-only and finds the job; StoreError naming the store
/// and the job (and the jobs it holds) when absent.
std::pair<ResultStore, int64_t> OpenJob(const JobLocation& location);

}  // namespace calib
