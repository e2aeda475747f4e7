#include "support/process_support.h"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

namespace calib::testing {
namespace {

std::atomic<int> g_counter{0};

}  // namespace

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

ChildProcess::ChildProcess(const std::vector<std::string>& argv,
                           const std::filesystem::path& log_dir,
                           const std::vector<std::string>& env) {
  const int n = g_counter++;
  out_path_ = log_dir / ("process_" + std::to_string(n) + ".out");
  err_path_ = log_dir / ("process_" + std::to_string(n) + ".err");
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  std::fflush(nullptr);
  pid_ = fork();
  if (pid_ == 0) {
    const int out = open(out_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err = open(err_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (out < 0 || err < 0) _exit(126);
    dup2(out, STDOUT_FILENO);
    dup2(err, STDERR_FILENO);
    const int null = open("/dev/null", O_RDONLY);
    if (null >= 0) dup2(null, STDIN_FILENO);
    // Its own process group, so that a kill reaches what it starts (mpirun).
    setpgid(0, 0);
    for (const std::string& e : env) putenv(const_cast<char*>(e.c_str()));
    execv(args[0], args.data());
    _exit(127);
  }
  EXPECT_GT(pid_, 0) << "fork failed";
}

ChildProcess::~ChildProcess() {
  if (pid_ > 0 && !reaped_) {
    ::kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
  }
}

void ChildProcess::Kill(int sig) {
  if (pid_ > 0 && !Exited()) ::kill(pid_, sig);
}

bool ChildProcess::Exited() {
  if (pid_ <= 0 || reaped_) return true;
  if (waitpid(pid_, &status_, WNOHANG) == pid_) reaped_ = true;
  return reaped_;
}

ProcessResult ChildProcess::Wait(double timeout_s) {
  ProcessResult result;
  if (pid_ <= 0) return result;
  const auto start = std::chrono::steady_clock::now();
  int& status = status_;
  while (!reaped_) {
    const pid_t r = waitpid(pid_, &status, WNOHANG);
    if (r == pid_) break;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >
        timeout_s) {
      ADD_FAILURE() << "process " << pid_ << " still running after " << timeout_s
                    << " s; killed";
      ::kill(pid_, SIGKILL);
      waitpid(pid_, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  reaped_ = true;
  if (WIFEXITED(status)) {
    result.exit_code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    result.signal = WTERMSIG(status);
  }
  result.out = ReadText(out_path_);
  result.err = ReadText(err_path_);
  return result;
}

ProcessResult RunProcess(const std::vector<std::string>& argv, const std::filesystem::path& log_dir,
                         const std::vector<std::string>& env, double timeout_s) {
  ChildProcess child(argv, log_dir, env);
  return child.Wait(timeout_s);
}

}  // namespace calib::testing
