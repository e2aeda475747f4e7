#pragma once
// One process works on a job at a time. `calib run` and `calib resume` take
// the job's lock in the results store (ResultStore::AcquireJobLock: process
// id, host, a token unique to this acquisition) before they change anything,
// renew its heartbeat from a thread of their own while they work, and
// release it when they end. A second run or resume of a held job is refused
// naming the holder (JobLockedError, exit 2).
//
// A holder is taken over when it has stopped:
//  - its heartbeat is older than JobLockOptions::stale_after_s (any host: a
//    killed process, a machine gone), or
//  - it is on this host and its process no longer exists (SIGKILL, a
//    crash): taken over at once, so a killed job resumes without waiting.
//    (Hosts are told apart by name: containers that share a host name must
//    also share the process table.)
// A holder paused past stale_after_s (SIGSTOP, a suspended laptop) loses
// its lock; it notices at its next heartbeat and stops resumably, but what
// it wrote between losing the lock and noticing may clash with the new
// holder's writes. Keep stale_after_s well above any such pause.

#include "calib/results/store.h"

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace calib {

struct JobLockOptions {
  /// Seconds between heartbeats, > 0.
  double heartbeat_s = 5.0;
  /// A holder whose heartbeat is older than this (s) is taken over; must be
  /// larger than heartbeat_s.
  double stale_after_s = 60.0;

  bool IsValid(std::string* error) const;
};

/// This machine's host name ("unknown" when it cannot be read).
std::string ThisHostName();

/// Whether `holder`, whose heartbeat is `heartbeat_age_s` old, has stopped
/// (see the top of this file): the policy AcquireJobLock applies, and what
/// `calib results` uses to call a job left running interrupted.
bool JobLockHolderStopped(const JobLock& holder, double heartbeat_age_s,
                          const JobLockOptions& options);

/// "process 123 on host 'h' (last heartbeat 4 s ago)".
std::string DescribeJobLockHolder(const JobLock& holder, double heartbeat_age_s);

/// Holds a job's lock for its lifetime: takes it on construction (throws
/// JobLockedError naming the job and the holder when a live process holds
/// it), renews the heartbeat from a thread with its own connection to the
/// store, releases it on destruction.
class HeldJobLock {
 public:
  /// `store` is the caller's connection (used on this thread only);
  /// `job_name` names the job in messages.
  HeldJobLock(ResultStore& store, int64_t job, const std::string& job_name,
              const JobLockOptions& options = {});
  ~HeldJobLock();
  HeldJobLock(const HeldJobLock&) = delete;
  HeldJobLock& operator=(const HeldJobLock&) = delete;

  /// The stopped holder this lock was taken over from, if any, and how old
  /// its heartbeat was then (s).
  const std::optional<JobLock>& taken_over() const { return taken_over_; }
  double taken_over_age_s() const { return taken_over_age_s_; }
  /// True once a heartbeat found the lock taken over by another process.
  bool lost() const { return lost_.load(); }

 private:
  ResultStore& store_;
  int64_t job_;
  JobLockOptions options_;
  std::string token_;
  std::optional<JobLock> taken_over_;
  double taken_over_age_s_ = 0.0;
  std::atomic<bool> lost_{false};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread heartbeat_;
};

}  // namespace calib
