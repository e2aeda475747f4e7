// Internal: a child process spoken to in lines (line_process.h).

#include "line_process.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <thread>

#include <fmt/format.h>

namespace calib::search::internal {
namespace {

void CloseFd(int* fd) {
  if (*fd >= 0) ::close(*fd);
  *fd = -1;
}

}  // namespace

LineProcess::LineProcess(const std::vector<std::string>& argv) {
  if (argv.empty()) throw std::runtime_error("no command to run");
  // A reader that went away must be a failed write, not the end of calib.
  ::signal(SIGPIPE, SIG_IGN);
  int in_pipe[2], out_pipe[2], exec_pipe[2];
  if (::pipe(in_pipe) != 0 || ::pipe(out_pipe) != 0 || ::pipe2(exec_pipe, O_CLOEXEC) != 0) {
    throw std::runtime_error(fmt::format("cannot make pipes: {}", std::strerror(errno)));
  }
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(fmt::format("cannot fork: {}", std::strerror(errno)));
  if (pid == 0) {
    ::dup2(in_pipe[0], STDIN_FILENO);
    ::dup2(out_pipe[1], STDOUT_FILENO);
    ::close(in_pipe[0]);
    ::close(in_pipe[1]);
    ::close(out_pipe[0]);
    ::close(out_pipe[1]);
    ::close(exec_pipe[0]);
    ::execvp(args[0], args.data());
    const int error = errno;  // exec failed: tell the parent why
    (void)!::write(exec_pipe[1], &error, sizeof error);
    ::_exit(127);
  }
  ::close(in_pipe[0]);
  ::close(out_pipe[1]);
  ::close(exec_pipe[1]);
  pid_ = pid;
  to_child_ = in_pipe[1];
  from_child_ = out_pipe[0];
  int error = 0;
  const ssize_t n = ::read(exec_pipe[0], &error, sizeof error);  // 0: exec succeeded (closed on exec)
  ::close(exec_pipe[0]);
  if (n == static_cast<ssize_t>(sizeof error)) {
    Kill();
    CloseFd(&to_child_);
    CloseFd(&from_child_);
    throw std::runtime_error(fmt::format("cannot run '{}': {}", argv[0], std::strerror(error)));
  }
}

LineProcess::~LineProcess() {
  CloseFd(&to_child_);
  if (pid_ > 0 && !WaitForEnd(1.0)) Kill();
  CloseFd(&from_child_);
}

bool LineProcess::WriteLine(const std::string& line) {
  const std::string text = line + "\n";
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(to_child_, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

LineProcess::ReadStatus LineProcess::ReadLine(double timeout_s, std::string* line) {
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                             std::chrono::duration<double>(timeout_s));
  for (;;) {
    const size_t newline = buffer_.find('\n');
    if (newline != std::string::npos) {
      *line = buffer_.substr(0, newline);
      buffer_.erase(0, newline + 1);
      return ReadStatus::kLine;
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return ReadStatus::kTimedOut;
    pollfd p{from_child_, POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(left.count()));
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) return ReadStatus::kTimedOut;
    char chunk[4096];
    const ssize_t n = ::read(from_child_, chunk, sizeof chunk);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return ReadStatus::kEnded;
    buffer_.append(chunk, static_cast<size_t>(n));
  }
}

bool LineProcess::WaitForEnd(double seconds) {
  for (int i = 0; !wait_status_ && i < static_cast<int>(seconds * 200); ++i) {
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      wait_status_ = status;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  return wait_status_.has_value();
}

void LineProcess::Kill() {
  if (pid_ <= 0 || wait_status_) return;
  ::kill(pid_, SIGKILL);
  int status = 0;
  if (::waitpid(pid_, &status, 0) == pid_) wait_status_ = status;
}

std::string LineProcess::HowItEnded() {
  if (!WaitForEnd(1.0)) return "closed its output";  // its output closed: a moment to be reaped
  if (WIFEXITED(*wait_status_)) return fmt::format("exited with status {}", WEXITSTATUS(*wait_status_));
  if (WIFSIGNALED(*wait_status_)) return fmt::format("was killed by signal {}", WTERMSIG(*wait_status_));
  return "ended";
}

}  // namespace calib::search::internal
