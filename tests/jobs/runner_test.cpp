// The runner: the same job and seed give bit-identical histories and best
// parameters whatever the thread count and batch size; the failure policy
// (penalty, retry, abort after N) with every failure stored with its
// reason; stopping and resuming (also from a corrupted checkpoint) gives
// the history of an uninterrupted run; progress as a bar or as log lines.

#include "calib/jobs/runner.h"

#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/job_commands.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/progress.h"
#include "calib/results/store.h"
#include "jobs/job_test_support.h"
#include "support/csv_support.h"
#include "support/process_support.h"
#include "support/sqlite_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace calib {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "text: " << (text) << "\nmissing: " << (part)

int64_t JobId(const fs::path& db, const std::string& name) {
  return ResultStore(db).FindJob(name).value().id;
}

using testing::ExpectSameBest;
using testing::JobRun;
using testing::RunJobIn;
using testing::StopAfterPolls;

struct OptimizerCase {
  std::string label;
  std::string optimizer;  // YAML
};

void PrintTo(const OptimizerCase& c, std::ostream* out) { *out << c.label; }

class RunnerDeterminism : public ::testing::TestWithParam<OptimizerCase> {};

TEST_P(RunnerDeterminism, SameHistoryAndBestAtAnyThreadCountAndBatchSize) {
  const JobSpec spec = testing::SyntheticJobSpec(GetParam().optimizer, "budget: {evaluations: 72}");
  const testing::SyntheticObjective objective({.fail_above_tau = 0.45});
  const fs::path dir = testing::ScratchDir("runner_determinism");
  RunControl serial;
  serial.batch_size = 1;
  const JobRun reference = RunJobIn(spec, dir / "reference.sqlite", objective, 1, serial);
  EXPECT_EQ(reference.summary.status, JobStatus::kFinished) << reference.summary.stop_reason;
  EXPECT_GT(reference.history.size(), 20u);
  EXPECT_LE(reference.history.size(), 72u) << "the budget caps the evaluations";
  ASSERT_TRUE(reference.best.has_value());

  testing::ExpectSameRunAtThreadCountsAndBatchSizes(spec, objective, dir, reference);
}

INSTANTIATE_TEST_SUITE_P(
    Optimizers, RunnerDeterminism,
    ::testing::Values(
        OptimizerCase{"cmaes", "{name: cmaes, settings: {population: 8, initial_sigma: 0.3}}"},
        OptimizerCase{"genetic", "{name: genetic, settings: {population: 12, generations: 8}}"},
        OptimizerCase{"annealing", "{name: annealing, settings: {batch_size: 4, warmup: 8}}"},
        OptimizerCase{"random", "{name: random}"},
        OptimizerCase{"grid", "{name: grid, settings: {resolution: 3}}"},
        OptimizerCase{"nlopt_bobyqa", "{name: 'nlopt:BOBYQA'}"},
        OptimizerCase{"nlopt_crs2", "{name: 'nlopt:CRS2_LM'}"}),
    [](const auto& info) { return info.param.label; });

// The real objective: simulating and scoring the bundled centre-push
// recording (coarse mesh, few substeps, to be quick).
// 0 means all cores; a count far past the cores is refused by name before
// any work (it would exhaust memory or the OpenMP runtime mid-job).
TEST(RunnerThreads, ZeroIsAllCoresAndTooManyIsNamed) {
  const int cores = ResolveThreadCount(0);
  EXPECT_GE(cores, 1);
  EXPECT_EQ(ResolveThreadCount(1), 1);
  EXPECT_EQ(ResolveThreadCount(kMaxThreadsPerCore * cores), kMaxThreadsPerCore * cores);
  for (const int bad : {-1, kMaxThreadsPerCore * cores + 1, 100000}) {
    try {
      ResolveThreadCount(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(fmt::format("threads = {}:", bad)), std::string::npos)
          << e.what();
    }
  }
}

