#include "calib/jobs/job_commands.h"

#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/job_inputs.h"
#include "calib/jobs/job_lock.h"
#include "calib/jobs/mpi_evaluator.h"
#include "calib/search/factory.h"

#include <fmt/format.h>

#include <fstream>

#include <unistd.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <csignal>
#include <optional>
#include <stdexcept>
#include <utility>

namespace calib {
namespace {

volatile std::sig_atomic_t g_interrupted = 0;

extern "C" void OnStopSignal(int) { g_interrupted = 1; }

// SIGINT, SIGTERM and SIGHUP (a closed terminal or SSH session) set a flag
// the runner polls between candidates: the job stops resumably. The handler
// resets itself, so a second signal ends the process at once.
class ScopedStopSignals {
 public:
  ScopedStopSignals() {
    g_interrupted = 0;
    struct sigaction action {};
    action.sa_handler = OnStopSignal;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESETHAND;
    sigaction(SIGINT, &action, &old_int_);
    sigaction(SIGTERM, &action, &old_term_);
    sigaction(SIGHUP, &action, &old_hup_);
  }
  ~ScopedStopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
    sigaction(SIGHUP, &old_hup_, nullptr);
  }
  static bool Interrupted() { return g_interrupted != 0; }

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
  struct sigaction old_hup_ {};
};

PreparationOptions Preparation(const JobSpec& spec, const JobCommandOptions& options) {
  PreparationOptions preparation = spec.model.preparation;
  if (options.no_cache) {
    preparation.cache_dir.clear();
  } else if (options.cache_dir) {
    preparation.cache_dir = *options.cache_dir;
  }
  return preparation;
}

// Paths of the canonical spec JSON that may differ on resume: they change
// where things go and how fast, never the history.
bool ChangeAllowedOnResume(const std::string& path) {
  for (const char* prefix : {"/threads", "/processes", "/checkpoint", "/budget/wall_time_s",
                             "/results"}) {
    const std::string p(prefix);
    if (path == p || path.rfind(p + "/", 0) == 0) return true;
  }
  return false;
}

// The budget the stored spec gave (0 when it cannot be read).
int64_t StoredBudget(const JobInfo& info) {
  const nlohmann::json* budget = info.spec.is_object() && info.spec.contains("budget")
                                     ? &info.spec["budget"]
                                     : nullptr;
  if (budget == nullptr || !budget->is_object() || !budget->contains("evaluations") ||
      !(*budget)["evaluations"].is_number_integer()) {
    return 0;
  }
  return (*budget)["evaluations"].get<int64_t>();
}

// Returns true when the spec's budget grew (the job is extended).
bool CheckResumedSpec(const JobSpec& spec, ResultStore& store, const JobInfo& info) {
  const nlohmann::json now = ToJson(spec);
  if (now == info.spec) return false;
  const int64_t stored_budget = StoredBudget(info);
  const bool grown = stored_budget > 0 && spec.budget.evaluations > stored_budget;
  const std::string budget_setting = "/optimizer/settings/" + search::BudgetSetting(spec.optimizer.name);
  std::vector<std::string> changed;
  for (const auto& op : nlohmann::json::diff(info.spec, now)) {
    const std::string path = op.value("path", "");
    if (grown && (path == "/budget/evaluations" || path == budget_setting)) continue;
    if (!ChangeAllowedOnResume(path)) changed.push_back(path);
  }
  if (grown && changed.empty() && !search::BudgetExtendsExactly(spec.optimizer.name)) {
    throw std::invalid_argument(fmt::format(
        "{}: job '{}': budget.evaluations = {} (was {}): optimiser '{}' lays out its search for "
        "its budget, so a larger one continues with another history than a run with it from the "
        "start; start the job over instead (`calib run --fresh --budget {} {}`). Budgets extend "
        "for random, cmaes and genetic",
        spec.source, spec.name, spec.budget.evaluations, stored_budget, spec.optimizer.name,
        spec.budget.evaluations, spec.source));
  }
  if (!changed.empty()) {
    std::string list;
    for (const auto& p : changed) list += (list.empty() ? "" : ", ") + p;
    throw std::invalid_argument(fmt::format(
        "{}: job '{}' was started with another spec ({} differ{}); resume needs the same spec "
        "(only threads, processes, checkpoint, budget.wall_time_s and results may change, and "
        "budget.evaluations grow)",
        spec.source, spec.name, list, changed.size() == 1 ? "s" : ""));
  }
  store.SetJobSpec(info.id, now);
  return grown;
}

// Finds or creates the job for `start`; changes nothing in an existing job
// (that waits for its lock), except that `fresh` deletes it.
int64_t FindOrCreateJob(const JobSpec& spec, JobStart start, ResultStore& store,
                        const JobLockOptions& lock, bool fresh) {
  std::optional<JobInfo> info = store.FindJob(spec.name);
  if (start == JobStart::kRun && info && fresh) {
    // Refused while a live process holds it; the lock goes with the job.
    HeldJobLock held(store, info->id, spec.name, lock);
    store.DeleteJob(info->id);
    spdlog::info("{}: job '{}' deleted (--fresh): starting it over", store.path().string(),
                 spec.name);
    info.reset();
  }
  if (start == JobStart::kRun) {
    if (!info) return store.CreateJob(spec.name, ToJson(spec));
    // A job that never got going (created, nothing recorded) may be run again.
    if (store.EvaluationCount(info->id) == 0 && store.CheckpointCount(info->id) == 0) {
      return info->id;
    }
    throw std::invalid_argument(fmt::format(
        "{}: job '{}' already exists ({}, {} evaluations): continue it with `calib resume "
        "{}`, start it over with `calib run --fresh`, or give the job another name (--name) or "
        "store",
        store.path().string(), spec.name, JobStatusText(store, *info, lock),
        store.EvaluationCount(info->id), spec.source));
  }
  if (!info) {
    throw std::invalid_argument(
        fmt::format("{}: there is no job '{}' to resume: start it with `calib run {}`",
                    store.path().string(), spec.name, spec.source));
  }
  return info->id;
}

// With the job's lock held: the spec and the recordings must be those the
// job started with (a job run again before anything was recorded takes the
// new ones). False when resume finds nothing to do (finished or aborted).
bool PrepareHeldJob(const JobSpec& spec, JobStart start, ResultStore& store, int64_t job,
                    const std::vector<InputFingerprint>& inputs, RunSummary* left_alone) {
  const JobInfo info = store.Job(job);
  const bool extended = CheckResumedSpec(spec, store, info);
  if (start == JobStart::kResume &&
      ((info.status == JobStatus::kFinished && !extended) || info.status == JobStatus::kAborted)) {
    left_alone->status = JobStatus::kCreated;
    left_alone->stop_reason = fmt::format("the job is already {} ({})", ToString(info.status),
                                          info.stop_reason);
    return false;
  }
  const std::vector<InputFingerprint> recorded = store.JobInputs(job);
  // None recorded: a new job, or one started by a build that did not record them.
  if (start == JobStart::kResume && !recorded.empty()) {
    CheckJobInputsUnchanged(spec, recorded, inputs);
  } else {
    store.SetJobInputs(job, inputs);
  }
  return true;
}

}  // namespace

