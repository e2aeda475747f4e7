#pragma once
// Several processes, on one machine or many, with MPI (OpenMPI): a
// manager-worker scheme with dynamic scheduling.
//
// Rank 0 is the manager: it runs the optimiser, the store, checkpoints and
// progress (RunCalibration with an MpiBatchEvaluator) and evaluates nothing
// itself. Every other rank is a worker (RunMpiWorker): it prepares the
// recordings once, then evaluates one candidate per message until told to
// stop. The manager hands the next candidate of the batch to whichever
// worker is idle, so fast and slow machines mix well. Because the runner
// asks, tells and records exactly as with threads, `mpirun -np N calib run`
// gives the same history as `calib run` at any thread count.
//
// Messages (MPI_COMM_WORLD, packed bytes, native endianness: one cluster of
// one architecture):
//   worker -> manager  kReady   status (0 ok, 1 error) and a message
//   manager -> worker  kWork    candidate id, max attempts, parameter values,
//                               the EarlyStop (pruning.h)
//   worker -> manager  kResult  the FinishedCandidate (with the trace of the
//                               score so far when pruning: a double a frame)
//   manager -> worker  kStop    (empty)
//   manager -> worker  kNextJob the index of the job the ranks run next, or
//                               -1: none (several jobs on the same ranks,
//                               one after the other: a comparison's runs)

#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/objective.h"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace calib {

/// True when the environment says this process was started by an MPI
/// launcher (mpirun, mpiexec, srun with PMI/PMIx). Does not initialise MPI.
bool LaunchedByMpi();

/// MPI_Init_thread (MPI_THREAD_FUNNELED) in the constructor, MPI_Finalize in
/// the destructor. One per process, made only when LaunchedByMpi().
class MpiSession {
 public:
  MpiSession(int* argc, char*** argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  /// MPI_Abort on every rank (after a fatal error on one).
  [[noreturn]] void Abort(int code);

 private:
  int rank_ = 0;
  int size_ = 1;
};

/// The manager's side (rank 0 of `size` ranks, size >= 2).
class MpiBatchEvaluator final : public BatchEvaluator {
 public:
  explicit MpiBatchEvaluator(int size);
  /// Sends kStop to every worker (StopWorkers).
  ~MpiBatchEvaluator() override;

  /// Waits for every worker's kReady. Throws std::runtime_error naming each
  /// rank that could not start and its message.
  void WaitForWorkers();
  /// Tells every worker to stop; idempotent. Call on every path out of the
  /// manager (the destructor does), or the workers wait forever.
  void StopWorkers();

  int workers() const override { return size_ - 1; }
  std::string Describe() const override;
  void Evaluate(std::span<const PendingCandidate> batch, int max_attempts,
                const PruneBounds* prune, const std::function<bool()>& should_stop,
                const std::function<void(std::vector<FinishedCandidate>&&)>& on_done,
                double tick_s) override;

 private:
  int size_;
  bool stopped_ = false;
};

/// The worker's side: builds the objective with make_objective (a throw is
/// reported to the manager as this rank's start-up error), makes one
/// ObjectiveWorker, evaluates candidates until kStop. Returns the number of
/// candidates evaluated. `rank` labels the evaluations ("rank 2").
int64_t RunMpiWorker(const std::function<std::unique_ptr<Objective>()>& make_objective, int rank);

/// Several jobs on the same ranks, one after the other (an optimiser
/// comparison's runs): before each job the manager tells every worker of
/// the `size` ranks which job comes next (an index >= 0), and -1 when none
/// does. Each job is then one RunMpiWorker on every worker.
void SendNextJob(int size, int32_t index);
/// The worker's side: waits for the manager's next index (-1: none).
int32_t ReceiveNextJob();

}  // namespace calib
