#pragma once
// The ask/tell cycle: ask a batch from the optimiser, evaluate it in
// parallel (BatchEvaluator), record every evaluation in the store, tell the
// optimiser, checkpoint, repeat until the optimiser is done, the budget is
// used, the wall time is up, the job is interrupted or the failure policy
// aborts it.
//
// Determinism. The history (every evaluation's id, x, parameters, status,
// score, IoU summary, reason and attempts) depends only on the job spec and
// its seed, never on the number of threads or MPI ranks, the batch size,
// the wall-time budget, checkpoint timing or where a job was interrupted
// and resumed:
//  - the optimisers propose the same candidate sequence whatever the batch
//    size (search/optimizer.h); the evaluation budget caps how many are
//    asked, so the last batch is cut exactly;
//  - results are told in id order, and only the longest prefix of the batch
//    that has results, so a partly evaluated batch (stopped) leaves exactly
//    its later candidates outstanding;
//  - the abort-after-N rule counts failures in id order and cuts the history
//    right after the N-th failure (later evaluations of the batch are
//    deleted from the store); pruned evaluations are not failures;
//  - with pruning (budget.prune_factor, pruning.h) workers stop candidates
//    at bounds that depend on timing, but each candidate is recorded only
//    once every candidate before it is, and then decided by the exact rule
//    from its trace: where a run stopped never shows in the history;
//  - wall time and checkpoints only decide where a run stops and what is
//    saved, never what is asked or told.
// Timing fields (eval_time_s, worker, recorded_unix_s) are not part of the
// history.
//
// Resume. RunCalibration always continues from the job's newest intact
// checkpoint (none: from the start). Evaluations recorded after that
// checkpoint are reused, not re-simulated: the restored optimiser asks the
// same candidates again, and each one found in the store with the same id
// and bit-identical x is told its stored result (a different x is an
// error: the spec or the code changed). So a run killed at any moment and
// resumed produces the history of an uninterrupted run, and no evaluation
// is lost or done twice after it was recorded. (With pruning a candidate
// that finished after one still running when the run stopped is not
// recorded; the resume simulates it again.)

#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/calibration_request.h"
#include "calib/results/store.h"

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace calib {

/// Candidates asked per batch. Any value gives the same history; this one
/// keeps 16 workers busy and a batch short enough to lose little on a crash.
inline constexpr int kDefaultBatchSize = 64;

/// How one invocation (run or resume) is controlled; none of it changes the
/// history.
struct RunControl {
  /// Candidates asked at a time (>= 1).
  int batch_size = kDefaultBatchSize;
  /// This invocation's wall-time budget (the spec's budget.wall_time_s);
  /// unset: none.
  std::optional<double> wall_time_s;
  /// Polled between candidates; true stops the run resumably (SIGINT,
  /// SIGTERM). Null: never.
  std::function<bool()> interrupted;
  /// How often observers hear from a run that produces no result (s).
  double tick_s = 0.5;

  bool IsValid(std::string* error) const;
};

/// A snapshot for progress displays.
struct RunProgress {
  int64_t evaluations = 0;       ///< told, over the whole job
  int64_t budget = 0;            ///< the spec's budget.evaluations
  int64_t failed = 0;            ///< over the whole job, the current batch's included
  int64_t pruned = 0;            ///< as `failed`, the pruned ones (not failures)
  int64_t evaluated_now = 0;     ///< simulated by this invocation
  int64_t running = 0;           ///< finished in the current batch, not yet told
  std::optional<double> best_score;
  int64_t best_id = -1;
  double elapsed_s = 0.0;        ///< this invocation
};

/// Hears what the runner does; called on the runner's thread. Presentation
/// only: nothing here may change the run.
class RunObserver {
 public:
  virtual ~RunObserver() = default;
  virtual void OnStart(const RunProgress& /*progress*/, const std::string& /*what*/) {}
  virtual void OnProgress(const RunProgress& /*progress*/) {}
  virtual void OnCheckpoint(const RunProgress& /*progress*/, int64_t /*sequence*/) {}
  virtual void OnWarning(const std::string& /*message*/) {}
  virtual void OnFinish(const RunProgress& /*progress*/) {}
};

struct RunSummary {
  JobStatus status = JobStatus::kCreated;  ///< kCreated: not run
  std::string stop_reason;
  int64_t evaluations = 0;    ///< told over the whole job
  int64_t evaluated_now = 0;  ///< simulated by this invocation
  int64_t reused = 0;         ///< taken from the store (recorded after the checkpoint)
  int64_t failed = 0;         ///< over the whole job
  int64_t pruned = 0;         ///< over the whole job (not failures)
  int64_t deleted = 0;        ///< evaluations removed past an abort cut or the budget
  std::optional<EvaluationRecord> best;
  std::optional<int64_t> resumed_from_checkpoint;  ///< its sequence
  int64_t checkpoints_written = 0;
  std::vector<std::string> warnings;  ///< e.g. corrupted checkpoints skipped
  double seconds = 0.0;               ///< this invocation
  double job_seconds = 0.0;           ///< every invocation of the job

  /// A few lines: status, counts, best score and its id.
  std::string BriefReport() const;
};

/// Runs (or continues) job `job` of `store`: the search `request` asks for,
/// over the objective `evaluator` evaluates (a job spec is a request, as
/// are the loop's stage calibrations). Sets the job's status (running, then
/// finished / stopped / aborted) and stop reason. Throws for errors
/// (StoreError, a checkpoint that does not fit the request, a reused
/// evaluation whose x differs); the caller marks the job failed.
RunSummary RunCalibration(const CalibrationRequest& request, ResultStore& store, int64_t job,
                          BatchEvaluator& evaluator, const RunControl& control,
                          RunObserver* observer = nullptr);

}  // namespace calib