std::unique_ptr<Objective> MakeRecordingObjective(const JobSpec& spec,
                                                  const PreparationOptions& preparation) {
  CheckRecordings(spec);
  std::vector<std::shared_ptr<const PreparedRecording>> prepared;
  for (const auto& folder : spec.train) {
    prepared.push_back(
        std::make_shared<const PreparedRecording>(PrepareRecording(LoadRecording(folder), preparation)));
  }
  return std::make_unique<RecordingObjective>(std::move(prepared), spec.model.simulation,
                                              ModelDefinition{spec.model.effects});
}

namespace {

// The report is written when the job stops: a folder it cannot be written
// to is found now, not after every evaluation has run.
void CheckWritableFolder(const JobSpec& spec, const std::filesystem::path& dir) {
  auto fail = [&](const std::string& why) {
    throw JobSpecError(
        fmt::format("{}: results.out_dir = '{}': {}", spec.source, dir.string(), why));
  };
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) fail("cannot create the folder: " + ec.message());
  const std::filesystem::path probe = dir / fmt::format(".calib-write-check-{}", ::getpid());
  {
    std::ofstream out(probe);
    if (!out || !(out << "ok") || !out.flush()) fail("cannot write files there");
  }
  std::filesystem::remove(probe, ec);
}

JobReport WriteReport(const JobSpec& spec, ResultStore& store, int64_t job,
                      const PreparationOptions& preparation, const JobCommandOptions& options) {
  CommandSettings settings;
  settings.preparation = preparation;
  settings.simulation = spec.model.simulation;
  settings.model = ModelDefinition{spec.model.effects};
  JobReportOptions report_options;
  report_options.simulate = options.report_simulations;
  report_options.write_video = options.report_video;
  return WriteJobReport(spec, store, job, settings, report_options);
}

}  // namespace

