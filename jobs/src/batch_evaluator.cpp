#include "calib/jobs/batch_evaluator.h"

#include "calib/jobs/pruning.h"

#include <fmt/format.h>
#include <omp.h>

#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace calib {

FinishedCandidate EvaluateWithRetries(ObjectiveWorker& worker, const PendingCandidate& candidate,
                                      const EarlyStop& stop, int max_attempts,
                                      const std::string& worker_label) {
  FinishedCandidate finished;
  finished.id = candidate.id;
  finished.worker = worker_label;
  double seconds = 0.0;
  for (int attempt = 1; attempt <= max_attempts; ++attempt) {
    const auto start = std::chrono::steady_clock::now();
    try {
      finished.result = worker.Evaluate(candidate.values, stop);
    } catch (const std::exception& e) {
      finished.result = ObjectiveResult{};
      finished.result.reason = fmt::format("exception: {}", e.what());
    } catch (...) {
      finished.result = ObjectiveResult{};
      finished.result.reason = "exception: unknown";
    }
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    finished.attempts = attempt;
    if (finished.result.status != CandidateStatus::kFailed) break;
  }
  finished.result.eval_seconds = seconds;
  return finished;
}

int ResolveThreadCount(int requested) {
  const int cores = std::max(1, omp_get_num_procs());
  if (requested < 0) {
    throw std::invalid_argument(fmt::format("threads = {}: must be >= 0 (0: all cores)", requested));
  }
  if (requested > kMaxThreadsPerCore * cores) {
    // More would only oversubscribe the cores; far more exhausts memory or
    // the OpenMP runtime's thread limit mid-job.
    throw std::invalid_argument(fmt::format(
        "threads = {}: more than {} times the {} cores of this machine", requested,
        kMaxThreadsPerCore, cores));
  }
  return requested == 0 ? cores : requested;
}

ThreadBatchEvaluator::ThreadBatchEvaluator(const Objective& objective, int threads,
                                           std::string label_prefix)
    : label_prefix_(std::move(label_prefix)) {
  if (threads < 1) {
    throw std::invalid_argument(fmt::format("threads = {}: must be >= 1", threads));
  }
  workers_.reserve(threads);
  for (int t = 0; t < threads; ++t) workers_.push_back(objective.MakeWorker());
}

ThreadBatchEvaluator::~ThreadBatchEvaluator() = default;

std::string ThreadBatchEvaluator::Describe() const {
  return fmt::format("{} OpenMP thread{}", workers_.size(), workers_.size() == 1 ? "" : "s");
}

void ThreadBatchEvaluator::Evaluate(
    std::span<const PendingCandidate> batch, int max_attempts, const PruneBounds* prune,
    const std::function<bool()>& should_stop,
    const std::function<void(std::vector<FinishedCandidate>&&)>& on_done, double tick_s) {
  if (max_attempts < 1) throw std::invalid_argument("max_attempts must be >= 1");
  if (batch.empty()) return;

  std::mutex mutex;
  std::condition_variable ready;
  std::vector<FinishedCandidate> finished;  // guarded by mutex
  size_t next = 0;                          // next index to start; guarded by mutex
  bool stop = false;                        // no more starts; guarded by mutex
  bool all_done = false;                    // guarded by mutex
  std::exception_ptr error;                 // guarded by mutex

  // The OpenMP team lives on a helper thread, so this thread can write to
  // the store and draw progress while candidates run.
  std::thread team([&] {
    const int threads = static_cast<int>(workers_.size());
    // Dynamic scheduling with chunks of one (as schedule(dynamic, 1)), but
    // claiming the next index and checking `stop` under one lock: starts
    // happen in batch order and none after a stop, so what finishes is a
    // prefix of the batch.
#pragma omp parallel num_threads(threads)
    {
      const int thread = omp_get_thread_num();
      const std::string label = fmt::format("{}thread {}", label_prefix_, thread);
      while (true) {
        size_t index;
        {
          std::lock_guard<std::mutex> lock(mutex);
          if (stop || error || next >= batch.size()) break;
          index = next++;
        }
        try {
          const EarlyStop stop = prune ? prune->StartFor(batch[index].id) : EarlyStop{};
          FinishedCandidate done =
              EvaluateWithRetries(*workers_[thread], batch[index], stop, max_attempts, label);
          std::lock_guard<std::mutex> lock(mutex);
          finished.push_back(std::move(done));
        } catch (...) {  // e.g. bad_alloc outside the objective: never escapes a thread
          std::lock_guard<std::mutex> lock(mutex);
          if (!error) error = std::current_exception();
        }
        ready.notify_one();
      }
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      all_done = true;
    }
    ready.notify_one();
  });

  std::exception_ptr caller_error;
  const auto tick = std::chrono::duration<double>(tick_s > 0.0 ? tick_s : 1.0);
  while (true) {
    std::vector<FinishedCandidate> items;
    bool done;
    {
      std::unique_lock<std::mutex> lock(mutex);
      ready.wait_for(lock, tick, [&] { return !finished.empty() || all_done; });
      items.swap(finished);
      done = all_done;
    }
    if (caller_error) {
      if (done) break;
      continue;
    }
    try {
      if (should_stop()) {
        std::lock_guard<std::mutex> lock(mutex);
        stop = true;
      }
      on_done(std::move(items));
    } catch (...) {
      caller_error = std::current_exception();
      std::lock_guard<std::mutex> lock(mutex);
      stop = true;
    }
    if (done) {
      std::lock_guard<std::mutex> lock(mutex);
      if (finished.empty()) break;
    }
  }
  team.join();
  if (caller_error) std::rethrow_exception(caller_error);
  if (error) std::rethrow_exception(error);
}

}  // namespace calib
