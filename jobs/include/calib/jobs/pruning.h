#pragma once
// Early stopping of hopeless candidates ("pruning"): the job spec's
// budget.prune_factor F > 1 turns it on; unset, nothing here is used and the
// history is that of a job without it.
//
// The rule. A candidate's score so far (ObjectiveResult::trace: the XOR
// area summed over the recordings in order and their frames in order) never
// decreases, so it is a lower bound of its score. Candidate i is pruned when
// its score so far exceeds
//     B(i) = F x (the lowest score among the ok evaluations with id < i)
// after some frame (none while no earlier evaluation is ok). It is recorded
// as pruned at the first such frame (PrunePoint), with the score so far
// there as its score, whatever it did after that frame: a simulation that
// failed later is pruned, not failed (the frames before a failure are all it
// scored, so a failure decides only when the trace up to it never exceeds
// B(i)). Otherwise it is recorded as it finished, ok or failed.
//
// Determinism. B(i) depends only on the history before i, but when a worker
// starts candidate i the runner may not know every evaluation before it yet
// (other threads, ranks or batches still run). The worker therefore gets the
// looser bound B_run(i) = F x the lowest score among the candidates with
// id < i it knows to have simulated to their end (PruneBounds), and stops
// after the first frame whose score so far exceeds B_run(i), returning its
// trace. B_run(i) >= B(i): every ok evaluation before i scores at least their
// lowest score, and one that is pruned when recorded scored more than F times
// that. So a run stopped at B_run(i) has passed B(i) too, and a run that
// never passed B_run(i) finished. The runner records candidates in id order,
// once every one before is recorded, and decides pruned or not from the
// trace and the exact B(i) (FindPrunePoint): the same outcome at any thread
// or rank count, batch size, and after any resume.

#include "calib/jobs/objective.h"

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>

namespace calib {

/// The bounds candidates start with (B_run above). Thread-safe: worker
/// threads ask while the runner's thread adds.
class PruneBounds {
 public:
  /// factor > 1 (the spec's budget.prune_factor, checked where it is read).
  explicit PruneBounds(double factor) : factor_(factor) {}

  double factor() const { return factor_; }

  /// Candidate `id` simulated every frame and scored `score` (an ok
  /// evaluation, or one pruned only when recorded). NaN is ignored.
  void AddCompleted(int64_t id, double score);
  /// A worker's result: its score when it ran to its end (kOk).
  void AddFinished(int64_t id, const ObjectiveResult& result) {
    if (result.ok()) AddCompleted(id, result.score);
  }
  /// What candidate `id` is started with: a trace, and a stop above F x the
  /// lowest score added with an id < `id` (never when none).
  EarlyStop StartFor(int64_t id) const;

 private:
  double factor_;
  mutable std::mutex mutex_;
  // The running minimum of the scores by id, as its steps: scores strictly
  // decrease as ids increase, so the entry before `id` is the lowest score
  // of the ids below it.
  std::map<int64_t, double> steps_;
};

/// Where a candidate's score so far first exceeds its bound.
struct PrunePoint {
  int frames = 0;      ///< frames scored up to and including it, over all recordings
  int recording = -1;  ///< index of the training recording
  int frame = -1;      ///< frame within that recording, from 0
  double score = 0.0;  ///< the score so far after it
};

/// The first frame of `result.trace` whose score so far exceeds `bound`;
/// nullopt when none does (or the trace is empty: nothing was scored).
/// Throws std::logic_error when the trace does not fit
/// result.recording_frames (an objective that breaks its contract).
std::optional<PrunePoint> FindPrunePoint(const ObjectiveResult& result, double bound);

}  // namespace calib