JobCommandResult RunJob(const JobSpec& spec, JobStart start, const JobCommandOptions& options) {
  JobCommandResult out;
  if (options.write_report && !(options.mpi != nullptr && options.mpi->rank() != 0)) {
    CheckWritableFolder(spec, spec.results.out_dir);
  }
  const PreparationOptions preparation = Preparation(spec, options);
  const ObjectiveFactory make_objective =
      options.make_objective ? options.make_objective : ObjectiveFactory(MakeRecordingObjective);
  const bool use_mpi = options.mpi != nullptr && options.mpi->size() > 1;

  if (use_mpi && options.mpi->rank() != 0) {
    ScopedStopSignals ignore;  // the manager decides when to stop
    RunMpiWorker([&] { return make_objective(spec, preparation); }, options.mpi->rank());
    out.mpi_worker = true;
    return out;
  }

  // The manager's evaluator exists before anything can throw, so its
  // destructor always releases the workers.
  std::unique_ptr<MpiBatchEvaluator> mpi_evaluator;
  if (use_mpi) mpi_evaluator = std::make_unique<MpiBatchEvaluator>(options.mpi->size());

  // Named before any work: a thread count the machine cannot give, a
  // recording that cannot be read (fingerprinting reads them all).
  const int threads = use_mpi ? 1 : ResolveThreadCount(options.threads.value_or(spec.threads));
  const std::vector<InputFingerprint> inputs = FingerprintJobInputs(spec);

  out.store = ResolveStorePath(spec, options.store);
  if (!out.store.parent_path().empty()) std::filesystem::create_directories(out.store.parent_path());
  ResultStore store(out.store);
  out.job = FindOrCreateJob(spec, start, store, options.lock, options.fresh);
  // Before anything of the job changes: a second process is refused here.
  HeldJobLock lock(store, out.job, spec.name, options.lock);
  if (lock.taken_over()) {
    const JobLock& was = *lock.taken_over();
    spdlog::warn("{}: job '{}': took over the lock of {}, which has stopped", out.store.string(),
                 spec.name, DescribeJobLockHolder(was, lock.taken_over_age_s()));
  }
  if (!PrepareHeldJob(spec, start, store, out.job, inputs, &out.run)) {
    if (options.write_report) out.report = WriteReport(spec, store, out.job, preparation, options);
    return out;
  }
  JobRunRecord run_record;
  run_record.started_unix_s = std::chrono::duration<double>(
                                  std::chrono::system_clock::now().time_since_epoch())
                                  .count();
  run_record.program_version = options.program_version;
  run_record.host = ThisHostName();
  run_record.pid = ::getpid();
  run_record.command = options.command.empty()
                           ? std::string(start == JobStart::kRun ? "run" : "resume")
                           : options.command;
  store.RecordJobRun(out.job, run_record);

  std::unique_ptr<Objective> objective;
  std::unique_ptr<BatchEvaluator> evaluator;
  if (use_mpi) {
    out.objective = "evaluated by the worker ranks";
  } else {
    objective = make_objective(spec, preparation);
    out.objective = objective->Describe();
    evaluator = std::make_unique<ThreadBatchEvaluator>(*objective, threads);
  }

  ProgressDisplay progress(options.progress, options.progress_interval_s);
  std::optional<ScopedStopSignals> signals;
  if (options.handle_signals) signals.emplace();
  RunControl control;
  control.batch_size = options.batch_size;
  control.wall_time_s = options.wall_time_s ? options.wall_time_s : spec.budget.wall_time_s;
  control.interrupted = [&lock, &signals, &options] {
    return (signals && ScopedStopSignals::Interrupted()) ||
           (options.interrupted && options.interrupted()) || lock.lost();
  };
  try {
    if (mpi_evaluator) mpi_evaluator->WaitForWorkers();
    BatchEvaluator& batch_evaluator = mpi_evaluator ? *mpi_evaluator : *evaluator;
    out.run = RunCalibration(spec, store, out.job, batch_evaluator, control, &progress);
  } catch (const std::exception& e) {
    try {
      store.SetJobStatus(out.job, JobStatus::kFailed, e.what());
    } catch (const std::exception&) {
      // The store itself failed; the first error is the one to report.
    }
    throw;
  }
  if (mpi_evaluator) mpi_evaluator->StopWorkers();
  if (lock.lost()) {
    spdlog::warn("{}: job '{}': another process took over its lock (this one had stopped "
                 "heart-beating); stopped",
                 out.store.string(), spec.name);
  }

  if (options.write_report) out.report = WriteReport(spec, store, out.job, preparation, options);
  return out;
}

