#include "calib/service/job_views.h"

#include "calib/evaluator/json_number.h"
#include "calib/results/store.h"
#include "queued_work.h"

#include <fstream>

namespace calib::service {
namespace {

namespace fs = std::filesystem;

ResultStore OpenReadOnly(const fs::path& store) {
  StoreOptions options;
  options.read_only = true;
  return ResultStore(store, options);
}

nlohmann::json BestOf(const std::optional<EvaluationRecord>& best) {
  if (!best) return nullptr;
  return {{"id", best->id}, {"score", JsonNumber(best->score)}, {"mean_iou", JsonNumber(best->mean_iou)}};
}

int64_t BudgetOf(const nlohmann::json& spec) {
  const nlohmann::json budget = spec.value("budget", nlohmann::json::object());
  return budget.is_object() ? budget.value("evaluations", int64_t{0}) : 0;
}

// The report a loop or a comparison writes at its end, relative to its
// folder.
const char* ReportOf(QueueKind kind) { return kind == QueueKind::kLoop ? "report.json" : "report.html"; }

bool IsFile(const fs::path& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

// A loop's or a comparison's own store, once it has one: nullopt before its
// command made it (absent, or being created at this moment).
std::optional<ResultStore> OpenOwnStore(const fs::path& path) {
  if (!IsFile(path)) return std::nullopt;
  try {
    return OpenReadOnly(path);
  } catch (const StoreError&) {
    return std::nullopt;
  }
}

// A loop's or a comparison's status and progress, from its own store.
void AddOwnStoreView(const ServiceOptions& options, const QueueEntry& entry, nlohmann::json* view) {
  nlohmann::json& v = *view;
  v["budget"] = entry.kind == QueueKind::kComparison ? entry.spec.value("budget", int64_t{0}) : 0;
  nlohmann::json progress = {{"jobs", 0}, {"jobs_finished", 0}};
  if (entry.kind == QueueKind::kComparison) progress["runs"] = entry.spec.value("runs", int64_t{0});
  const std::optional<ResultStore> own = OpenOwnStore(OwnStore(options, entry));
  const bool started = own.has_value();
  if (started) {
    const ResultStore& store = *own;
    int64_t evaluations = 0, failed = 0, pruned = 0, finished = 0;
    std::vector<JobInfo> jobs;
    try {
      jobs = store.Jobs();
      for (const JobInfo& job : jobs) {
        const JobSummary summary = store.Summary(job.id);
        evaluations += summary.evaluations;
        failed += summary.failed;
        pruned += summary.pruned;
        if (job.status == JobStatus::kFinished || job.status == JobStatus::kAborted) ++finished;
      }
    } catch (const StoreError&) {
      // Its tables being made at this moment: no progress yet, and the list
      // of every job still answers.
      jobs.clear();
      evaluations = failed = pruned = finished = 0;
    }
    v["evaluations"] = evaluations;
    v["failed"] = failed;
    v["pruned"] = pruned;
    progress["jobs"] = jobs.size();
    progress["jobs_finished"] = finished;
  }
  v["progress"] = progress;
  const bool reported = IsFile(WorkFolder(options, entry.name) / ReportOf(entry.kind));
  v["report"] = reported ? nlohmann::json(ReportOf(entry.kind)) : nlohmann::json(nullptr);
  switch (entry.state) {
    case QueueState::kRunning:
      v["status"] = "running";
      break;
    case QueueState::kQueued:
      v["status"] = started ? "stopped" : "queued";
      break;
    case QueueState::kCancelled:
      v["status"] = "stopped";
      break;
    case QueueState::kDone:
      v["status"] = reported ? "finished" : "failed";
      break;
  }
}

}  // namespace

nlohmann::json JobStatusView(const ServiceOptions& options, const QueueEntry& entry) {
  nlohmann::json view = {{"name", entry.name},
                         {"kind", ToString(entry.kind)},
                         {"state", ToString(entry.state)},
                         {"priority", entry.priority},
                         {"submitted_unix_s", entry.submitted_unix_s},
                         {"message", entry.message},
                         {"status", "queued"},
                         {"stop_reason", ""},
                         {"evaluations", 0},
                         {"failed", 0},
                         {"pruned", 0},
                         {"budget", BudgetOf(entry.spec)},
                         {"best", nullptr},
                         {"runs", nlohmann::json::array()}};
  if (entry.kind != QueueKind::kJob) {
    AddOwnStoreView(options, entry, &view);
    return view;
  }
  const ResultStore store = OpenReadOnly(options.store());
  const std::optional<JobInfo> job = store.FindJob(entry.name);
  if (!job) return view;
  const JobSummary summary = store.Summary(job->id);
  view["status"] = ToString(job->status);
  view["stop_reason"] = job->stop_reason;
  view["evaluations"] = summary.evaluations;
  view["failed"] = summary.failed;
  view["pruned"] = summary.pruned;
  view["best"] = BestOf(summary.best);
  for (const JobRunRecord& run : store.JobRuns(job->id)) {
    view["runs"].push_back({{"started_unix_s", run.started_unix_s},
                            {"program_version", run.program_version},
                            {"host", run.host},
                            {"command", run.command}});
  }
  return view;
}

nlohmann::json JobResultsView(const ServiceOptions& options, const QueueEntry& entry) {
  if (entry.kind != QueueKind::kJob) {
    nlohmann::json view = {{"job", JobStatusView(options, entry)},
                           {"jobs", nlohmann::json::array()},
                           {"report", nullptr}};
    if (const std::optional<ResultStore> store = OpenOwnStore(OwnStore(options, entry))) {
      for (const JobInfo& job : store->Jobs()) {
        const JobSummary summary = store->Summary(job.id);
        view["jobs"].push_back({{"name", job.name},
                                {"status", ToString(job.status)},
                                {"evaluations", summary.evaluations},
                                {"failed", summary.failed},
                                {"best", BestOf(summary.best)}});
      }
    }
    const fs::path report = WorkFolder(options, entry.name) / "report.json";
    if (entry.kind == QueueKind::kLoop && IsFile(report)) {
      std::ifstream in(report);
      nlohmann::json parsed = nlohmann::json::parse(in, nullptr, false);
      if (!parsed.is_discarded()) view["report"] = std::move(parsed);
    }
    return view;
  }
  nlohmann::json view = {{"job", JobStatusView(options, entry)},
                         {"evaluations", nlohmann::json::array()}};
  const ResultStore store = OpenReadOnly(options.store());
  const std::optional<JobInfo> job = store.FindJob(entry.name);
  if (!job) return view;
  const JobSummary summary = store.Summary(job->id);
  view["summary"] = {{"evaluations", summary.evaluations},
                     {"ok", summary.ok},
                     {"failed", summary.failed},
                     {"pruned", summary.pruned},
                     {"best", BestOf(summary.best)},
                     {"mean_eval_time_s", summary.mean_eval_time_s},
                     {"checkpoints", summary.checkpoints}};
  for (const EvaluationRecord& e : store.Evaluations(job->id)) {
    view["evaluations"].push_back({{"id", e.id},
                                   {"status", e.status()},
                                   {"score", JsonNumber(e.score)},
                                   {"mean_iou", JsonNumber(e.mean_iou)},
                                   {"iou_min", JsonNumber(e.iou_min)},
                                   {"iou_max", JsonNumber(e.iou_max)},
                                   {"failure_frame", e.failure_frame},
                                   {"reason", e.reason},
                                   {"attempt", e.attempt},
                                   {"parameters", e.parameters},
                                   {"x", e.x}});
  }
  return view;
}

std::optional<nlohmann::json> BestView(const fs::path& store_path, const std::string& name) {
  const ResultStore store = OpenReadOnly(store_path);
  const std::optional<JobInfo> job = store.FindJob(name);
  if (!job) return std::nullopt;
  const std::optional<EvaluationRecord> best = store.Best(job->id);
  if (!best) return std::nullopt;
  return nlohmann::json{{"evaluation", best->id},
                        {"score", JsonNumber(best->score)},
                        {"mean_iou", JsonNumber(best->mean_iou)},
                        {"parameters", best->parameters}};
}

}  // namespace calib::service
