#pragma once
// The service's job queue, kept in the results store (table job_queue,
// schema version 3) so that it outlives the server: a job submitted and not
// finished when the server is killed is found again when it restarts.
//
// An entry is a piece of work by name (unique in the queue, as in the store)
// of a kind: a calibration job (its canonical spec, jobs/job_spec.h ToJson),
// a loop (`calib loop`, its spec discovery/loop_spec.h) or an optimiser
// comparison (`calib compare-optimizers`, its spec as submitted,
// jobs/comparison_spec.h); with a priority (higher first) and its
// submission order (the entry id: earlier first among equal priorities).
// States: queued -> running -> done, or cancelled (from queued or running);
// a done or cancelled entry is queued again by resume or an extended
// budget. The job's own status (finished, stopped, ...) is the store's.
//
// Thread-safe: one connection of its own, used under a mutex (the server's
// request threads and its workers share one JobQueue).

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace calib {

enum class QueueState { kQueued, kRunning, kDone, kCancelled };
std::string ToString(QueueState state);  ///< "queued", "running", "done", "cancelled"
/// Throws std::invalid_argument naming the value.
QueueState QueueStateFromString(const std::string& name);

/// What an entry runs.
enum class QueueKind { kJob, kLoop, kComparison };
std::string ToString(QueueKind kind);  ///< "job", "loop", "comparison"
/// Throws std::invalid_argument naming the value and the kinds.
QueueKind QueueKindFromString(const std::string& name);

struct QueueEntry {
  int64_t id = 0;  ///< submission order
  std::string name;
  QueueKind kind = QueueKind::kJob;
  nlohmann::json spec;  ///< the kind's spec
  int64_t priority = 0;
  double submitted_unix_s = 0.0;
  QueueState state = QueueState::kQueued;
  bool resume = false;  ///< continue the job in the store (false: start it)
  std::string message;  ///< why it is done or cancelled (an error, "cancelled by a request")
};

class JobQueue {
 public:
  /// Opens the store at `store` (creating or migrating it, ResultStore) and
  /// the queue in it. Throws StoreError naming the path.
  explicit JobQueue(const std::filesystem::path& store);
  ~JobQueue();
  JobQueue(const JobQueue&) = delete;
  JobQueue& operator=(const JobQueue&) = delete;

  /// Queues a new entry; returns its id. Throws StoreError when the name is
  /// in the queue already.
  int64_t Add(const std::string& name, QueueKind kind, const nlohmann::json& spec, int64_t priority,
              bool resume);
  /// The next queued entry (highest priority, then lowest id), marked
  /// running; nullopt when none is queued.
  std::optional<QueueEntry> ClaimNext();
  /// Sets an entry's state, message, and whether a start resumes the job.
  void Set(int64_t id, QueueState state, const std::string& message, bool resume);
  /// Replaces the entry's spec (an extended budget).
  void SetSpec(int64_t id, const nlohmann::json& spec);
  std::optional<QueueEntry> Find(const std::string& name) const;
  /// By id.
  std::vector<QueueEntry> Entries() const;
  void Remove(int64_t id);
  /// After a restart: every entry left running (its server was killed) is
  /// queued again to resume; returns how many.
  int64_t RequeueRunning();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  mutable std::mutex mutex_;
};

}  // namespace calib
