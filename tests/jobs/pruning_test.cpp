// Early stopping of hopeless candidates (budget.prune_factor, pruning.h):
// off unless the spec asks; on, every evaluation follows the rule recomputed
// from the recorded history, and the history is the same at any thread count
// and batch size and after stops and resumes; a pruned evaluation is not a
// failure; a worker given a bound stops early with the trace of a full run.

#include "calib/jobs/pruning.h"

#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/job_commands.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/runner.h"
#include "jobs/job_test_support.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <mutex>
#include <optional>

namespace calib {
namespace {

namespace fs = std::filesystem;

using testing::JobRun;
using testing::RunJobIn;
using testing::SyntheticObjective;

constexpr double kFactor = 1.5;
constexpr double kFailAboveTau = 0.45;

// A random search (many hopeless candidates) with pruning at kFactor.
JobSpec PrunedSpec(const std::string& extra = "", const std::string& name = "pruned") {
  return testing::SyntheticJobSpec(
      "{name: random}",
      fmt::format("budget: {{evaluations: 80, prune_factor: {}}}\n{}", kFactor, extra), name);
}

// Checks every evaluation of `history` (of SyntheticObjective with
// fail_above_tau = kFailAboveTau: a frame scores f = Score(values), 10
// frames, 3 when it fails) against pruning.h's rule recomputed from the
// history: pruned at the first frame whose score so far exceeds
// B(i) = kFactor x the lowest ok score before it, else as it finished.
// Returns how many were pruned.
int64_t ExpectThePruningRule(const std::vector<EvaluationRecord>& history) {
  std::optional<double> best;  // lowest ok score so far
  int64_t pruned = 0;
  for (const EvaluationRecord& e : history) {
    const std::string where = fmt::format("evaluation {}", e.id);
    const double f = SyntheticObjective::Score(e.parameters);
    const int frames = e.parameters.at("tau") > kFailAboveTau ? 3 : 10;
    int first = -1;  // the pruning frame
    for (int k = 0; best && k < frames && first < 0; ++k) {
      if ((k + 1) * f > kFactor * *best) first = k;
    }
    if (first >= 0) {
      ++pruned;
      EXPECT_TRUE(e.pruned) << where;
      EXPECT_FALSE(e.ok) << where;
      EXPECT_EQ(e.pruned_recording, 0) << where;
      EXPECT_EQ(e.pruned_frame, first) << where;
      EXPECT_EQ(e.score, (first + 1) * f) << where << ": the score so far at the pruning frame";
      EXPECT_GT(e.score, kFactor * *best) << where;
      EXPECT_EQ(e.detail["frames_scored"], first + 1) << where;
      EXPECT_EQ(e.attempt, 1) << where;
      EXPECT_NE(e.reason.find(fmt::format("pruned at recording 0 frame {}", first)),
                std::string::npos)
          << where << ": " << e.reason;
    } else {
      EXPECT_FALSE(e.pruned) << where;
      EXPECT_EQ(e.ok, frames == 10) << where << ": as it finished";
      if (e.ok && best) {
        EXPECT_LE(e.score, kFactor * *best) << where;
      }
      if (!e.ok) {
        EXPECT_EQ(e.failure_frame, 3) << where;
      }
    }
    if (e.ok && (!best || e.score < *best)) best = e.score;
  }
  return pruned;
}

TEST(PruneBounds, AreTheFactorTimesTheLowestCompletedScoreOfTheLowerIds) {
  PruneBounds bounds(2.0);
  EXPECT_EQ(bounds.StartFor(0).stop_above, std::numeric_limits<double>::infinity())
      << "no bound while nothing is known";
  EXPECT_TRUE(bounds.StartFor(0).trace);
  bounds.AddCompleted(5, 10.0);
  bounds.AddCompleted(2, 30.0);
  bounds.AddCompleted(8, 4.0);
  bounds.AddCompleted(3, 20.0);
  EXPECT_EQ(bounds.StartFor(2).stop_above, std::numeric_limits<double>::infinity());
  EXPECT_EQ(bounds.StartFor(3).stop_above, 60.0);
  EXPECT_EQ(bounds.StartFor(4).stop_above, 40.0);
  EXPECT_EQ(bounds.StartFor(6).stop_above, 20.0);
  EXPECT_EQ(bounds.StartFor(9).stop_above, 8.0);
  bounds.AddCompleted(1, 3.0);  // lower than all of them: bounds every later id
  EXPECT_EQ(bounds.StartFor(2).stop_above, 6.0);
  EXPECT_EQ(bounds.StartFor(9).stop_above, 6.0);
  ObjectiveResult failed;  // status kFailed: teaches nothing
  failed.score = 0.5;
  bounds.AddFinished(0, failed);
  EXPECT_EQ(bounds.StartFor(1).stop_above, std::numeric_limits<double>::infinity());
}

TEST(PruneBounds, FindPrunePointNamesTheRecordingAndFrame) {
  ObjectiveResult r;
  r.recording_frames = {3, 4};
  r.trace = {1.0, 2.0, 3.0, 3.0, 5.0, 8.0};
  EXPECT_FALSE(FindPrunePoint(r, 8.0).has_value()) << "not above the bound";
  const std::optional<PrunePoint> at = FindPrunePoint(r, 3.0);
  ASSERT_TRUE(at.has_value());
  EXPECT_EQ(at->frames, 5);
  EXPECT_EQ(at->recording, 1);
  EXPECT_EQ(at->frame, 1);
  EXPECT_EQ(at->score, 5.0);
  EXPECT_EQ(FindPrunePoint(r, 0.5)->recording, 0);
  r.recording_frames = {2};
  EXPECT_THROW(FindPrunePoint(r, 3.0), std::logic_error) << "a trace longer than the recordings";
}

// Without the key the spec has no factor, its canonical form no key, and
// no worker is given a bound or asked for a trace.
TEST(RunnerPruning, OffWhenTheSpecLeavesItOut) {
  struct Spy final : Objective {
    struct Worker final : ObjectiveWorker {
      explicit Worker(const Spy& spy) : spy(spy) {}
      using ObjectiveWorker::Evaluate;
      ObjectiveResult Evaluate(const ParameterValues& values, const EarlyStop& stop) override {
        {
          std::lock_guard<std::mutex> lock(spy.mutex);
          const bool bounded = stop.stop_above < std::numeric_limits<double>::infinity();
          spy.early_stops += (stop.trace || bounded) ? 1 : 0;
        }
        return inner->Evaluate(values, stop);
      }
      const Spy& spy;
      std::unique_ptr<ObjectiveWorker> inner = SyntheticObjective().MakeWorker();
    };
    std::unique_ptr<ObjectiveWorker> MakeWorker() const override {
      return std::make_unique<Worker>(*this);
    }
    std::string Describe() const override { return "spy"; }
    mutable std::mutex mutex;
    mutable int early_stops = 0;
  } spy;
  const JobSpec spec = testing::SyntheticJobSpec("{name: random}", "budget: {evaluations: 40}");
  EXPECT_FALSE(spec.budget.prune_factor.has_value());
  EXPECT_FALSE(ToJson(spec)["budget"].contains("prune_factor"))
      << "a job stored before the key existed keeps its spec";
  const JobRun run = RunJobIn(spec, testing::ScratchDir("pruning_off") / "r.sqlite", spy, 2);
  ASSERT_EQ(run.history.size(), 40u);
  EXPECT_EQ(spy.early_stops, 0);
  for (const EvaluationRecord& e : run.history) EXPECT_FALSE(e.pruned) << "evaluation " << e.id;
  EXPECT_EQ(run.summary.pruned, 0);
  EXPECT_EQ(run.summary.BriefReport().find("pruned"), std::string::npos);

  const JobSpec on = PrunedSpec();
  EXPECT_EQ(ToJson(on)["budget"]["prune_factor"], kFactor);
  JobSpecParseOptions parse;
  parse.recordings = RecordingCheck::kNone;
  const JobSpec stored = ParseJobSpec(ToJson(on), "stored", fs::temp_directory_path(), parse);
  EXPECT_EQ(stored.budget.prune_factor, kFactor) << "the canonical form reads back";
}

// PrunedSpec run in `dir` on one thread, a candidate a batch: every bound
// a worker starts with is exact.
JobRun SerialReference(const fs::path& dir, const Objective& objective) {
  RunControl serial;
  serial.batch_size = 1;
  JobRun reference = RunJobIn(PrunedSpec(), dir / "reference.sqlite", objective, 1, serial);
  EXPECT_EQ(reference.summary.status, JobStatus::kFinished) << reference.summary.stop_reason;
  EXPECT_EQ(reference.history.size(), 80u);
  return reference;
}

TEST(RunnerPruning, FollowsTheRuleAndGivesTheSameHistoryAtAnyThreadCountAndBatchSize) {
  const SyntheticObjective objective({.fail_above_tau = kFailAboveTau});
  const fs::path dir = testing::ScratchDir("pruning_determinism");
  const JobRun reference = SerialReference(dir, objective);
  const int64_t pruned = ExpectThePruningRule(reference.history);
  EXPECT_GT(pruned, 10) << "the test needs pruned evaluations";
  EXPECT_EQ(reference.summary.pruned, pruned);
  int64_t failed = 0;
  for (const EvaluationRecord& e : reference.history) failed += !e.ok && !e.pruned;
  EXPECT_GT(failed, 0) << "the test needs failures that are not pruned";
  EXPECT_EQ(reference.summary.failed, failed) << "pruned ones are not failures";
  EXPECT_NE(reference.summary.BriefReport().find(fmt::format("{} pruned", pruned)),
            std::string::npos)
      << reference.summary.BriefReport();

  testing::ExpectSameRunAtThreadCountsAndBatchSizes(PrunedSpec(), objective, dir, reference);
}

// Runs every candidate of a batch to its end (the loosest bound a worker
// may be given) and hands them back last first, one at a time.
class LooseReversedEvaluator final : public BatchEvaluator {
 public:
  explicit LooseReversedEvaluator(const Objective& objective) : worker_(objective.MakeWorker()) {}
  int workers() const override { return 1; }
  std::string Describe() const override { return "loose bounds, last first"; }
  void Evaluate(std::span<const PendingCandidate> batch, int max_attempts, const PruneBounds* prune,
                const std::function<bool()>& /*should_stop*/,
                const std::function<void(std::vector<FinishedCandidate>&&)>& on_done,
                double /*tick_s*/) override {
    std::vector<FinishedCandidate> done;
    for (const PendingCandidate& c : batch) {
      const EarlyStop stop{.trace = prune != nullptr};
      done.push_back(EvaluateWithRetries(*worker_, c, stop, max_attempts, "loose"));
    }
    for (auto it = done.rbegin(); it != done.rend(); ++it) {
      std::vector<FinishedCandidate> one;
      one.push_back(std::move(*it));
      on_done(std::move(one));
    }
  }

