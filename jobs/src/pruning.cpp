#include "calib/jobs/pruning.h"

#include <fmt/format.h>

#include <cmath>
#include <iterator>
#include <stdexcept>

namespace calib {

void PruneBounds::AddCompleted(int64_t id, double score) {
  if (std::isnan(score)) return;
  std::lock_guard<std::mutex> lock(mutex_);
  auto next = steps_.lower_bound(id);
  if (next != steps_.begin() && std::prev(next)->second <= score) return;  // no lower
  if (next != steps_.end() && next->first == id) {
    if (next->second <= score) return;
    next->second = score;
  } else {
    next = steps_.emplace_hint(next, id, score);
  }
  // Later steps no lower than this one are no longer steps.
  auto later = std::next(next);
  while (later != steps_.end() && later->second >= score) later = steps_.erase(later);
}

EarlyStop PruneBounds::StartFor(int64_t id) const {
  EarlyStop stop;
  stop.trace = true;
  std::lock_guard<std::mutex> lock(mutex_);
  const auto next = steps_.lower_bound(id);
  if (next != steps_.begin()) stop.stop_above = factor_ * std::prev(next)->second;
  return stop;
}

std::optional<PrunePoint> FindPrunePoint(const ObjectiveResult& result, double bound) {
  const std::vector<double>& trace = result.trace;
  size_t k = 0;
  while (k < trace.size() && !(trace[k] > bound)) ++k;
  if (k == trace.size()) return std::nullopt;
  PrunePoint point;
  point.frames = static_cast<int>(k) + 1;
  point.score = trace[k];
  int first = 0;  // trace index of the recording's frame 0
  for (size_t r = 0; r < result.recording_frames.size(); ++r) {
    const int frames = result.recording_frames[r];
    if (static_cast<int>(k) < first + frames) {
      point.recording = static_cast<int>(r);
      point.frame = static_cast<int>(k) - first;
      return point;
    }
    first += frames;
  }
  throw std::logic_error(fmt::format(
      "the objective traced {} frames, more than its recordings' {} frames", trace.size(), first));
}

}  // namespace calib
