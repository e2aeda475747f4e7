#pragma once
// What a finished (or stopped) job leaves for people in its out_dir:
//   best_params.json   the best evaluation's parameters (`calib simulate --params`)
//   evaluations.csv    every evaluation (ResultStore::ExportCsv)
//   job.json           the job, its summary and every evaluation (ExportJson)
//   summary.txt        the summary `calib results` prints
//   convergence.svg    score and best so far against evaluations (convergence_plot.h;
//                      left out with a warning when gnuplot is missing)
//   train/<rec>/, holdout/<rec>/   the best parameters simulated on each
//       recording: overlay.mp4, frames.csv, the worst frame's overlay PNG
// The held-out scores (predicted, not refitted) are also kept in the store
// as the job's result JSON.

#include "calib/jobs/commands.h"
#include "calib/jobs/job_lock.h"
#include "calib/jobs/job_spec.h"
#include "calib/results/store.h"

#include <filesystem>
#include <string>
#include <vector>

namespace calib {

struct RecordingReport {
  std::string role;  ///< "train" or "holdout"
  std::filesystem::path recording;
  std::filesystem::path out_dir;
  EvaluationResult result;
  std::filesystem::path overlay_video;  ///< empty when not written
};

struct JobReport {
  std::filesystem::path out_dir;
  std::filesystem::path best_params;  ///< empty when no evaluation succeeded
  std::filesystem::path evaluations_csv;
  std::filesystem::path job_json;
  std::filesystem::path summary_txt;
  std::filesystem::path convergence_svg;  ///< empty when not written
  std::vector<RecordingReport> recordings;
  /// What the history says about the fit (FitDiagnostics::Summary: an
  /// uninformative score, parameters on their box's bounds); empty: nothing.
  std::string diagnostics;

  /// Lines naming every file and each recording's score and mean IoU.
  std::string Report() const;
};

struct JobReportOptions {
  /// Simulate the best parameters on every train and holdout recording.
  bool simulate = true;
  bool write_video = true;
};

/// The job's status and stop reason for people. A job left "running" is
/// told apart by its lock (job_lock.h): "running, by process P on host H
/// (...)" while its holder is alive, "interrupted (...)" with a hint to
/// resume once the holder stopped (SIGKILL, a crash, a full disk) or when no
/// process holds it.
std::string JobStatusText(const ResultStore& store, const JobInfo& info,
                          const JobLockOptions& lock_options = {});

/// The text of `calib results`: the job's name, status (JobStatusText), the
/// store's summary and the held-out results kept by WriteJobReport.
std::string JobResultsText(const ResultStore& store, int64_t job);

/// Writes the files above into spec.results.out_dir (created) and keeps the
/// per-recording scores as the job's result. `settings` carries the
/// preparation (cache) and simulation options of the spec.
JobReport WriteJobReport(const JobSpec& spec, ResultStore& store, int64_t job,
                         const CommandSettings& settings, const JobReportOptions& options = {});

}  // namespace calib
