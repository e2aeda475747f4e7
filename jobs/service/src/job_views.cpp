#include "calib/service/job_views.h"

#include "calib/evaluator/json_number.h"
#include "calib/results/store.h"

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

}  // namespace

nlohmann::json JobStatusView(const fs::path& store_path, const QueueEntry& entry) {
  nlohmann::json view = {{"name", entry.name},
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
  const ResultStore store = OpenReadOnly(store_path);
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

nlohmann::json JobResultsView(const fs::path& store_path, const QueueEntry& entry) {
  nlohmann::json view = {{"job", JobStatusView(store_path, entry)},
                         {"evaluations", nlohmann::json::array()}};
  const ResultStore store = OpenReadOnly(store_path);
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
