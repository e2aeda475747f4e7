// What a start of the calib program costs before it does anything: the
// dynamic loader's work on the libraries it links. Every command, MPI rank,
// service worker and test process pays it. OpenCV's videoio and imgcodecs
// (some 220 libraries) are loaded only when a video or image file is first
// read or written (evaluator/include/calib/evaluator/media.h), so `calib
// --help` maps neither.
//
//   build/bench/calib_bench --benchmark_filter=ProgramStart

#include <benchmark/benchmark.h>
#include <spawn.h>
#include <sys/wait.h>

#include <fcntl.h>
#include <unistd.h>

#include <string>

extern char** environ;

namespace calib::bench {
namespace {

// `calib --help`, its output to /dev/null, waited for.
void BM_ProgramStart(benchmark::State& state) {
  std::string exe = CALIB_EXE, help = "--help";
  char* argv[] = {exe.data(), help.data(), nullptr};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  for (auto _ : state) {
    pid_t pid = 0;
    if (posix_spawn(&pid, exe.c_str(), &actions, nullptr, argv, environ) != 0) {
      state.SkipWithError(("cannot start " + exe).c_str());
      break;
    }
    int status = 0;
    waitpid(pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
      state.SkipWithError((exe + " --help failed").c_str());
      break;
    }
  }
  posix_spawn_file_actions_destroy(&actions);
}
BENCHMARK(BM_ProgramStart)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace calib::bench
