// Running an optimiser comparison (comparison.h).

#include "calib/jobs/comparison.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <limits>
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

}  // namespace

ComparisonAnalysisOptions AnalysisOptions(const ComparisonSpec& spec) {
  ComparisonAnalysisOptions o;
  o.budget = spec.budget_evaluations;
  o.relative_targets = spec.targets.kind == TargetKind::kRelative;
  o.targets = spec.targets.values;
  return o;
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
  std::filesystem::create_directories(out_dir);
  std::filesystem::create_directories(spec.store.parent_path());
  {
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
      (void)RunJob(run.job, JobStart::kResume, job_options);
      ++result.already_done;
      continue;
    }
    spdlog::info("run {}/{}: {} seed {} ({})", i + 1, spec.runs.size(), run.label, run.seed,
                 status ? "resumed" : "new");
    const JobCommandResult r = RunJob(run.job, status ? JobStart::kResume : JobStart::kRun, job_options);
    ++result.run_now;
    if (r.run.status == JobStatus::kStopped) {
      result.stopped = true;
      return result;
    }
  }
  result.analysis = AnalyseComparison(LoadComparisonRuns(spec), AnalysisOptions(spec));
  result.report = WriteComparisonReport(out_dir, spec.name, *result.analysis, options.report);
  return result;
}

}  // namespace calib
