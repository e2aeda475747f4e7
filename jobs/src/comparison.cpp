// Running an optimiser comparison (comparison.h).

#include "calib/jobs/comparison.h"

#include "calib/jobs/job_report.h"
#include "calib/jobs/mpi_evaluator.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>

namespace calib {
namespace {

// One objective shared by every run of the comparison: the recordings are
// prepared once.
class SharedObjective final : public Objective {
 public:
  explicit SharedObjective(std::shared_ptr<const Objective> objective) : objective_(std::move(objective)) {}
  std::unique_ptr<ObjectiveWorker> MakeWorker() const override { return objective_->MakeWorker(); }
  std::string Describe() const override { return objective_->Describe(); }

 private:
  std::shared_ptr<const Objective> objective_;
};

// The runs' objective is the same for every run (only the optimiser and the
// seed differ), so the first run's serves them all.
ObjectiveFactory SharedRecordingObjective() {
  auto shared = std::make_shared<std::shared_ptr<const Objective>>();
  return [shared](const JobSpec& spec, const PreparationOptions& preparation) -> std::unique_ptr<Objective> {
    if (!*shared) *shared = MakeRecordingObjective(spec, preparation);
    return std::make_unique<SharedObjective>(*shared);
  };
}

bool Done(JobStatus status) { return status == JobStatus::kFinished || status == JobStatus::kAborted; }

// On the manager of several ranks: tells the workers which run comes next,
// and on every way out (the last run done, a stop, an error) that none does.
class NextRunAnnouncer {
 public:
  explicit NextRunAnnouncer(const MpiSession* mpi) : size_(mpi ? mpi->size() : 1) {}
  ~NextRunAnnouncer() { Announce(-1); }
  NextRunAnnouncer(const NextRunAnnouncer&) = delete;
  NextRunAnnouncer& operator=(const NextRunAnnouncer&) = delete;

  void Announce(int32_t index) {
    if (size_ <= 1 || finished_) return;
    SendNextJob(size_, index);
    finished_ = index < 0;
  }