std::filesystem::path ResolveStorePath(const JobSpec& spec,
                                       const std::optional<std::filesystem::path>& store) {
  if (store) return *store;
  std::error_code ec;
  const std::filesystem::path& earlier = spec.results.earlier_default_store;
  if (earlier.empty() || std::filesystem::exists(spec.results.store, ec) ||
      !std::filesystem::is_regular_file(earlier, ec)) {
    return spec.results.store;
  }
  try {
    StoreOptions read_only;
    read_only.read_only = true;
    if (ResultStore(earlier, read_only).FindJob(spec.name)) {
      spdlog::info("{}: job '{}' is in this store, where jobs were stored by default before "
                   "out/jobs/; it stays there",
                   earlier.string(), spec.name);
      return earlier;
    }
  } catch (const StoreError&) {
    // Not a store this build reads: the default place it is.
  }
  return spec.results.store;
}

JobLocation LocateJob(const std::string& job, const std::optional<std::filesystem::path>& store,
                      const JobSpecOverrides& overrides) {
  JobLocation location;
  const std::filesystem::path path(job);
  std::error_code ec;
  if (std::filesystem::is_regular_file(path, ec)) {
    JobSpecParseOptions parse;
    parse.recordings = RecordingCheck::kNone;
    parse.overrides = overrides;
    const JobSpec spec = LoadJobSpec(path, parse);
    location.name = spec.name;
    location.store = ResolveStorePath(spec, store);
    return location;
  }
  if (!store) {
    throw std::invalid_argument(fmt::format(
        "'{}' is not a job spec file; to name a job by its name, give its store with --store",
        job));
  }
  location.name = overrides.name.value_or(job);
  location.store = *store;
  return location;
}

std::pair<ResultStore, int64_t> OpenJob(const JobLocation& location) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(location.store, ec)) {
    throw StoreError(fmt::format("{}: no results store there (has the job been run?)",
                                 location.store.string()));
  }
  StoreOptions options;
  options.read_only = true;
  ResultStore store(location.store, options);
  const std::optional<JobInfo> info = store.FindJob(location.name);
  if (!info) {
    std::string names;
    for (const JobInfo& j : store.Jobs()) names += (names.empty() ? "" : ", ") + j.name;
    throw StoreError(fmt::format("{}: no job '{}' (jobs there: {})", location.store.string(),
                                 location.name, names.empty() ? "none" : names));
  }
  const int64_t id = info->id;
  return {std::move(store), id};
}

}  // namespace calib
