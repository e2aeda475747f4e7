#include "calib/jobs/progress.h"

#include "calib/core/enum_names.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace calib {

namespace {

constexpr auto kProgressModeNames = std::to_array<EnumName<ProgressMode>>({
    {ProgressMode::kAuto, "auto"},
    {ProgressMode::kBar, "bar"},
    {ProgressMode::kLog, "log"},
    {ProgressMode::kNone, "none"},
});

}  // namespace

std::string ToString(ProgressMode mode) { return EnumToString(kProgressModeNames, mode); }

ProgressMode ProgressModeFromString(const std::string& text) {
  return EnumFromString(kProgressModeNames, "progress mode", text);
}

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0.0) return "-";
  if (seconds < 60.0) return fmt::format("{:.0f} s", seconds);
  const auto total = static_cast<int64_t>(std::llround(seconds));
  if (total < 3600) return fmt::format("{} min {} s", total / 60, total % 60);
  return fmt::format("{} h {} min", total / 3600, (total % 3600) / 60);
}

namespace {

double EtaSeconds(const RunProgress& p, double rate) {
  const double remaining = static_cast<double>(p.budget - p.evaluations - p.running);
  if (remaining <= 0.0) return 0.0;
  if (!(rate > 0.0)) return -1.0;
  return remaining / rate;
}

std::string BestText(const RunProgress& p) {
  if (!p.best_score) return "best -";
  return fmt::format("best {:.10g} (#{})", *p.best_score, p.best_id);
}

int TerminalWidth(std::FILE* stream) {
  winsize size{};
  if (ioctl(fileno(stream), TIOCGWINSZ, &size) == 0 && size.ws_col > 20) return size.ws_col;
  return 80;
}

}  // namespace

std::string FormatProgressBar(const RunProgress& p, double rate, int width) {
  const int64_t done = std::min(p.budget, p.evaluations + p.running);
  std::string tail = fmt::format("  {}/{}  {:.2f} eval/s  {}", done, p.budget, rate, BestText(p));
  if (p.failed > 0) tail += fmt::format("  failed {}", p.failed);
  if (p.pruned > 0) tail += fmt::format("  pruned {}", p.pruned);
  tail += fmt::format("  ETA {}", FormatDuration(EtaSeconds(p, rate)));
  const int bar_width = std::clamp(width - 3 - static_cast<int>(tail.size()), 10, 40);
  const double fraction =
      p.budget > 0 ? std::clamp(static_cast<double>(done) / p.budget, 0.0, 1.0) : 0.0;
  const int filled = static_cast<int>(std::floor(fraction * bar_width));
  std::string text = fmt::format("[{}{}]{}", std::string(filled, '#'),
                                 std::string(bar_width - filled, '.'), tail);
  if (static_cast<int>(text.size()) >= width) text.resize(std::max(0, width - 1));
  return text;
}

std::string FormatProgressLine(const RunProgress& p, double rate) {
  const int64_t done = std::min(p.budget, p.evaluations + p.running);
  const double percent = p.budget > 0 ? 100.0 * done / p.budget : 0.0;
  std::string line = fmt::format("{}/{} evaluations ({:.1f} %), {:.2f} eval/s, {}", done, p.budget,
                                 percent, rate, BestText(p));
  if (p.failed > 0) line += fmt::format(", {} failed", p.failed);
  if (p.pruned > 0) line += fmt::format(", {} pruned", p.pruned);
  line += fmt::format(", elapsed {}, ETA {}", FormatDuration(p.elapsed_s),
                      FormatDuration(EtaSeconds(p, rate)));
  return line;
}

ProgressDisplay::ProgressDisplay(ProgressMode mode, double log_interval_s, std::FILE* stream)
    : mode_(mode), log_interval_s_(log_interval_s), stream_(stream) {
  if (mode_ == ProgressMode::kAuto) {
    mode_ = isatty(fileno(stream_)) ? ProgressMode::kBar : ProgressMode::kLog;
  }
}

double ProgressDisplay::Rate(const RunProgress& p) const {
  return p.elapsed_s > 0.0 ? p.evaluated_now / p.elapsed_s : 0.0;
}

void ProgressDisplay::ClearBar() {
  if (!bar_drawn_) return;
  std::fputs("\r\033[K", stream_);
  std::fflush(stream_);
  bar_drawn_ = false;
}

void ProgressDisplay::DrawBar(const RunProgress& p) {
  std::fputs(("\r\033[K" + FormatProgressBar(p, Rate(p), TerminalWidth(stream_))).c_str(),
             stream_);
  std::fflush(stream_);
  bar_drawn_ = true;
  last_draw_ = std::chrono::steady_clock::now();
}

void ProgressDisplay::OnStart(const RunProgress& p, const std::string& what) {
  if (mode_ == ProgressMode::kNone) return;
  spdlog::info("job {}", what);
  if (p.evaluations > 0) {
    spdlog::info("continuing after {} evaluations ({} failed)", p.evaluations, p.failed);
  }
  last_log_ = std::chrono::steady_clock::now();
}

void ProgressDisplay::OnProgress(const RunProgress& p) {
  const auto now = std::chrono::steady_clock::now();
  if (mode_ == ProgressMode::kBar) {
    if (now - last_draw_ >= std::chrono::milliseconds(200)) DrawBar(p);
  } else if (mode_ == ProgressMode::kLog) {
    if (std::chrono::duration<double>(now - last_log_).count() >= log_interval_s_) {
      spdlog::info("{}", FormatProgressLine(p, Rate(p)));
      last_log_ = now;
    }
  }
}

void ProgressDisplay::OnCheckpoint(const RunProgress& p, int64_t sequence) {
  if (mode_ == ProgressMode::kNone) return;
  if (mode_ == ProgressMode::kBar) {
    DrawBar(p);  // the bar stays; checkpoints are too frequent for lines
    return;
  }
  spdlog::debug("checkpoint {} after {} evaluations", sequence, p.evaluations);
}

void ProgressDisplay::OnWarning(const std::string& message) {
  ClearBar();
  spdlog::warn("{}", message);
}

void ProgressDisplay::OnFinish(const RunProgress& p) {
  if (mode_ == ProgressMode::kBar) {
    DrawBar(p);
    std::fputc('\n', stream_);
    bar_drawn_ = false;
  } else if (mode_ == ProgressMode::kLog) {
    spdlog::info("{}", FormatProgressLine(p, Rate(p)));
  }
}

}  // namespace calib