TEST(RunnerDeterminismOnARecording, SameHistoryAtOneTwoAndFourThreads) {
  const fs::path dir = testing::ScratchDir("runner_recording");
  JobSpec spec = testing::SyntheticJobSpec(
      "{name: cmaes, settings: {population: 6}}",
      "budget: {evaluations: 18}\nmodel: {substeps: 4, mesh: {edge_length_px: 40}}", "recording");
  spec.train = {fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre"};
  PreparationOptions preparation = spec.model.preparation;
  preparation.cache_dir = dir / "cache";
  const std::unique_ptr<Objective> objective = MakeRecordingObjective(spec, preparation);
  EXPECT_CONTAINS(objective->Describe(), "1 training recording, 330 frames");
  RunControl serial;
  serial.batch_size = 1;
  const JobRun reference = RunJobIn(spec, dir / "t1.sqlite", *objective, 1, serial);
  ASSERT_EQ(reference.history.size(), 18u);
  ASSERT_TRUE(reference.best.has_value());
  EXPECT_GT(reference.best->mean_iou, 0.5);
  EXPECT_EQ(reference.best->detail["frames_total"], 330);
  for (const int threads : {2, 4}) {
    RunControl control;
    control.batch_size = 4;
    const std::string what = fmt::format("{} threads on push_centre", threads);
    const JobRun run =
        RunJobIn(spec, dir / fmt::format("t{}.sqlite", threads), *objective, threads, control);
    testing::ExpectSameHistory(reference.history, run.history, what);
    ExpectSameBest(reference, run, what);
  }
}

// A job whose spec adds effects calibrates that model: the objective
// simulates the effects, so their parameters change the score.
TEST(RunnerObjective, SimulatesTheEffectsTheSpecAdds) {
  const fs::path dir = testing::ScratchDir("runner_effects");
  JobSpec spec = testing::SyntheticJobSpec(
      "{name: random}", "model: {substeps: 4, mesh: {edge_length_px: 40}}", "recording");
  spec.train = {fs::path(CALIB_SOURCE_DIR) / "examples" / "push_viscoelastic"};
  spec.model.effects = {"viscoelastic"};
  PreparationOptions preparation = spec.model.preparation;
  preparation.cache_dir = dir / "cache";
  const std::unique_ptr<Objective> objective = MakeRecordingObjective(spec, preparation);
  EXPECT_CONTAINS(objective->Describe(), "model base+viscoelastic");
  const std::unique_ptr<ObjectiveWorker> worker = objective->MakeWorker();
  ParameterValues values = {{"k_D", 400.0}, {"k_d", 2.0},         {"k_A", 200.0},
                            {"k_phi", 50.0}, {"mass", 0.2},        {"tau", 0.3},
                            {"visco_share", 0.0}, {"visco_time_s", 1.0}};
  const ObjectiveResult elastic = worker->Evaluate(values);
  values["visco_share"] = 0.8;
  const ObjectiveResult relaxing = worker->Evaluate(values);
  ASSERT_TRUE(elastic.ok()) << elastic.reason;
  ASSERT_TRUE(relaxing.ok()) << relaxing.reason;
  EXPECT_NE(elastic.score, relaxing.score) << "visco_share must act on the simulation";
  // A candidate without the effect's parameters is refused, naming one.
  values.erase("visco_time_s");
  try {
    worker->Evaluate(values);
    ADD_FAILURE() << "a candidate without visco_time_s was evaluated";
  } catch (const std::exception& e) {
    EXPECT_CONTAINS(std::string(e.what()), "visco_time_s");
  }
}

TEST(RunnerFailurePolicy, PenaltyStoresEveryFailureWithItsReason) {
  const JobSpec spec = testing::SyntheticJobSpec(
      "{name: random}", "failure_policy: {mode: penalty, penalty_score: 1.0e7}");
  const testing::SyntheticObjective objective({.fail_above_tau = 0.3});
  const JobRun run = RunJobIn(spec, testing::ScratchDir("runner_penalty") / "r.sqlite", objective, 2);
  EXPECT_EQ(run.summary.status, JobStatus::kFinished);
  ASSERT_EQ(run.history.size(), 96u);
  int64_t failed = 0;
  for (const EvaluationRecord& e : run.history) {
    const bool should_fail = e.parameters.at("tau") > 0.3;
    EXPECT_EQ(e.ok, !should_fail) << "evaluation " << e.id;
    if (!e.ok) {
      ++failed;
      EXPECT_CONTAINS(e.reason, "frame 3: tau = ");
      EXPECT_CONTAINS(e.reason, "blew up");
      EXPECT_EQ(e.failure_frame, 3);
      EXPECT_TRUE(std::isnan(e.score)) << "a failed evaluation has no score";
      EXPECT_EQ(e.detail["partial_score"].get<double>(),
                3.0 * testing::SyntheticObjective::Score(e.parameters));
      EXPECT_EQ(e.attempt, 1);
    } else {
      EXPECT_TRUE(e.reason.empty());
      EXPECT_EQ(e.score, 10.0 * testing::SyntheticObjective::Score(e.parameters));
    }
  }
  EXPECT_GT(failed, 10);
  EXPECT_EQ(run.summary.failed, failed);
  ASSERT_TRUE(run.best.has_value());
  EXPECT_TRUE(run.best->ok) << "a failure is never best, whatever its penalty";
}

TEST(RunnerFailurePolicy, AFailedCandidatesIouNeverRanksAboveAnOkOne) {
  // The synthetic failures score their first 3 frames of 10 well: an IoU
  // averaged over those frames would rank them first.
  const JobSpec spec = testing::SyntheticJobSpec("{name: random}", "budget: {evaluations: 40}");
  const testing::SyntheticObjective objective({.fail_above_tau = 0.3});
  const fs::path db = testing::ScratchDir("runner_failed_iou") / "r.sqlite";
  const JobRun run = RunJobIn(spec, db, objective, 2);
  int64_t failed = 0;
  for (const EvaluationRecord& e : run.history) {
    if (e.ok) {
      EXPECT_FALSE(std::isnan(e.mean_iou)) << "evaluation " << e.id;
      continue;
    }
    ++failed;
    EXPECT_TRUE(std::isnan(e.mean_iou)) << "evaluation " << e.id << ": " << e.mean_iou;
    EXPECT_TRUE(std::isnan(e.iou_min) && std::isnan(e.iou_max)) << "evaluation " << e.id;
    EXPECT_GT(e.detail["partial_mean_iou"].get<double>(), 0.0) << "the partial figure is kept";
  }
  ASSERT_GT(failed, 0);
  // Sorted by IoU, best first, in a spreadsheet or SQL: a failed one has
  // none (an empty CSV field, NULL), so it never comes first.
  ResultStore store(db);
  store.ExportCsv(store.FindJob(spec.name)->id, db.parent_path() / "e.csv");
  const testing::CsvRows rows = testing::ParseCsvFile(db.parent_path() / "e.csv");
  for (size_t i = 1; i < rows.size(); ++i) {
    if (rows[i][1] == "failed") {
      EXPECT_EQ(rows[i][3], "") << "row " << i;
    }
  }
}

TEST(RunnerFailurePolicy, RetryEvaluatesAgainAndRecordsTheAttempts) {
  const JobSpec spec = testing::SyntheticJobSpec(
      "{name: cmaes, settings: {population: 6}}",
      "budget: {evaluations: 30}\nfailure_policy: {mode: retry, max_retries: 2}");
  const testing::SyntheticObjective flaky({.flaky = true});
  const fs::path dir = testing::ScratchDir("runner_retry");
  const JobRun run = RunJobIn(spec, dir / "flaky.sqlite", flaky, 2);
  EXPECT_EQ(run.summary.status, JobStatus::kFinished);
  ASSERT_EQ(run.history.size(), 30u);
  for (const EvaluationRecord& e : run.history) {
    EXPECT_TRUE(e.ok) << "evaluation " << e.id << ": " << e.reason;
    EXPECT_EQ(e.attempt, 2) << "the first attempt failed, the retry succeeded";
  }
  // The retried history is the history of an objective that never failed.
  const testing::SyntheticObjective steady;
  JobRun clean = RunJobIn(spec, dir / "steady.sqlite", steady, 1);
  for (EvaluationRecord& e : clean.history) e.attempt = 2;
  testing::ExpectSameHistory(clean.history, run.history, "retried vs never failed");

  // Without retries the same transient failure is recorded with its reason.
  const JobSpec no_retry = testing::SyntheticJobSpec(
      "{name: cmaes, settings: {population: 6}}",
      "budget: {evaluations: 12}\nfailure_policy: {mode: penalty}", "no_retry");
  const JobRun failing = RunJobIn(no_retry, dir / "no_retry.sqlite", flaky, 2);
  ASSERT_EQ(failing.history.size(), 12u);
  for (const EvaluationRecord& e : failing.history) {
    EXPECT_FALSE(e.ok);
    EXPECT_EQ(e.reason, "exception: transient: connection to the recording store lost");
  }
  EXPECT_FALSE(failing.best.has_value());
  EXPECT_CONTAINS(failing.summary.BriefReport(), "best: none");
}

TEST(RunnerFailurePolicy, AbortAfterNCutsTheHistoryAtTheNthFailure) {
  const JobSpec spec = testing::SyntheticJobSpec(
      "{name: random}", "failure_policy: {mode: abort, abort_after: 5}");
  const testing::SyntheticObjective objective({.fail_above_tau = 0.35});
  const fs::path dir = testing::ScratchDir("runner_abort");
  RunControl serial;
  serial.batch_size = 1;
  const JobRun reference = RunJobIn(spec, dir / "serial.sqlite", objective, 1, serial);
  EXPECT_EQ(reference.summary.status, JobStatus::kAborted);
  EXPECT_EQ(reference.info.status, JobStatus::kAborted);
  EXPECT_CONTAINS(reference.info.stop_reason, "5 failed evaluations (failure policy: abort after 5)");
  ASSERT_FALSE(reference.history.empty());
  EXPECT_LT(reference.history.size(), 96u);
  EXPECT_FALSE(reference.history.back().ok) << "the history ends at the 5th failure";
  int64_t failed = 0;
  for (const auto& e : reference.history) failed += e.ok ? 0 : 1;
  EXPECT_EQ(failed, 5);

  for (const int threads : {2, 4}) {
    RunControl control;
    control.batch_size = 16;
    const std::string what = fmt::format("{} threads, batch 16", threads);
    const JobRun run = RunJobIn(spec, dir / fmt::format("t{}.sqlite", threads), objective, threads,
                                control);
    EXPECT_EQ(run.summary.status, JobStatus::kAborted) << what;
    testing::ExpectSameHistory(reference.history, run.history, what);
  }

  // Resuming an aborted job changes nothing.
  const JobRun again = RunJobIn(spec, dir / "serial.sqlite", objective, 2);
  EXPECT_EQ(again.summary.status, JobStatus::kAborted);
  EXPECT_EQ(again.summary.evaluated_now, 0);
  testing::ExpectSameHistory(reference.history, again.history, "resumed after the abort");
}

TEST(RunnerResume, StoppedAndResumedManyTimesGivesTheUninterruptedHistory) {
  const JobSpec spec = testing::SyntheticJobSpec(
      "{name: cmaes, settings: {population: 8}}",
      "checkpoint: {every_evaluations: 10, every_seconds: 0}");
  const testing::SyntheticObjective objective({.fail_above_tau = 0.45});
  const fs::path dir = testing::ScratchDir("runner_resume");
  const JobRun reference = RunJobIn(spec, dir / "reference.sqlite", objective, 2);
  ASSERT_EQ(reference.summary.status, JobStatus::kFinished);

  const fs::path db = dir / "resumed.sqlite";
  JobRun run;
  int invocations = 0;
  for (const int polls : {3, 7, 1, 12, 5, 30, 2, 1000000}) {
    run = RunJobIn(spec, db, objective, 1 + invocations % 3, StopAfterPolls(polls, 5 + invocations));
    ++invocations;
    if (run.summary.status == JobStatus::kFinished) break;
    EXPECT_EQ(run.summary.status, JobStatus::kStopped);
    EXPECT_EQ(run.summary.stop_reason, "interrupted");
    EXPECT_EQ(run.info.status, JobStatus::kStopped);
  }
  EXPECT_GT(invocations, 4);
  ASSERT_EQ(run.summary.status, JobStatus::kFinished);
  testing::ExpectSameHistory(reference.history, run.history, "stopped and resumed");
  ExpectSameBest(reference, run, "stopped and resumed");
  EXPECT_EQ(run.summary.evaluations, static_cast<int64_t>(reference.history.size()));
}

TEST(RunnerResume, WallTimeStopsResumably) {
  const JobSpec spec = testing::SyntheticJobSpec(
      "{name: random}", "budget: {evaluations: 40, wall_time_s: 0.05}\n"
                        "checkpoint: {every_evaluations: 4, every_seconds: 0}");
  const testing::SyntheticObjective slow({.sleep_s = 0.01});
  const fs::path db = testing::ScratchDir("runner_wall_time") / "r.sqlite";
  RunControl control;
  control.batch_size = 4;
  control.wall_time_s = spec.budget.wall_time_s;
  const JobRun first = RunJobIn(spec, db, slow, 2, control);
  EXPECT_EQ(first.summary.status, JobStatus::kStopped);
  EXPECT_CONTAINS(first.summary.stop_reason, "wall time of 0.05 s used");
  EXPECT_LT(first.history.size(), 40u);
  const JobRun rest = RunJobIn(spec, db, slow, 2);  // no wall time this time
  EXPECT_EQ(rest.summary.status, JobStatus::kFinished);
  EXPECT_EQ(rest.history.size(), 40u);
  EXPECT_EQ(rest.summary.resumed_from_checkpoint.has_value(), first.summary.checkpoints_written > 0);
}

TEST(RunnerResume, CorruptedCheckpointFallsBackToTheLastGoodOneLosingNothing) {
  const JobSpec spec = testing::SyntheticJobSpec(
      "{name: genetic, settings: {population: 10, generations: 9}}",
      "checkpoint: {every_evaluations: 9, every_seconds: 0}");
  const testing::SyntheticObjective objective;
  const fs::path dir = testing::ScratchDir("runner_corrupt");
  const JobRun reference = RunJobIn(spec, dir / "reference.sqlite", objective, 2);

  // Stop after the 4th checkpoint.
  const fs::path db = dir / "r.sqlite";
  struct CountCheckpoints : RunObserver {
    int64_t checkpoints = 0;
    void OnCheckpoint(const RunProgress&, int64_t) override { ++checkpoints; }
  } counter;
  RunControl control;
  control.batch_size = 9;
  control.interrupted = [&counter] { return counter.checkpoints >= 4; };
  const JobRun stopped = RunJobIn(spec, db, objective, 2, control, &counter);
  ASSERT_EQ(stopped.summary.status, JobStatus::kStopped);
  const int64_t recorded = static_cast<int64_t>(stopped.history.size());
  ASSERT_GE(stopped.summary.checkpoints_written, 4);
  const int64_t newest = stopped.summary.checkpoints_written;  // sequences 1, 2, ...

  // Truncate the newest checkpoint's state and flip a byte of the one before.
  testing::RawSql(db, fmt::format("UPDATE checkpoints SET state_json = substr(state_json, 1, 40) "
                                   "WHERE sequence = {}",
                                   newest));
  testing::RawSql(db, fmt::format("UPDATE checkpoints SET state_json = CAST(replace(CAST("
                                   "state_json AS TEXT), '\"told\":', '\"tolD\":') AS BLOB) "
                                   "WHERE sequence = {}",
                                   newest - 1));
  int64_t good_told = 0;
  {
    const LatestCheckpointResult latest =
        ResultStore(db).LatestCheckpoint(JobId(db, spec.name));
    ASSERT_TRUE(latest.checkpoint.has_value());
    good_told = latest.checkpoint->evaluations_done;
  }
  const JobRun resumed = RunJobIn(spec, db, objective, 1);
  ASSERT_EQ(resumed.summary.status, JobStatus::kFinished) << resumed.summary.stop_reason;
  ASSERT_EQ(resumed.summary.warnings.size(), 2u);
  EXPECT_CONTAINS(resumed.summary.warnings[0], db.string());
  EXPECT_CONTAINS(resumed.summary.warnings[0], fmt::format("checkpoint {} is corrupted", newest));
  EXPECT_CONTAINS(resumed.summary.warnings[1], fmt::format("checkpoint {} is corrupted", newest - 1));
  ASSERT_TRUE(resumed.summary.resumed_from_checkpoint.has_value());
  EXPECT_EQ(*resumed.summary.resumed_from_checkpoint, newest - 2);
  EXPECT_GT(recorded, good_told);
  EXPECT_EQ(resumed.summary.reused, recorded - good_told)
      << "what was recorded after the good checkpoint is reused, not lost or repeated";
  testing::ExpectSameHistory(reference.history, resumed.history, "resumed past corrupted checkpoints");
  ExpectSameBest(reference, resumed, "resumed past corrupted checkpoints");
}

TEST(RunnerResume, ACheckpointOfAnotherSeedIsRefusedNamingIt) {
  const JobSpec spec = testing::SyntheticJobSpec("{name: random}",
                                                 "checkpoint: {every_evaluations: 8, every_seconds: 0}");
  const testing::SyntheticObjective objective;
  const fs::path db = testing::ScratchDir("runner_other_seed") / "r.sqlite";
  RunJobIn(spec, db, objective, 1, StopAfterPolls(20, 8));
  JobSpec other = spec;
  other.seed = 8;
  try {
    RunJobIn(other, db, objective, 1);
    FAIL() << "a checkpoint of seed 7 was used for seed 8";
  } catch (const std::runtime_error& e) {
    EXPECT_CONTAINS(e.what(), db.string());
    EXPECT_CONTAINS(e.what(), "does not fit the job spec: it was taken with seed 7, the spec says 8");
  }
}

// ------------------------------------------------------------- progress

TEST(Progress, BarShowsDoneBudgetRateBestAndEta) {
  RunProgress p;
  p.evaluations = 120;
  p.budget = 300;
  p.failed = 2;
  p.best_score = 81234;
  p.best_id = 87;
  const std::string bar = FormatProgressBar(p, 3.4, 100);
  EXPECT_CONTAINS(bar, "[");
  EXPECT_CONTAINS(bar, "120/300");
  EXPECT_CONTAINS(bar, "3.40 eval/s");
  EXPECT_CONTAINS(bar, "best 81234 (#87)");
  EXPECT_CONTAINS(bar, "failed 2");
  EXPECT_CONTAINS(bar, "ETA 53 s");
  EXPECT_LT(bar.size(), 100u);
  EXPECT_EQ(bar.find('\n'), std::string::npos);
  const std::string line = FormatProgressLine(p, 3.4);
  EXPECT_CONTAINS(line, "120/300 evaluations (40.0 %), 3.40 eval/s, best 81234 (#87), 2 failed");
  EXPECT_CONTAINS(line, "ETA 53 s");
  EXPECT_EQ(FormatDuration(725), "12 min 5 s");
  EXPECT_EQ(FormatDuration(7380), "2 h 3 min");
  EXPECT_EQ(FormatDuration(-1), "-");
}

// spdlog's output captured for the test's lifetime.
class CapturedLog {
 public:
  CapturedLog() : sink_(std::make_shared<spdlog::sinks::ostream_sink_mt>(text_)) {
    spdlog::default_logger()->sinks().push_back(sink_);
  }
  ~CapturedLog() {
    auto& sinks = spdlog::default_logger()->sinks();
    sinks.erase(std::find(sinks.begin(), sinks.end(), sink_));
  }
  std::string text() const { return text_.str(); }

 private:
  std::ostringstream text_;
  std::shared_ptr<spdlog::sinks::ostream_sink_mt> sink_;
};

TEST(Progress, NotATerminalGivesPlainLogLines) {
  const fs::path dir = testing::ScratchDir("progress_log");
  std::FILE* file = std::fopen((dir / "stream.txt").c_str(), "w+");
  ASSERT_NE(file, nullptr);
  {
    ProgressDisplay display(ProgressMode::kAuto, 0.0, file);
    EXPECT_EQ(display.mode(), ProgressMode::kLog) << "a file is not a terminal";
    CapturedLog log;
    const JobSpec spec = testing::SyntheticJobSpec("{name: random}", "budget: {evaluations: 24}");
    RunControl control;
    control.batch_size = 6;
    RunJobIn(spec, dir / "r.sqlite", testing::SyntheticObjective(), 2, control, &display);
    const std::string text = log.text();
    EXPECT_CONTAINS(text, "job synthetic (random), 24 evaluations budget, 2 OpenMP threads");
    EXPECT_CONTAINS(text, "24/24 evaluations (100.0 %)");
    int lines = 0;
    for (size_t at = text.find("evaluations ("); at != std::string::npos;
         at = text.find("evaluations (", at + 1)) {
      ++lines;
    }
    EXPECT_GE(lines, 4) << "one line per batch at least (log interval 0): " << text;
    EXPECT_EQ(text.find('\r'), std::string::npos) << "no bar redraws in a log";
    EXPECT_EQ(text.find('\033'), std::string::npos) << "no escape codes in a log";
  }
  std::fclose(file);
  EXPECT_EQ(testing::ReadText(dir / "stream.txt"), "") << "log mode leaves the bar's stream alone";
}

TEST(Progress, BarIsRedrawnInPlaceAndEndsWithANewline) {
  const fs::path dir = testing::ScratchDir("progress_bar");
  std::FILE* file = std::fopen((dir / "stream.txt").c_str(), "w+");
  ASSERT_NE(file, nullptr);
  {
    ProgressDisplay display(ProgressMode::kBar, 10.0, file);
    const JobSpec spec = testing::SyntheticJobSpec("{name: random}", "budget: {evaluations: 16}");
    RunJobIn(spec, dir / "r.sqlite", testing::SyntheticObjective(), 2, {}, &display);
  }
  std::fclose(file);
  const std::string text = testing::ReadText(dir / "stream.txt");
  EXPECT_EQ(text.rfind("\r\033[K[", 0), 0u) << text;
  EXPECT_CONTAINS(text, "16/16");
  EXPECT_CONTAINS(text, "eval/s");
  EXPECT_CONTAINS(text, "best ");
  EXPECT_CONTAINS(text, "ETA 0 s");
  ASSERT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n');
}

}  // namespace
}  // namespace calib
