// The store's reports and exports, written on its public reading API.

#include "calib/results/store.h"

#include "calib/evaluator/json_number.h"
#include "calib/results/csv_writer.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <set>
#include <utility>

namespace calib {
namespace {

using csv_writer::WriteRecord;

// Shortest text that reads back to the same double; NaN: empty.
std::string Number(double v) { return std::isnan(v) ? std::string() : fmt::format("{}", v); }

std::string UtcTime(double unix_s) {
  if (unix_s <= 0.0) return "-";
  const auto t = static_cast<std::time_t>(unix_s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

nlohmann::json ToJson(const EvaluationRecord& r) {
  nlohmann::json out = {
      {"id", r.id},
      {"status", r.status()},
      {"score", JsonNumber(r.score)},
      {"mean_iou", JsonNumber(r.mean_iou)},
      {"iou_min", JsonNumber(r.iou_min)},
      {"iou_max", JsonNumber(r.iou_max)},
      {"failure_frame", r.failure_frame},
      {"reason", r.reason},
      {"eval_time_s", JsonNumber(r.eval_time_s)},
      {"worker", r.worker},
      {"attempt", r.attempt},
      {"parameters", r.parameters},
      {"x", r.x},
      {"detail", r.detail},
      {"recorded_unix_s", JsonNumber(r.recorded_unix_s)},
  };
  if (r.pruned) {
    out["pruned_recording"] = r.pruned_recording;
    out["pruned_frame"] = r.pruned_frame;
  }
  return out;
}

nlohmann::json ToJson(const JobSummary& s) {
  nlohmann::json out = {
      {"evaluations", s.evaluations},
      {"ok", s.ok},
      {"failed", s.failed},
      {"pruned", s.pruned},
      {"mean_eval_time_s", s.mean_eval_time_s},
      {"total_eval_time_s", s.total_eval_time_s},
      {"first_recorded_unix_s", s.first_recorded_unix_s},
      {"last_recorded_unix_s", s.last_recorded_unix_s},
      {"checkpoints", s.checkpoints},
      {"best", nullptr},
  };
  if (s.best) {
    out["best"] = {{"id", s.best->id},
                   {"score", JsonNumber(s.best->score)},
                   {"mean_iou", JsonNumber(s.best->mean_iou)},
                   {"parameters", s.best->parameters}};
  }
  return out;
}

}  // namespace

std::string JobSummary::Report() const {
  // Pruned ones are named only when there are (a job without pruning reads as before).
  std::string out = fmt::format("evaluations: {} ({} ok, {} failed{})\n", evaluations, ok, failed,
                                pruned > 0 ? fmt::format(", {} pruned", pruned) : "");
  if (best) {
    out += fmt::format("best: score {} (candidate {}), mean IoU {:.4f}\n", best->score, best->id,
                       best->mean_iou);
    out += "best parameters:";
    for (const auto& [name, value] : best->parameters) out += fmt::format(" {}={}", name, value);
    out += "\n";
  } else {
    out += "best: none (no evaluation succeeded yet)\n";
  }
  out += fmt::format("evaluation time: mean {:.3f} s, total {:.1f} s\n", mean_eval_time_s,
                     total_eval_time_s);
  out += fmt::format("recorded: {} .. {} ({:.0f} s)\n", UtcTime(first_recorded_unix_s),
                     UtcTime(last_recorded_unix_s), last_recorded_unix_s - first_recorded_unix_s);
  out += fmt::format("checkpoints kept: {}\n", checkpoints);
  return out;
}

void ResultStore::ExportCsv(int64_t job, const std::filesystem::path& path) const {
  (void)Job(job);  // throws for an unknown job
  const std::vector<EvaluationRecord> records = Evaluations(job);
  std::set<std::string> names;
  for (const auto& r : records) {
    for (const auto& [name, value] : r.parameters) names.insert(name);
  }
  csv_writer::File out = csv_writer::Open(path);
  if (!out) {
    throw StoreError(fmt::format("{}: export CSV of job {}: cannot open {} for writing",
                                 this->path().string(), job, path.string()));
  }
  std::vector<std::string> header = {"id",          "status",           "score",
                                     "mean_iou",    "iou_min",          "iou_max",
                                     "failure_frame", "pruned_recording", "pruned_frame",
                                     "reason",      "eval_time_s",      "worker",
                                     "attempt"};
  header.insert(header.end(), names.begin(), names.end());
  WriteRecord(out.get(), header);
  for (const auto& r : records) {
    std::vector<std::string> row = {std::to_string(r.id),
                                    r.status(),
                                    Number(r.score),
                                    Number(r.mean_iou),
                                    Number(r.iou_min),
                                    Number(r.iou_max),
                                    std::to_string(r.failure_frame),
                                    std::to_string(r.pruned_recording),
                                    std::to_string(r.pruned_frame),
                                    r.reason,
                                    Number(r.eval_time_s),
                                    r.worker,
                                    std::to_string(r.attempt)};
    for (const auto& name : names) {
      const auto it = r.parameters.find(name);
      row.push_back(it == r.parameters.end() ? std::string() : Number(it->second));
    }
    WriteRecord(out.get(), row);
  }
  if (!csv_writer::Close(std::move(out))) {
    throw StoreError(fmt::format("{}: export CSV of job {}: write to {} failed", this->path().string(),
                                 job, path.string()));
  }
}

void ResultStore::ExportJson(int64_t job, const std::filesystem::path& path) const {
  const JobInfo info = Job(job);
  nlohmann::json doc;
  doc["job"] = {{"id", info.id},
                {"name", info.name},
                {"status", ToString(info.status)},
                {"stop_reason", info.stop_reason},
                {"created_unix_s", info.created_unix_s},
                {"updated_unix_s", info.updated_unix_s},
                {"spec", info.spec},
                {"result", info.result}};
  doc["summary"] = ToJson(Summary(job));
  doc["evaluations"] = nlohmann::json::array();
  for (const auto& r : Evaluations(job)) doc["evaluations"].push_back(ToJson(r));
  std::ofstream out(path);
  if (!out) {
    throw StoreError(fmt::format("{}: export JSON of job {}: cannot open {} for writing",
                                 this->path().string(), job, path.string()));
  }
  out << doc.dump(2) << '\n';
  out.close();
  if (!out) {
    throw StoreError(fmt::format("{}: export JSON of job {}: write to {} failed", this->path().string(),
                                 job, path.string()));
  }
}

void ResultStore::WriteBestParameterFile(int64_t job, const std::filesystem::path& path) const {
  const std::optional<EvaluationRecord> best = Best(job);
  if (!best) {
    throw StoreError(fmt::format("{}: write best parameters of job {}: no evaluation succeeded",
                                 this->path().string(), job));
  }
  SaveParameterFile(path, best->parameters);
}

}  // namespace calib
