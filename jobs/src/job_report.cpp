#include "calib/jobs/job_report.h"

#include "calib/evaluator/recording.h"
#include "calib/jobs/fit_diagnostics.h"
#include "calib/results/convergence_plot.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <ctime>

#include <chrono>
#include <fstream>
#include <optional>
#include <set>
#include <stdexcept>

namespace calib {
namespace {

}  // namespace

std::string JobReport::Report() const {
  std::string text;
  if (!best_params.empty()) text += fmt::format("best parameters: {}\n", best_params.string());
  if (!diagnostics.empty()) text += fmt::format("fit: {}\n", diagnostics);
  for (const RecordingReport& r : recordings) {
    text += fmt::format("{} {}: score {:.1f}, mean IoU {:.4f}{}\n", r.role,
                        RecordingDisplayName(r.recording), r.result.xor_sum, r.result.mean_iou,
                        r.result.ok() ? "" : " (simulation failed: " + r.result.failure_reason + ")");
    if (!r.overlay_video.empty()) text += fmt::format("  overlay video: {}\n", r.overlay_video.string());
  }
  if (!convergence_svg.empty()) text += fmt::format("convergence plot: {}\n", convergence_svg.string());
  text += fmt::format("summary: {}\n", summary_txt.string());
  text += fmt::format("evaluations: {} and {}\n", evaluations_csv.string(), job_json.string());
  return text;
}

std::string JobStatusText(const ResultStore& store, const JobInfo& info,
                          const JobLockOptions& lock_options) {
  const std::string reason = info.stop_reason.empty() ? "" : " (" + info.stop_reason + ")";
  if (info.status != JobStatus::kRunning) return ToString(info.status) + reason;
  // "running" is also what a process killed by a signal or a full disk
  // leaves; the lock's heartbeat tells the two apart.
  const std::optional<JobLock> holder = store.JobLockHolder(info.id);
  if (holder) {
    const double age_s = NowUnixSeconds() - holder->heartbeat_unix_s;
    if (!JobLockHolderStopped(*holder, age_s, lock_options)) {
      return fmt::format("running, by {}", DescribeJobLockHolder(*holder, age_s));
    }
    return fmt::format("interrupted (left running by {}, which has stopped); continue it with "
                       "`calib resume`",
                       DescribeJobLockHolder(*holder, age_s));
  }
  return "interrupted (left running, and no process holds it); continue it with `calib resume`";
}

std::string JobResultsText(const ResultStore& store, int64_t job) {
  const JobInfo info = store.Job(job);
  std::string text = fmt::format("job: {} (store {})\n", info.name, store.path().string());
  text += fmt::format("status: {}\n", JobStatusText(store, info));
  text += store.Summary(job).Report();
  if (!text.empty() && text.back() != '\n') text += '\n';
  for (const JobRunRecord& run : store.JobRuns(job)) {
    const auto t = static_cast<std::time_t>(run.started_unix_s);
    std::tm tm{};
    gmtime_r(&t, &tm);
    text += fmt::format("{}: {} by {} on host {} (process {})\n", run.command,
                        fmt::format("{:04}-{:02}-{:02} {:02}:{:02}:{:02} UTC", tm.tm_year + 1900,
                                    tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec),
                        run.program_version, run.host, run.pid);
  }
  if (info.result.is_object() && info.result.contains("recordings")) {
    for (const auto& r : info.result["recordings"]) {
      text += fmt::format("{} {}: score {:.1f}, mean IoU {:.4f}, status {}\n",
                          r.value("role", "?"), r.value("recording", "?"),
                          r.value("score", 0.0), r.value("mean_iou", 0.0),
                          r.value("status", "?"));
    }
  }
  return text;
}

JobReport WriteJobReport(const JobSpec& spec, ResultStore& store, int64_t job,
                         const CommandSettings& settings, const JobReportOptions& options) {
  JobReport report;
  report.out_dir = spec.results.out_dir;
  std::filesystem::create_directories(report.out_dir);

  report.evaluations_csv = report.out_dir / "evaluations.csv";
  store.ExportCsv(job, report.evaluations_csv);
  report.job_json = report.out_dir / "job.json";

  const std::optional<EvaluationRecord> best = store.Best(job);
  const bool has_best = best.has_value();
  if (has_best) {
    // The history once, for the plot and for what it says about the fit.
    const std::vector<EvaluationRecord> evaluations = store.Evaluations(job);
    // A plot is for people: without gnuplot the report goes on without it.
    try {
      WriteConvergencePlot(report.out_dir / "convergence.svg", evaluations, spec.name);
      report.convergence_svg = report.out_dir / "convergence.svg";
    } catch (const std::runtime_error& e) {
      spdlog::warn("{}: no convergence plot: {}", spec.name, e.what());
    }
    report.best_params = report.out_dir / "best_params.json";
    store.WriteBestParameterFile(job, report.best_params);
    report.diagnostics = DiagnoseFit(spec.parameters, best->parameters, evaluations).Summary();
  }

  nlohmann::json result = {{"recordings", nlohmann::json::array()}};
  if (has_best && options.simulate) {
    std::set<std::string> used;
    const auto simulate = [&](const std::string& role, const std::filesystem::path& recording) {
      const std::string name = RecordingDisplayName(recording);
      std::string unique = name;
      for (int k = 2; used.count(role + "/" + unique); ++k) unique = fmt::format("{}_{}", name, k);
      used.insert(role + "/" + unique);
      RecordingReport r;
      r.role = role;
      r.recording = recording;
      r.out_dir = report.out_dir / role / unique;
      SimulateOptions simulate_options;
      simulate_options.write_video = options.write_video;
      const SimulateSummary s =
          RunSimulate(recording, report.best_params, r.out_dir, simulate_options, settings);
      r.result = s.result;
      r.overlay_video = s.overlay_video;
      result["recordings"].push_back({{"role", role},
                                      {"recording", unique},
                                      {"path", recording.string()},
                                      {"score", s.result.xor_sum},
                                      {"mean_iou", s.result.mean_iou},
                                      {"status", ToString(s.result.status)},
                                      {"frames", s.result.num_frames}});
      report.recordings.push_back(std::move(r));
    };
    for (const auto& recording : spec.train) simulate("train", recording);
    for (const auto& recording : spec.holdout) simulate("holdout", recording);
    store.SetJobResult(job, result);
  }

  store.ExportJson(job, report.job_json);
  report.summary_txt = report.out_dir / "summary.txt";
  std::ofstream out(report.summary_txt);
  out << JobResultsText(store, job);
  if (!out) {
    throw std::runtime_error(fmt::format("{}: cannot write", report.summary_txt.string()));
  }
  return report;
}

}  // namespace calib