 private:
  std::unique_ptr<ObjectiveWorker> worker_;
};

// The runner decides from the trace and the exact bound, not from where a
// worker stopped or in which order results came back: candidates simulated
// to their end, handed back last first, give the history of tight bounds.
TEST(RunnerPruning, TheHistoryDoesNotDependOnWhereWorkersStopped) {
  const JobSpec spec = PrunedSpec();
  const SyntheticObjective objective({.fail_above_tau = kFailAboveTau});
  const fs::path dir = testing::ScratchDir("pruning_loose");
  const JobRun reference = SerialReference(dir, objective);
  EXPECT_GT(ExpectThePruningRule(reference.history), 10);
  for (const int batch_size : {1, 5, 80}) {
    ResultStore store(dir / fmt::format("loose_b{}.sqlite", batch_size));
    const int64_t job = store.CreateJob(spec.name, ToJson(spec));
    LooseReversedEvaluator loose(objective);
    RunControl control;
    control.batch_size = batch_size;
    const RunSummary summary = RunCalibration(spec, store, job, loose, control);
    EXPECT_EQ(summary.status, JobStatus::kFinished);
    testing::ExpectSameHistory(reference.history, store.Evaluations(job),
                               fmt::format("loose bounds, batch {}", batch_size));
  }
}

TEST(RunnerPruning, StoppedAndResumedGivesTheUninterruptedHistory) {
  const JobSpec spec = PrunedSpec("checkpoint: {every_evaluations: 7, every_seconds: 0}");
  const SyntheticObjective objective({.fail_above_tau = kFailAboveTau});
  const fs::path dir = testing::ScratchDir("pruning_resume");
  const JobRun reference = RunJobIn(spec, dir / "reference.sqlite", objective, 2);
  ASSERT_EQ(reference.summary.status, JobStatus::kFinished);
  EXPECT_GT(ExpectThePruningRule(reference.history), 10);

  const fs::path db = dir / "resumed.sqlite";
  JobRun run;
  int invocations = 0;
  for (const int polls : {3, 7, 1, 12, 5, 30, 2, 1000000}) {
    run = RunJobIn(spec, db, objective, 1 + invocations % 3,
                   testing::StopAfterPolls(polls, 4 + invocations));
    ++invocations;
    if (run.summary.status == JobStatus::kFinished) break;
    EXPECT_EQ(run.summary.status, JobStatus::kStopped);
  }
  EXPECT_GT(invocations, 4);
  ASSERT_EQ(run.summary.status, JobStatus::kFinished);
  testing::ExpectSameHistory(reference.history, run.history, "stopped and resumed");
  EXPECT_EQ(run.summary.pruned, reference.summary.pruned) << "counted over the whole job";
  EXPECT_EQ(run.summary.failed, reference.summary.failed);
}

// The failure policy counts failures only: a job that aborts after 3
// failures runs past pruned evaluations to its 3rd failure, and the retry
// policy does not retry a pruned one.
TEST(RunnerPruning, APrunedEvaluationIsNotAFailure) {
  const SyntheticObjective objective({.fail_above_tau = kFailAboveTau});
  const fs::path dir = testing::ScratchDir("pruning_not_failed");
  const JobSpec abort = PrunedSpec("failure_policy: {mode: abort, abort_after: 3}", "abort");
  const JobRun run = RunJobIn(abort, dir / "abort.sqlite", objective, 2);
  EXPECT_EQ(run.summary.status, JobStatus::kAborted);
  ASSERT_FALSE(run.history.empty());
  int64_t failed = 0;
  int64_t pruned = 0;
  for (const EvaluationRecord& e : run.history) {
    failed += !e.ok && !e.pruned;
    pruned += e.pruned;
  }
  EXPECT_EQ(failed, 3);
  EXPECT_FALSE(run.history.back().ok || run.history.back().pruned)
      << "the history ends at the 3rd failure";
  EXPECT_GT(pruned, 0);
  EXPECT_GT(failed + pruned, 3) << "counted as failures, the pruned ones would have aborted it "
                                   "earlier";
  EXPECT_EQ(run.summary.failed, 3);

  const JobSpec retry = PrunedSpec("failure_policy: {mode: retry, max_retries: 2}", "retry");
  const JobRun retried = RunJobIn(retry, dir / "retry.sqlite", objective, 2);
  int64_t retried_pruned = 0;
  for (const EvaluationRecord& e : retried.history) {
    if (e.pruned) {
      ++retried_pruned;
      EXPECT_EQ(e.attempt, 1) << "evaluation " << e.id;
    } else if (!e.ok) {
      EXPECT_EQ(e.attempt, 3) << "evaluation " << e.id << ": a failure is retried";
    }
  }
  EXPECT_GT(retried_pruned, 0);
}

// The real objective: a worker given a bound stops after the first frame
// whose score so far exceeds it, having simulated fewer frames, and what it
// traced is the start of the trace of the whole run, bit for bit.
TEST(RecordingObjectivePruning, StopsAtTheBoundWithThePrefixOfTheWholeTrace) {
  const fs::path dir = testing::ScratchDir("pruning_recording");
  JobSpec spec = testing::SyntheticJobSpec(
      "{name: random}", "model: {substeps: 4, mesh: {edge_length_px: 40}}", "recording");
  spec.train = {fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre"};
  PreparationOptions preparation = spec.model.preparation;
  preparation.cache_dir = dir / "cache";
  const std::unique_ptr<Objective> objective = MakeRecordingObjective(spec, preparation);
  const std::unique_ptr<ObjectiveWorker> worker = objective->MakeWorker();
  const ParameterValues values = {{"k_D", 400.0}, {"k_d", 2.0}, {"k_A", 200.0},
                                  {"k_phi", 50.0}, {"mass", 0.2}, {"tau", 0.3}};
  const ObjectiveResult plain = worker->Evaluate(values);
  const ObjectiveResult whole = worker->Evaluate(values, {.trace = true});
  ASSERT_TRUE(whole.ok()) << whole.reason;
  EXPECT_TRUE(plain.trace.empty()) << "no trace unless asked";
  EXPECT_EQ(std::memcmp(&plain.score, &whole.score, sizeof(double)), 0)
      << "tracing changes nothing";
  ASSERT_EQ(whole.trace.size(), 330u);
  EXPECT_EQ(whole.recording_frames, std::vector<int>{330});
  EXPECT_EQ(std::memcmp(&whole.trace.back(), &whole.score, sizeof(double)), 0)
      << "the score so far after the last frame is the score";
  for (size_t k = 1; k < whole.trace.size(); ++k) ASSERT_GE(whole.trace[k], whole.trace[k - 1]);

  const double bound = whole.trace[100];
  const std::optional<PrunePoint> expected = FindPrunePoint(whole, bound);
  ASSERT_TRUE(expected.has_value());
  const ObjectiveResult stopped = worker->Evaluate(values, {.stop_above = bound, .trace = true});
  EXPECT_EQ(stopped.status, CandidateStatus::kPruned);
  EXPECT_EQ(stopped.iou.frames_scored, expected->frames) << "stopped right after the crossing";
  EXPECT_LT(stopped.iou.frames_scored, stopped.iou.frames_total) << "fewer frames simulated";
  EXPECT_EQ(stopped.iou.frames_total, 330);
  ASSERT_EQ(stopped.trace.size(), static_cast<size_t>(expected->frames));
  EXPECT_EQ(std::memcmp(stopped.trace.data(), whole.trace.data(),
                        stopped.trace.size() * sizeof(double)),
            0)
      << "the trace of a stopped run is the start of the whole one";
  EXPECT_EQ(stopped.score, stopped.trace.back());
  const ObjectiveResult again = worker->Evaluate(values, {.trace = true});
  EXPECT_EQ(again.trace, whole.trace) << "a worker that stopped early carries nothing over";

  // Over two recordings the second's frames add to the first's score.
  const auto& recording = static_cast<const RecordingObjective&>(*objective).recordings()[0];
  const RecordingObjective twice({recording, recording}, spec.model.simulation);
  const std::unique_ptr<ObjectiveWorker> twice_worker = twice.MakeWorker();
  const ObjectiveResult both = twice_worker->Evaluate(values, {.trace = true});
  ASSERT_EQ(both.trace.size(), 660u);
  EXPECT_EQ(std::memcmp(&both.trace[329], &whole.score, sizeof(double)), 0);
  EXPECT_EQ(std::memcmp(&both.trace.back(), &both.score, sizeof(double)), 0);
  const ObjectiveResult cut =
      twice_worker->Evaluate(values, {.stop_above = both.trace[400], .trace = true});
  const std::optional<PrunePoint> second = FindPrunePoint(both, both.trace[400]);
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->recording, 1);
  EXPECT_EQ(cut.status, CandidateStatus::kPruned);
  EXPECT_EQ(cut.iou.frames_scored, second->frames);
  EXPECT_EQ(cut.trace.size(), static_cast<size_t>(second->frames));
  EXPECT_EQ(std::memcmp(&cut.trace.back(), &both.trace[second->frames - 1], sizeof(double)), 0);
}

}  // namespace
}  // namespace calib
