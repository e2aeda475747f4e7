#pragma once
// Progress of a running job for people: on a terminal a live bar
//   [########........]  120/300  3.4 eval/s  best 81234 (#87)  failed 2  ETA 53s
// redrawn in place a few times a second; when the stream is not a terminal
// (a log file, Slurm's output) plain spdlog lines every log_interval_s.
// Warnings and checkpoints are always logged as lines.

#include "calib/jobs/runner.h"

#include <chrono>
#include <cstdio>
#include <string>

namespace calib {

enum class ProgressMode {
  kAuto,  ///< kBar when the stream is a terminal, kLog otherwise
  kBar,
  kLog,
  kNone,  ///< warnings only
};
std::string ToString(ProgressMode mode);  ///< "auto", "bar", "log", "none"
/// Throws std::invalid_argument naming the value and the choices.
ProgressMode ProgressModeFromString(const std::string& text);

/// "3.4 s", "12 min 5 s", "2 h 3 min"; "-" for a negative or non-finite time.
std::string FormatDuration(double seconds);

/// The text of the live bar for `width` columns (no escape codes).
std::string FormatProgressBar(const RunProgress& progress, double evals_per_s, int width);
/// One log line: "120/300 evaluations (40.0 %), 3.4 eval/s, best ... , ETA ...".
std::string FormatProgressLine(const RunProgress& progress, double evals_per_s);

class ProgressDisplay final : public RunObserver {
 public:
  /// `stream` (stderr by default) decides kAuto and takes the bar.
  explicit ProgressDisplay(ProgressMode mode = ProgressMode::kAuto, double log_interval_s = 10.0,
                           std::FILE* stream = stderr);

  ProgressMode mode() const { return mode_; }

  void OnStart(const RunProgress& progress, const std::string& what) override;
  void OnProgress(const RunProgress& progress) override;
  void OnCheckpoint(const RunProgress& progress, int64_t sequence) override;
  void OnWarning(const std::string& message) override;
  void OnFinish(const RunProgress& progress) override;

 private:
  void DrawBar(const RunProgress& progress);
  void ClearBar();
  double Rate(const RunProgress& progress) const;

  ProgressMode mode_;
  double log_interval_s_;
  std::FILE* stream_;
  bool bar_drawn_ = false;
  std::chrono::steady_clock::time_point last_draw_{};
  std::chrono::steady_clock::time_point last_log_{};
};

}  // namespace calib
