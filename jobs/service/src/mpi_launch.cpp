#include "mpi_launch.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

extern char** environ;

namespace calib::service {
namespace {

// How often the launcher is asked whether it has ended.
constexpr auto kPoll = std::chrono::milliseconds(100);

}  // namespace

int RunOnMpiHosts(const ServiceOptions& options, const std::filesystem::path& spec_file,
                  const std::vector<std::string>& calib_args, const std::filesystem::path& log_file,
                  const std::function<bool()>& interrupted, bool comparison) {
  std::vector<std::string> args = {options.mpi_launcher.string(), "--hosts", options.mpi_hosts};
  if (!options.mpirun_args.empty()) {
    args.push_back("--mpirun-args");
    args.push_back(options.mpirun_args);
  }
  if (comparison) args.push_back("--compare");
  args.push_back("--");
  args.push_back(spec_file.string());
  args.insert(args.end(), calib_args.begin(), calib_args.end());
  // Everything the child needs is made before fork: between fork and exec
  // only async-signal-safe calls.
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::vector<std::string> env_strings = {"CALIB=" + options.calib_executable.string()};
  for (char** e = environ; *e != nullptr; ++e) {
    if (std::string_view(*e).rfind("CALIB=", 0) != 0) env_strings.emplace_back(*e);
  }
  std::vector<char*> envp;
  for (std::string& e : env_strings) envp.push_back(e.data());
  envp.push_back(nullptr);
  const int log = ::open(log_file.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
  if (log < 0) throw std::runtime_error(fmt::format("{}: cannot write", log_file.string()));
  const int null = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    // The server's threads block the stop signals (a thread of its own waits
    // for them) and ignore SIGPIPE; exec keeps both, and the launcher must
    // hear SIGTERM to pass it on.
    sigset_t none;
    ::sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    ::signal(SIGPIPE, SIG_DFL);
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(127);  // the server died before prctl
    ::setpgid(0, 0);  // a terminal's signals are the server's to handle
    ::dup2(log, STDOUT_FILENO);
    ::dup2(log, STDERR_FILENO);
    if (null >= 0) ::dup2(null, STDIN_FILENO);
    ::execve(argv[0], argv.data(), envp.data());
    ::_exit(127);
  }
  ::close(log);
  if (null >= 0) ::close(null);
  if (pid < 0) throw std::runtime_error(fmt::format("{}: cannot start (fork)", args[0]));
  bool signalled = false;
  int status = 0;
  while (true) {
    const pid_t done = ::waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (done < 0 && errno != EINTR) throw std::runtime_error(fmt::format("{}: waitpid failed", args[0]));
    if (!signalled && interrupted && interrupted()) {
      ::kill(pid, SIGTERM);  // passed on to the ranks: the job stops at a checkpoint
      signalled = true;
    }
    std::this_thread::sleep_for(kPoll);
  }
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  if (code == 0 || code == 3 || code == 4) return code;
  throw std::runtime_error(fmt::format(
      "{} --hosts {} ended with exit status {}{} (its output: {})", args[0], options.mpi_hosts, code,
      code == 127 ? " (it could not be started: --mpi-launcher)" : "", log_file.string()));
}

}  // namespace calib::service
