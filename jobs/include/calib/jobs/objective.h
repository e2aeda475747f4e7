#pragma once
// What the runner minimises: a candidate's parameter values in, a score and
// its evidence out.
//
// An Objective is shared by every thread and holds what does not depend on
// the candidate (the prepared recordings, read-only). Each thread evaluates
// through its own ObjectiveWorker, which owns that thread's preallocated
// buffers (for the recordings: one Evaluator per recording). The runner makes
// one worker per thread (or per MPI worker rank) before the first candidate.
//
// Contract of ObjectiveWorker::Evaluate:
//  - Deterministic: the same values give the same result bit for bit (except
//    eval_seconds), whichever worker evaluates them and whatever it evaluated
//    before. The runner's determinism rests on this.
//  - An expected numerical failure (a simulation that blows up) is a result
//    with status kFailed and a reason, never an exception. An exception means
//    something outside the candidate went wrong (memory, I/O); the runner
//    catches it and records a failed evaluation whose reason starts with
//    "exception: ", which the failure policy may retry.
//  - Early stopping (pruning, pruning.h): with EarlyStop::trace the result
//    holds the score so far after every frame scored; the simulation stops
//    (status kPruned) after the first frame at which that exceeds
//    EarlyStop::stop_above. The trace up to there is that of the run without
//    a bound, bit for bit, so where a run stopped never changes what the
//    runner records. A worker without frames may ignore EarlyStop; a job
//    that prunes then fails on its first result without a trace.

#include "calib/core/model_definition.h"
#include "calib/core/parameters.h"
#include "calib/core/simulator.h"
#include "calib/evaluator/evaluation.h"

#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace calib {

/// kPruned: stopped early as hopeless (pruning.h); from a worker: stopped at
/// EarlyStop::stop_above.
enum class CandidateStatus { kOk, kFailed, kPruned };
/// "ok" / "failed" / "pruned".
std::string ToString(CandidateStatus status);
/// Throws std::invalid_argument naming the text for anything else.
CandidateStatus CandidateStatusFromString(std::string_view text);

/// The per-frame IoU of a candidate over every training recording, summarised.
struct IouSummary {
  double mean = 0.0;         ///< over every frame scored, all recordings
  double min = 0.0;          ///< worst frame's IoU (0 when nothing was scored)
  double max = 0.0;          ///< best frame's IoU (0 when nothing was scored)
  int worst_recording = -1;  ///< index into the objective's recordings
  int worst_frame = -1;      ///< frame of `min` within that recording
  int frames_scored = 0;     ///< frames simulated and scored
  int frames_total = 0;      ///< frames in the recordings

  bool operator==(const IouSummary&) const = default;
};

/// How one evaluation may stop early (pruning.h). The default runs
/// every frame and records no trace.
struct EarlyStop {
  /// Stop after the first frame at which the score so far exceeds this.
  double stop_above = std::numeric_limits<double>::infinity();
  /// Fill ObjectiveResult::trace and recording_frames.
  bool trace = false;
};

struct ObjectiveResult {
  CandidateStatus status = CandidateStatus::kFailed;
  /// Total XOR pixel area (px^2, EvaluationResult::xor_sum) over every
  /// recording and frame scored, summed in recording order (lower is better).
  /// For a failed candidate: over the frames scored before the failure
  /// (evidence only; the failure policy decides what the optimiser is told).
  double score = std::numeric_limits<double>::quiet_NaN();
  IouSummary iou;
  std::string reason;         ///< empty when kOk
  /// Failed: the first frame not simulated, within failure_recording; -1 otherwise.
  int failure_frame = -1;
  int failure_recording = -1;  ///< failed: index of the recording that failed
  double eval_seconds = 0.0;  ///< wall time of the evaluation (not deterministic)
  /// With EarlyStop::trace: the score so far after each frame scored, over
  /// the recordings in order and their frames in order (trace[k]: the first
  /// k + 1 frames). Non-decreasing; after the last frame scored it is
  /// `score`, bit for bit. Empty without EarlyStop::trace.
  std::vector<double> trace;
  /// With EarlyStop::trace: every training recording's frame count, in
  /// order (names the recording and frame of a trace index).
  std::vector<int> recording_frames;

  bool ok() const { return status == CandidateStatus::kOk; }
};

/// One thread's evaluator; not thread-safe, used by one thread at a time.
class ObjectiveWorker {
 public:
  virtual ~ObjectiveWorker() = default;
  /// Every frame, no trace.
  ObjectiveResult Evaluate(const ParameterValues& values) { return Evaluate(values, EarlyStop{}); }
  /// See the contract at the top.
  virtual ObjectiveResult Evaluate(const ParameterValues& values, const EarlyStop& stop) = 0;
};

class Objective {
 public:
  virtual ~Objective() = default;
  /// A new worker with its own buffers. Called by one thread at a time.
  virtual std::unique_ptr<ObjectiveWorker> MakeWorker() const = 0;
  /// One line for logs, e.g. "2 recordings, 660 frames".
  virtual std::string Describe() const = 0;
};

/// The calibration objective: simulate every training recording with the
/// candidate (the base model plus the model's effects; a candidate names
/// every parameter of ModelParameterSpecs(model)) and sum the XOR pixel
/// areas over all frames. A candidate is failed
/// when any recording's simulation fails; its reason names the recording
/// and frame. Its workers stop early and trace as EarlyStop asks, without
/// allocating per frame.
class RecordingObjective final : public Objective {
 public:
  /// `recordings` non-empty; `options` and `model` valid (else
  /// std::invalid_argument naming the culprit). The recordings are shared
  /// read-only by every worker.
  RecordingObjective(std::vector<std::shared_ptr<const PreparedRecording>> recordings,
                     SimulationOptions options, ModelDefinition model = {});

  std::unique_ptr<ObjectiveWorker> MakeWorker() const override;
  std::string Describe() const override;

  const std::vector<std::shared_ptr<const PreparedRecording>>& recordings() const {
    return recordings_;
  }

 private:
  std::vector<std::shared_ptr<const PreparedRecording>> recordings_;
  SimulationOptions options_;
  ModelDefinition model_;
};

/// Combines per-recording results into one ObjectiveResult (score, IoU
/// summary, first failure; kPruned when a recording was stopped by its
/// cutoff). `names` labels the recordings in the reason.
ObjectiveResult CombineRecordingResults(const std::vector<EvaluationResult>& results,
                                        const std::vector<std::string>& names);

}  // namespace calib
