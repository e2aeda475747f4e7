// The runner's cost (jobs/include/calib/jobs/runner.h): a whole calibration
// job, from the optimiser's asks to the results store's transactions and
// checkpoints, with
//  - a trivial objective (nothing to simulate): what the runner itself costs
//    per evaluation, to compare with BM_FullEvaluation of the reference
//    scene (evaluation_bench.cpp);
//  - the reference scene as the objective: evaluations per second at 1, 2,
//    4, ... threads up to the machine's, and so the parallel efficiency.
//
//   build/bench/calib_bench --benchmark_filter=Runner

#include "reference_scene.h"

#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/objective.h"
#include "calib/jobs/runner.h"
#include "calib/results/store.h"

#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <thread>

namespace calib::bench {
namespace {

namespace fs = std::filesystem;

// Returns a score at once: the runner's work only.
class TrivialObjective final : public Objective {
 public:
  std::unique_ptr<ObjectiveWorker> MakeWorker() const override {
    struct Worker final : ObjectiveWorker {
      using ObjectiveWorker::Evaluate;
      ObjectiveResult Evaluate(const ParameterValues& values, const EarlyStop& /*stop*/) override {
        ObjectiveResult r;
        r.status = CandidateStatus::kOk;
        r.score = values.at("k_D") + values.at("tau");
        r.iou.mean = r.iou.min = r.iou.max = 0.9;
        r.iou.frames_scored = r.iou.frames_total = 330;
        return r;
      }
    };
    return std::make_unique<Worker>();
  }
  std::string Describe() const override { return "trivial"; }
};

// Random search around the reference parameters (all stable), checkpoints
// as a job would write them.
JobSpec BenchSpec(int64_t evaluations) {
  const std::string text = fmt::format(R"yaml(
name: bench
train: [reference_scene]
parameters:
  - {{name: k_D,   lower: 350, upper: 450}}
  - {{name: k_d,   lower: 1.8, upper: 2.2}}
  - {{name: k_A,   lower: 180, upper: 220}}
  - {{name: k_phi, lower: 45,  upper: 55}}
  - {{name: mass,  fixed: 1}}
  - {{name: tau,   lower: 0.09, upper: 0.11}}
optimizer: {{name: random}}
budget: {{evaluations: {}}}
checkpoint: {{every_evaluations: 64, every_seconds: 0}}
)yaml",
                                       evaluations);
  JobSpecParseOptions options;
  options.recordings = RecordingCheck::kNone;
  return ParseJobSpec(text, "bench.yaml", fs::temp_directory_path(), options);
}

// Runs the whole job once per iteration in a fresh store; counts evaluations.
void RunJobs(benchmark::State& state, const Objective& objective, int64_t evaluations) {
  const int threads = static_cast<int>(state.range(0));
  const JobSpec spec = BenchSpec(evaluations);
  const fs::path dir = fs::temp_directory_path() / fmt::format("calib_bench_{}", ::getpid());
  ThreadBatchEvaluator evaluator(objective, threads);
  RunControl control;
  control.batch_size = 64;
  int64_t done = 0;
  int run = 0;
  for (auto _ : state) {
    state.PauseTiming();
    fs::remove_all(dir);
    fs::create_directories(dir);
    ResultStore store(dir / fmt::format("run{}.sqlite", run++));
    const int64_t job = store.CreateJob(spec.name, ToJson(spec));
    state.ResumeTiming();
    const RunSummary summary = RunCalibration(spec, store, job, evaluator, control);
    done += summary.evaluations;
    if (summary.failed > 0) state.SkipWithError("an evaluation failed");
  }
  fs::remove_all(dir);
  state.SetItemsProcessed(done);  // items/s = evaluations per second
  state.counters["threads"] = threads;
  state.counters["s_per_eval"] = benchmark::Counter(
      static_cast<double>(done), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// 1, 2, 4, ... threads up to the machine's hardware threads, and that
// count itself when it is not a power of two.
void ThreadCounts(benchmark::internal::Benchmark* b) {
  const int hardware = std::max(2, static_cast<int>(std::thread::hardware_concurrency()));
  for (int t = 1; t < hardware; t *= 2) b->Arg(t);
  b->Arg(hardware);
}

void BM_RunnerOverheadTrivialObjective(benchmark::State& state) {
  static const TrivialObjective objective;
  RunJobs(state, objective, 1024);
}
BENCHMARK(BM_RunnerOverheadTrivialObjective)
    ->Apply(ThreadCounts)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_RunnerThroughputReferenceScene(benchmark::State& state) {
  static const RecordingObjective objective(
      {std::make_shared<const PreparedRecording>(MakeReferenceScene())}, SimulationOptions{});
  // Eight evaluations a thread, at least 16: every thread has work for the
  // whole job, so the figure is throughput, not the last batch's tail.
  RunJobs(state, objective, std::max<int64_t>(16, 8 * state.range(0)));
}
BENCHMARK(BM_RunnerThroughputReferenceScene)
    ->Apply(ThreadCounts)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(2);

}  // namespace
}  // namespace calib::bench