 private:
  int size_;
  bool finished_ = false;
};

// A worker rank: evaluates for each run the manager names, until it names
// none.
void RunComparisonWorker(const ComparisonSpec& spec, const JobCommandOptions& job_options) {
  while (true) {
    const int32_t index = ReceiveNextJob();
    if (index < 0) return;
    if (static_cast<size_t>(index) >= spec.runs.size()) {
      throw std::logic_error(fmt::format("MPI: the manager named run {} of {}", index, spec.runs.size()));
    }
    (void)RunJob(spec.runs[static_cast<size_t>(index)].job, JobStart::kRun, job_options);
  }
}

}  // namespace

ComparisonAnalysisOptions AnalysisOptions(const ComparisonSpec& spec) {
  ComparisonAnalysisOptions o;
  o.budget = spec.budget_evaluations;
  o.relative_targets = spec.targets.kind == TargetKind::kRelative;
  o.targets = spec.targets.values;
  return o;
}

std::string ComparisonStatusText(const ComparisonSpec& spec) {
  std::optional<ResultStore> store;
  if (std::filesystem::exists(spec.store)) {
    StoreOptions read_only;
    read_only.read_only = true;
    store.emplace(spec.store, read_only);
  }
  std::string text = fmt::format("comparison: {} (store {})\n", spec.name, spec.store.string());
  std::map<std::string, int> counts;
  for (const ComparisonRun& run : spec.runs) {
    const std::optional<JobInfo> info = store ? store->FindJob(run.job.name) : std::nullopt;
    std::string status = "not started";
    std::string count = "not started";
    if (info) {
      status = JobStatusText(*store, *info);
      // "running, by ..." and "interrupted (...)" counted by their first word.
      count = status.substr(0, status.find_first_of(" ,"));
      status += fmt::format(", {} evaluations", store->EvaluationCount(info->id));
    }
    text += fmt::format("{} seed {} (job {}): {}\n", run.label, run.seed, run.job.name, status);
    ++counts[count];
  }
  std::string tally;
  for (const auto& [status, n] : counts) tally += fmt::format(", {} {}", n, status);
  text += fmt::format("{} runs{}\n", spec.runs.size(), tally.empty() ? "" : ":" + tally.substr(1));
  return text;
}

std::vector<ComparisonRunData> LoadComparisonRuns(const ComparisonSpec& spec) {
  StoreOptions read_only;
  read_only.read_only = true;
  const ResultStore store(spec.store, read_only);
  std::vector<ComparisonRunData> out;
  for (const ComparisonRun& run : spec.runs) {
    ComparisonRunData d;
    d.optimizer = run.label;
    d.seed = run.seed;
    d.job = run.job.name;
    const std::optional<JobInfo> info = store.FindJob(run.job.name);
    d.status = info ? ToString(info->status) : "absent";
    if (info) {
      for (const EvaluationRecord& e : store.Evaluations(info->id)) {
        d.scores.push_back(e.ok ? e.score : std::numeric_limits<double>::quiet_NaN());
        d.pruned += e.pruned ? 1 : 0;
        d.eval_seconds.push_back(e.eval_time_s);
      }
    }
    out.push_back(std::move(d));
  }
  return out;
}

ComparisonResult RunComparison(const ComparisonSpec& spec, const std::filesystem::path& out_dir,
                               const ComparisonOptions& options) {
  ComparisonResult result;
  result.store = spec.store;
  result.runs = static_cast<int>(spec.runs.size());
  const bool use_mpi = options.mpi != nullptr && options.mpi->size() > 1;
  const bool manager = !use_mpi || options.mpi->rank() == 0;
  if (manager) {
    std::filesystem::create_directories(out_dir);
    std::filesystem::create_directories(spec.store.parent_path());
    std::ofstream json(out_dir / "comparison.json");
    json << spec.ToJson().dump(1) << "\n";
    if (!json) throw std::runtime_error(fmt::format("{}: cannot write", (out_dir / "comparison.json").string()));
  }

  JobCommandOptions job_options;
  job_options.threads = options.threads;
  job_options.cache_dir = options.cache_dir;
  job_options.no_cache = options.no_cache;
  job_options.write_report = false;
  job_options.progress = options.progress;
  job_options.progress_interval_s = options.progress_interval_s;
  job_options.lock = options.lock;
  job_options.program_version = options.program_version;
  job_options.command = "compare-optimizers";
  job_options.handle_signals = options.handle_signals;
  job_options.interrupted = options.interrupted;
  job_options.make_objective = options.make_objective ? options.make_objective : SharedRecordingObjective();
  if (use_mpi) job_options.mpi = options.mpi;
  if (!manager) {
    RunComparisonWorker(spec, job_options);
    result.mpi_worker = true;
    return result;
  }
  // Finished runs are only checked, by the manager alone.
  JobCommandOptions check_options = job_options;
  check_options.mpi = nullptr;

  NextRunAnnouncer announcer(use_mpi ? options.mpi : nullptr);
  for (size_t i = 0; i < spec.runs.size(); ++i) {
    const ComparisonRun& run = spec.runs[i];
    std::optional<JobStatus> status;
    {
      const ResultStore store(spec.store);
      if (const auto info = store.FindJob(run.job.name)) status = info->status;
    }
    if (status && Done(*status)) {
      // Resuming a finished job does nothing but check that its spec and
      // recordings are the ones it ran with: a changed comparison is named.
      (void)RunJob(run.job, JobStart::kResume, check_options);
      ++result.already_done;
      continue;
    }
    spdlog::info("run {}/{}: {} seed {} ({})", i + 1, spec.runs.size(), run.label, run.seed,
                 status ? "resumed" : "new");
    announcer.Announce(static_cast<int32_t>(i));
    const JobCommandResult r = RunJob(run.job, status ? JobStart::kResume : JobStart::kRun, job_options);
    ++result.run_now;
    if (r.run.status == JobStatus::kStopped) {
      result.stopped = true;
      return result;
    }
  }
  announcer.Announce(-1);
  result.analysis = AnalyseComparison(LoadComparisonRuns(spec), AnalysisOptions(spec));
  result.report = WriteComparisonReport(out_dir, spec.name, *result.analysis, options.report);
  return result;
}

}  // namespace calib
