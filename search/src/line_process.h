// Internal: a child process spoken to in lines over its standard input and
// output (the external optimiser's transport), with a time limit on each
// reply. POSIX: fork, execvp, pipes, poll.
#pragma once

#include <sys/types.h>

#include <optional>
#include <string>
#include <vector>

namespace calib::search::internal {

class LineProcess {
 public:
  // Starts argv (argv[0] found on PATH or as a path). Throws
  // std::runtime_error naming it when it cannot be started.
  explicit LineProcess(const std::vector<std::string>& argv);
  // Closes its input, waits up to a second for it to end, then kills it.
  ~LineProcess();
  LineProcess(const LineProcess&) = delete;
  LineProcess& operator=(const LineProcess&) = delete;

  // Writes `line` and a newline; false when the process no longer reads.
  bool WriteLine(const std::string& line);

  enum class ReadStatus { kLine, kEnded, kTimedOut };
  // The next line (without its newline) within timeout_s seconds.
  ReadStatus ReadLine(double timeout_s, std::string* line);

  // Kills the process (SIGKILL) and reaps it.
  void Kill();
  // After kEnded: how it ended ("exited with status 3", "was killed by
  // signal 9"), waiting for it; "is still running" if it has not ended.
  std::string HowItEnded();

 private:
  // Reaps the process if it ends within `seconds`; whether it has ended.
  bool WaitForEnd(double seconds);

  pid_t pid_ = -1;
  int to_child_ = -1;
  int from_child_ = -1;
  std::string buffer_;
  std::optional<int> wait_status_;
};

}  // namespace calib::search::internal
