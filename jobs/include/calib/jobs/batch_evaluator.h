#pragma once
// Batch evaluators: how the runner gets a batch of candidates evaluated in
// parallel. The runner holds the optimiser and the store on its own thread;
// a BatchEvaluator spreads the batch over workers (OpenMP threads here, MPI
// ranks in mpi_evaluator.h) and hands finished candidates back to the
// runner's thread as they arrive.
//
// Contract of Evaluate (every implementation):
//  - Candidates are started in batch order, each on one worker, dynamically
//    (an idle worker takes the next one). Once should_stop() returns true no
//    further candidate is started; Evaluate returns when every started one
//    has finished. So the finished candidates are always a prefix of the
//    batch, and nothing is lost when a job is stopped.
//  - on_done is called on the calling thread only, with candidates in the
//    order they finished (not by id), and also with an empty vector about
//    every tick_s seconds while nothing finishes (for progress displays).
//  - A failed evaluation is retried on the same worker until it succeeds or
//    max_attempts attempts are used; an exception from the objective is a
//    failed attempt whose reason starts with "exception: ". A pruned one
//    (stopped early) is not retried.
//  - With pruning (a PruneBounds, pruning.h), each candidate is evaluated
//    with the EarlyStop that prune->StartFor(id) gives when it starts
//    (called on any thread); without, every frame and no trace.
//  - Deterministic: a candidate's result does not depend on the worker (the
//    ObjectiveWorker contract), so the runner's history does not depend on
//    the number of workers.

#include "calib/core/parameters.h"
#include "calib/jobs/objective.h"

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace calib {

struct PendingCandidate {
  int64_t id = 0;
  ParameterValues values;
};

struct FinishedCandidate {
  int64_t id = 0;
  ObjectiveResult result;  ///< of the last attempt; eval_seconds summed over attempts
  int attempts = 1;
  std::string worker;      ///< e.g. "rank 0 thread 1"
};

class PruneBounds;

class BatchEvaluator {
 public:
  virtual ~BatchEvaluator() = default;

  /// Workers evaluating concurrently (threads or worker ranks).
  virtual int workers() const = 0;
  /// One line for logs, e.g. "4 OpenMP threads".
  virtual std::string Describe() const = 0;

  /// See the contract above. max_attempts >= 1; prune: null without pruning.
  virtual void Evaluate(std::span<const PendingCandidate> batch, int max_attempts,
                        const PruneBounds* prune, const std::function<bool()>& should_stop,
                        const std::function<void(std::vector<FinishedCandidate>&&)>& on_done,
                        double tick_s) = 0;
};

/// Evaluates one candidate with retries; exceptions become failed attempts.
/// The common core of every BatchEvaluator's worker.
FinishedCandidate EvaluateWithRetries(ObjectiveWorker& worker, const PendingCandidate& candidate,
                                      const EarlyStop& stop, int max_attempts,
                                      const std::string& worker_label);

/// OpenMP: `threads` workers (schedule(dynamic, 1)), each with its own
/// ObjectiveWorker made once here. The parallel region runs on a helper
/// thread so that the caller's thread stays free for on_done.
class ThreadBatchEvaluator final : public BatchEvaluator {
 public:
  /// threads >= 1; `objective` must outlive this.
  ThreadBatchEvaluator(const Objective& objective, int threads, std::string label_prefix = "");
  ~ThreadBatchEvaluator() override;

  int workers() const override { return static_cast<int>(workers_.size()); }
  std::string Describe() const override;
  void Evaluate(std::span<const PendingCandidate> batch, int max_attempts,
                const PruneBounds* prune, const std::function<bool()>& should_stop,
                const std::function<void(std::vector<FinishedCandidate>&&)>& on_done,
                double tick_s) override;

 private:
  std::vector<std::unique_ptr<ObjectiveWorker>> workers_;
  std::string label_prefix_;
};

/// Threads a job or loop may ask for at most, per core.
inline constexpr int kMaxThreadsPerCore = 4;

/// The number of threads to use for `requested` (0: all cores, as OpenMP
/// reports them). Throws std::invalid_argument naming the value when it is
/// negative or more than kMaxThreadsPerCore times the cores.
int ResolveThreadCount(int requested);

}  // namespace calib
