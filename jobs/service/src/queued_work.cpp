#include "queued_work.h"

#include "calib/discovery/loop_spec.h"
#include "calib/jobs/comparison.h"
#include "calib/jobs/job_commands.h"
#include "calib/jobs/job_lock.h"
#include "calib/service/data_roots.h"
#include "calib/service/service_error.h"
#include "mpi_launch.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <fstream>
#include <thread>

namespace calib::service {
namespace {

namespace fs = std::filesystem;

constexpr const char* kJobSource = "submitted spec";
constexpr const char* kLoopSource = "submitted loop spec";
constexpr const char* kComparisonSource = "submitted comparison spec";

JobSpecParseOptions ParseOptions(const ServiceOptions& options, RecordingCheck recordings) {
  JobSpecParseOptions parse;
  parse.recordings = recordings;
  parse.results_root = options.reports();
  return parse;
}

// The spec the server runs: results in its store, the report in its folder.
void PlaceResults(const ServiceOptions& options, JobSpec* spec) {
  spec->results.store = fs::absolute(options.store());
  spec->results.out_dir = fs::absolute(WorkFolder(options, spec->name));
  spec->results.earlier_default_store.clear();
}

// An external optimiser runs the program its settings name: a client of the
// service would run any program on the server, which reads no more than its
// data roots.
void RefuseExternal(const std::string& optimizer, const std::string& source, const std::string& key) {
  if (optimizer != "external") return;
  throw ServiceError(403, "spec",
                     fmt::format("{}: {} = 'external': runs a program on the server, which the "
                                 "service does not do (run it on the command line)",
                                 source, key));
}

// Where the recordings are is checked before whether they exist: nothing
// outside the data roots is looked at.
ValidatedWork ValidateJob(const std::string& text, const ServiceOptions& options) {
  JobSpec spec;
  try {
    spec = ParseJobSpec(text, kJobSource, options.data_roots.front(),
                        ParseOptions(options, RecordingCheck::kNone));
    RequireRecordingsInsideDataRoots(spec.train, spec.holdout, options.data_roots);
    spec = ParseJobSpec(text, kJobSource, options.data_roots.front(),
                        ParseOptions(options, RecordingCheck::kExists));
    CheckRecordings(spec);
  } catch (const JobSpecError& e) {
    throw ServiceError(400, "spec", e.what());
  }
  RefuseExternal(spec.optimizer.name, kJobSource, "optimizer.name");
  ValidatedWork work;
  work.name = spec.name;
  const fs::path default_store = fs::absolute(options.reports() / (spec.name + ".sqlite")).lexically_normal();
  const fs::path default_out = fs::absolute(WorkFolder(options, spec.name)).lexically_normal();
  if (spec.results.store != default_store || spec.results.out_dir != default_out) {
    work.notices.push_back(fmt::format(
        "results.store and results.out_dir of a submitted spec are ignored: the server keeps "
        "the job in its store {} and its report in {}",
        options.store().string(), WorkFolder(options, spec.name).string()));
  }
  PlaceResults(options, &spec);
  work.queued_spec = ToJson(spec);
  return work;
}

LoopSpec ReadLoopSpec(const std::string& text, const ServiceOptions& options) {
  try {
    return ParseLoopSpec(text, kLoopSource, options.data_roots.front());
  } catch (const LoopSpecError& e) {
    throw ServiceError(400, "spec", e.what());
  }
}

ValidatedWork ValidateLoop(const std::string& text, const ServiceOptions& options) {
  const LoopSpec spec = ReadLoopSpec(text, options);
  RequireRecordingsInsideDataRoots(spec.options.train, spec.options.holdout, options.data_roots);
  try {
    CheckRecordings(kLoopSource, spec.options.train, spec.options.holdout);
  } catch (const JobSpecError& e) {
    throw ServiceError(400, "spec", e.what());
  }
  RefuseExternal(spec.options.optimizer, kLoopSource, "optimizer");
  return {spec.name, ToJson(spec), nlohmann::json::array()};
}

ComparisonSpec ReadComparisonSpec(const std::string& text, const ServiceOptions& options,
                                  const fs::path& out_dir, RecordingCheck recordings) {
  try {
    return ParseComparisonSpec(text, kComparisonSource, options.data_roots.front(), out_dir,
                               ParseOptions(options, recordings));
  } catch (const JobSpecError& e) {
    throw ServiceError(400, "spec", e.what());
  }
}

ValidatedWork ValidateComparison(const std::string& text, const ServiceOptions& options) {
  ComparisonSpec spec = ReadComparisonSpec(text, options, options.reports(), RecordingCheck::kNone);
  for (const ComparisonRun& run : spec.runs) {
    RequireRecordingsInsideDataRoots(run.job.train, run.job.holdout, options.data_roots);
  }
  for (size_t i = 0; i < spec.optimizers.size(); ++i) {
    RefuseExternal(spec.optimizers[i].name, kComparisonSource, fmt::format("optimizers[{}].name", i));
  }
  spec = ReadComparisonSpec(text, options, WorkFolder(options, spec.name), RecordingCheck::kExists);
  try {
    CheckRecordings(spec.runs.front().job);
  } catch (const JobSpecError& e) {
    throw ServiceError(400, "spec", e.what());
  }
  // The text is kept as submitted (its paths relative to the data root);
  // the counts are what the status shows as its budget.
  const auto runs = static_cast<int64_t>(spec.runs.size());
  return {spec.name,
          {{"text", text}, {"runs", runs}, {"budget", runs * spec.budget_evaluations}},
          nlohmann::json::array()};
}

// What a job's run ended with, as the store has it.
WorkOutcome StoredOutcome(const ServiceOptions& options, const std::string& name) {
  StoreOptions read_only;
  read_only.read_only = true;
  const std::optional<JobInfo> job = ResultStore(options.store(), read_only).FindJob(name);
  if (!job) return {false, "not run"};
  return {job->status == JobStatus::kStopped, fmt::format("{}: {}", ToString(job->status), job->stop_reason)};
}

// A manager started by an earlier server (killed; its launcher then told to
// stop) may hold the job of `store` a moment longer: wait until it has
// stopped, as calib-mpirun.sh waits before it resumes.
void WaitForRelease(const fs::path& store_path, const std::string& name,
                    const std::function<bool()>& interrupted) {
  if (!fs::exists(store_path)) return;
  const JobLockOptions lock;
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration<double>(lock.stale_after_s + lock.heartbeat_s);
  while (std::chrono::steady_clock::now() < deadline && !interrupted()) {
    ResultStore store(store_path);
    const std::optional<JobInfo> job = store.FindJob(name);
    if (!job) return;
    const std::optional<JobLock> holder = store.JobLockHolder(job->id);
    if (!holder || JobLockHolderStopped(*holder, NowUnixSeconds() - holder->heartbeat_unix_s, lock)) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

// As `scripts/calib-mpirun.sh --hosts HOSTS SPEC` (calib run, or resume for
// a job the store holds) with the spec the server runs, written to
// <state_dir>/mpi/<name>.json; the launcher's output beside it (.log).
WorkOutcome RunJobOnMpiHosts(const JobSpec& spec, const ServiceOptions& options,
                             const std::function<bool()>& interrupted) {
  const fs::path folder = options.state_dir / "mpi";
  fs::create_directories(folder);
  const fs::path spec_file = fs::absolute(folder / (spec.name + ".json"));
  {
    // Every path absolute: the ranks read the file where it is.
    JobSpec absolute = spec;
    absolute.base_dir.clear();
    std::ofstream out(spec_file);
    out << ToJson(absolute).dump(1) << "\n";
    if (!out) throw std::runtime_error(fmt::format("{}: cannot write", spec_file.string()));
  }
  std::vector<std::string> args = {"--progress", "log", "--progress-interval", "10"};
  if (!options.write_report) args.push_back("--no-report");
  if (!options.report_video) args.push_back("--no-video");
  WaitForRelease(options.store(), spec.name, interrupted);
  const int code = RunOnMpiHosts(options, spec_file, args, folder / (spec.name + ".log"), interrupted);
  WorkOutcome outcome = StoredOutcome(options, spec.name);
  outcome.stopped = code == 4;
  return outcome;
}

WorkOutcome RunJobEntry(const QueueEntry& entry, const ServiceOptions& options,
                        const std::function<bool()>& interrupted) {
  const JobSpec spec = ServiceJobSpec(entry.spec, options);
  if (!options.mpi_hosts.empty()) return RunJobOnMpiHosts(spec, options, interrupted);
  JobCommandOptions run;
  run.threads = options.threads_per_job;
  run.write_report = options.write_report;
  run.report_video = options.report_video;
  run.progress = ProgressMode::kNone;
  run.handle_signals = false;
  run.interrupted = interrupted;
  run.program_version = options.program_version;
  run.command = "serve";
  bool exists = false;
  {
    ResultStore store(options.store());
    exists = store.FindJob(spec.name).has_value();
  }
  // A job already in the store continues (after a restart, a cancel, an
  // extended budget); RunJob starts afresh one that recorded nothing yet.
  const JobCommandResult result = RunJob(spec, exists ? JobStart::kResume : JobStart::kRun, run);
  WorkOutcome outcome;
  outcome.stopped = result.run.status == JobStatus::kStopped;
  outcome.message = result.run.status == JobStatus::kCreated
                        ? result.run.stop_reason
                        : fmt::format("{}: {}", ToString(result.run.status), result.run.stop_reason);
  return outcome;
}

// As `calib loop --out FOLDER [--resume]` with the spec's options.
WorkOutcome RunLoopEntry(const QueueEntry& entry, const ServiceOptions& options,
                         const std::function<bool()>& interrupted) {
  LoopSpec spec = ReadLoopSpec(entry.spec.dump(), options);
  LoopOptions& loop = spec.options;
  loop.out_dir = WorkFolder(options, entry.name);
  loop.threads = options.threads_per_job;
  loop.resume = entry.resume;
  loop.interrupted = interrupted;
  loop.command = fmt::format("{} serve: loop {}", options.program_version, entry.name);
  const std::string name = entry.name;
  try {
    const LoopResult result =
        RunLoop(loop, [name](const std::string& line) { spdlog::info("loop '{}': {}", name, line); });
    return {false, fmt::format("finished: {} effect(s) kept; report {}", result.report.effects_kept.size(),
                               result.report_json.filename().string())};
  } catch (const LoopStopped& e) {
    return {true, e.what()};
  }
}

// As `scripts/calib-mpirun.sh --hosts HOSTS --compare SPEC --out FOLDER
// --base-dir DATA_ROOT`: the submitted text written to
// <state_dir>/mpi/<name>.yaml (its recordings relative to the first data
// root, as the server reads them), the launcher's output beside it (.log).
WorkOutcome RunComparisonOnMpiHosts(const QueueEntry& entry, const ComparisonSpec& spec,
                                    const ServiceOptions& options,
                                    const std::function<bool()>& interrupted) {
  const fs::path folder = options.state_dir / "mpi";
  fs::create_directories(folder);
  const fs::path spec_file = fs::absolute(folder / (entry.name + ".yaml"));
  {
    std::ofstream out(spec_file);
    out << entry.spec.at("text").get<std::string>();
    if (!out) throw std::runtime_error(fmt::format("{}: cannot write", spec_file.string()));
  }
  for (const ComparisonRun& run : spec.runs) WaitForRelease(spec.store, run.job.name, interrupted);
  const std::vector<std::string> args = {"--out", fs::absolute(spec.out_dir).string(), "--base-dir",
                                         fs::absolute(options.data_roots.front()).string(),
                                         "--progress", "log", "--progress-interval", "10"};
  const int code = RunOnMpiHosts(options, spec_file, args, folder / (entry.name + ".log"), interrupted,
                                 /*comparison=*/true);
  if (code == 4) return {true, "stopped"};
  const ComparisonAnalysis analysis = AnalyseComparison(LoadComparisonRuns(spec), AnalysisOptions(spec));
  return {false, fmt::format("finished: {}", analysis.verdict)};
}

// As `calib compare-optimizers SPEC --out FOLDER` (run again: continued).
WorkOutcome RunComparisonEntry(const QueueEntry& entry, const ServiceOptions& options,
                               const std::function<bool()>& interrupted) {
  const ComparisonSpec spec = ReadComparisonSpec(entry.spec.at("text").get<std::string>(), options,
                                                 WorkFolder(options, entry.name), RecordingCheck::kExists);
  if (!options.mpi_hosts.empty()) return RunComparisonOnMpiHosts(entry, spec, options, interrupted);
  ComparisonOptions run;
  run.threads = options.threads_per_job;
  run.progress = ProgressMode::kNone;
  run.handle_signals = false;
  run.interrupted = interrupted;
  run.program_version = options.program_version;
  const ComparisonResult result = RunComparison(spec, spec.out_dir, run);
  if (result.stopped) return {true, "stopped"};
  return {false, fmt::format("finished: {}", result.analysis->verdict)};
}

}  // namespace

std::string SubmittedSource(QueueKind kind) {
  switch (kind) {
    case QueueKind::kLoop:
      return kLoopSource;
    case QueueKind::kComparison:
      return kComparisonSource;
    case QueueKind::kJob:
      break;
  }
  return kJobSource;
}

fs::path WorkFolder(const ServiceOptions& options, const std::string& name) {
  return options.reports() / name;
}

fs::path OwnStore(const ServiceOptions& options, const QueueEntry& entry) {
  switch (entry.kind) {
    case QueueKind::kLoop:
      return WorkFolder(options, entry.name) / "store.sqlite";
    case QueueKind::kComparison:
      return WorkFolder(options, entry.name) / "comparison.sqlite";
    case QueueKind::kJob:
      break;
  }
  return {};
}

JobSpec ServiceJobSpec(const nlohmann::json& canonical, const ServiceOptions& options) {
  JobSpec spec = ParseJobSpec(canonical, kJobSource, options.data_roots.front(),
                              ParseOptions(options, RecordingCheck::kExists));
  PlaceResults(options, &spec);
  return spec;
}

ValidatedWork ValidateSubmitted(QueueKind kind, const std::string& text, const ServiceOptions& options) {
  switch (kind) {
    case QueueKind::kLoop:
      return ValidateLoop(text, options);
    case QueueKind::kComparison:
      return ValidateComparison(text, options);
    case QueueKind::kJob:
      break;
  }
  return ValidateJob(text, options);
}

WorkOutcome RunQueued(const QueueEntry& entry, const ServiceOptions& options,
                      const std::function<bool()>& interrupted) {
  switch (entry.kind) {
    case QueueKind::kLoop:
      return RunLoopEntry(entry, options, interrupted);
    case QueueKind::kComparison:
      return RunComparisonEntry(entry, options, interrupted);
    case QueueKind::kJob:
      break;
  }
  return RunJobEntry(entry, options, interrupted);
}

}  // namespace calib::service
