#include "calib/jobs/job_lock.h"

#include <fmt/format.h>

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <climits>
#include <random>
#include <stdexcept>

namespace calib {

bool JobLockOptions::IsValid(std::string* error) const {
  if (!(heartbeat_s > 0.0)) {
    *error = fmt::format("JobLockOptions::heartbeat_s = {}. Violated: heartbeat_s > 0.", heartbeat_s);
    return false;
  }
  if (!(stale_after_s > heartbeat_s)) {
    *error = fmt::format(
        "JobLockOptions::stale_after_s = {}. Violated: stale_after_s > heartbeat_s ({}).",
        stale_after_s, heartbeat_s);
    return false;
  }
  return true;
}

std::string ThisHostName() {
  char name[HOST_NAME_MAX + 1] = {};
  if (::gethostname(name, sizeof name - 1) != 0 || name[0] == '\0') return "unknown";
  return name;
}

bool JobLockHolderStopped(const JobLock& holder, double heartbeat_age_s,
                          const JobLockOptions& options) {
  if (heartbeat_age_s > options.stale_after_s) return true;
  // On this host a process that no longer exists has stopped, whatever its
  // heartbeat says (kill with signal 0 only checks; EPERM: it exists).
  return holder.host == ThisHostName() && holder.pid > 0 &&
         ::kill(static_cast<pid_t>(holder.pid), 0) != 0 && errno == ESRCH;
}

std::string DescribeJobLockHolder(const JobLock& holder, double heartbeat_age_s) {
  return fmt::format("process {} on host '{}' (last heartbeat {:.0f} s ago)", holder.pid,
                     holder.host, heartbeat_age_s);
}

namespace {

std::string NewToken(const std::string& host) {
  std::random_device device;
  const uint64_t bits = (static_cast<uint64_t>(device()) << 32) ^ device();
  return fmt::format("{}:{}:{:016x}", host, ::getpid(), bits);
}

}  // namespace

HeldJobLock::HeldJobLock(ResultStore& store, int64_t job, const std::string& job_name,
                         const JobLockOptions& options)
    : store_(store), job_(job), options_(options) {
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument(error);
  JobLock claim;
  claim.pid = ::getpid();
  claim.host = ThisHostName();
  claim.token = NewToken(claim.host);
  token_ = claim.token;
  const auto stopped = [this](const JobLock& holder, double age_s) {
    return JobLockHolderStopped(holder, age_s, options_);
  };
  try {
    taken_over_ = store_.AcquireJobLock(job_, claim, stopped);
    if (taken_over_) taken_over_age_s_ = NowUnixSeconds() - taken_over_->heartbeat_unix_s;
  } catch (const JobLockedError& e) {
    const double age_s = NowUnixSeconds() - e.holder().heartbeat_unix_s;
    throw JobLockedError(
        fmt::format("{}: job '{}' is held by {}: another `calib run` or `calib resume` is working "
                    "on it; wait for it to end or stop it (Ctrl-C, SIGTERM). A holder silent for "
                    "more than {} s is taken over",
                    store_.path().string(), job_name, DescribeJobLockHolder(e.holder(), age_s),
                    options_.stale_after_s),
        e.holder());
  }
  heartbeat_ = std::thread([this, path = store_.path()] {
    // Its own connection: a ResultStore is used by one thread only.
    std::optional<ResultStore> own;
    std::unique_lock<std::mutex> lock(mutex_);
    const auto period = std::chrono::duration<double>(options_.heartbeat_s);
    while (!wake_.wait_for(lock, period, [this] { return stopping_; })) {
      try {
        if (!own) own.emplace(path);
        if (!own->HeartbeatJobLock(job_, token_)) {
          lost_ = true;
          return;
        }
      } catch (const std::exception&) {
        // A busy or briefly unreadable store: try again at the next beat.
        // Nothing may escape this thread.
      }
    }
  });
}

HeldJobLock::~HeldJobLock() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  heartbeat_.join();
  try {
    store_.ReleaseJobLock(job_, token_);
  } catch (const std::exception&) {
    // The store failed (a full disk): the lock stays, and is taken over
    // once this process is gone.
  }
}

}  // namespace calib
