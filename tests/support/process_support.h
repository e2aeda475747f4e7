#pragma once
// Running the product's executables from tests: start, wait, kill, and read
// what they printed.

#include <sys/types.h>

#include <filesystem>
#include <string>
#include <vector>

namespace calib::testing {

struct ProcessResult {
  int exit_code = -1;  ///< -1 when ended by a signal
  int signal = 0;      ///< the signal that ended it, 0 when it exited
  std::string out;     ///< what it wrote to stdout
  std::string err;     ///< what it wrote to stderr
};

/// A child process running argv[0] (a path) with stdout and stderr written
/// to files in `log_dir`. `env` holds extra NAME=VALUE settings.
class ChildProcess {
 public:
  ChildProcess(const std::vector<std::string>& argv, const std::filesystem::path& log_dir,
               const std::vector<std::string>& env = {});
  ~ChildProcess();  ///< kills and reaps it when still running
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const { return pid_; }
  /// Sends `sig` (still running only).
  void Kill(int sig);
  /// True once it has ended (does not wait).
  bool Exited();
  /// Waits for the end (killing it with SIGKILL after timeout_s seconds,
  /// which fails the test).
  ProcessResult Wait(double timeout_s = 600.0);

 private:
  pid_t pid_ = -1;
  bool reaped_ = false;
  int status_ = 0;  ///< waitpid's, once reaped
  std::filesystem::path out_path_;
  std::filesystem::path err_path_;
};

/// Starts argv and waits for it; see ChildProcess.
ProcessResult RunProcess(const std::vector<std::string>& argv, const std::filesystem::path& log_dir,
                         const std::vector<std::string>& env = {}, double timeout_s = 600.0);

/// The whole file as text ("" when absent).
std::string ReadText(const std::filesystem::path& path);

}  // namespace calib::testing
