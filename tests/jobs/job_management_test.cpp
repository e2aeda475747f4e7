// Managing jobs through RunJob with a cheap synthetic objective:
//  - a finished job resumed with a larger budget ends with the history of a
//    run with that budget from the start (random, cmaes, genetic), and the
//    optimisers that lay out their search for the budget refuse, naming it;
//  - a budget may not shrink on resume, nor the prune factor change;
//  - `fresh` deletes the job and starts over, refused while a live process
//    holds it;
//  - every run records the program version, host, process and time;
//  - a job in the store at the default place of earlier builds
//    (results/<name>.sqlite beside the spec) is found there.

#include "calib/jobs/job_commands.h"
#include "calib/jobs/job_report.h"
#include "jobs/job_test_support.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <optional>

namespace calib {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "text: " << (text) << "\nmissing: " << (part)

// A synthetic job with `budget` evaluations, its train recording the bundled
// centre push (read for its fingerprints only), its store `store`.
JobSpec ManagedSpec(const std::string& optimizer, int64_t budget, const fs::path& store) {
  JobSpec spec = testing::SyntheticJobSpec(
      optimizer, fmt::format("budget: {{evaluations: {}}}\ncheckpoint: {{every_evaluations: 8}}", budget),
      "managed");
  spec.train = {fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre"};
  spec.results.store = store;
  spec.results.out_dir = store.parent_path() / "out";
  spec.results.earlier_default_store.clear();
  return spec;
}

JobCommandOptions SyntheticOptions() {
  JobCommandOptions options = testing::SyntheticJobCommandOptions();
  options.batch_size = 5;  // batches that do not line up with the budgets
  return options;
}

std::vector<EvaluationRecord> History(const fs::path& store) {
  ResultStore s(store);
  return s.Evaluations(s.FindJob("managed")->id);
}

struct Extension {
  const char* label;
  const char* optimizer;
  int64_t small, large;
};

class BudgetExtension : public ::testing::TestWithParam<Extension> {};

TEST_P(BudgetExtension, AFinishedJobResumedWithALargerBudgetEndsWithTheLargerRunsHistory) {
  const Extension e = GetParam();
  const fs::path dir = testing::ScratchDir(std::string("extend_") + e.label);
  const JobCommandOptions options = SyntheticOptions();

  const JobCommandResult reference =
      RunJob(ManagedSpec(e.optimizer, e.large, dir / "reference.sqlite"), JobStart::kRun, options);
  ASSERT_EQ(reference.run.status, JobStatus::kFinished) << reference.run.stop_reason;

  const JobCommandResult small =
      RunJob(ManagedSpec(e.optimizer, e.small, dir / "extended.sqlite"), JobStart::kRun, options);
  ASSERT_EQ(small.run.status, JobStatus::kFinished) << small.run.stop_reason;
  ASSERT_LT(small.run.evaluations, reference.run.evaluations);

  const JobCommandResult extended = RunJob(
      ManagedSpec(e.optimizer, e.large, dir / "extended.sqlite"), JobStart::kResume, options);
  EXPECT_EQ(extended.run.status, JobStatus::kFinished) << extended.run.stop_reason;
  EXPECT_EQ(extended.run.evaluated_now, reference.run.evaluations - small.run.evaluations);
  testing::ExpectSameHistory(History(dir / "reference.sqlite"), History(dir / "extended.sqlite"),
                             std::string(e.optimizer) + " extended");
  ResultStore store(dir / "extended.sqlite");
  EXPECT_EQ(store.FindJob("managed")->spec["budget"]["evaluations"], e.large)
      << "the store keeps the extended spec";
}

// Budgets that are not whole batches (5) nor whole generations (4, 6).
INSTANTIATE_TEST_SUITE_P(
    Optimisers, BudgetExtension,
    ::testing::Values(
        Extension{"random", "{name: random}", 23, 51},
        Extension{"cmaes", "{name: cmaes, settings: {population: 4}}", 30, 61},
        Extension{"genetic", "{name: genetic, settings: {population: 6, generations: 20}}", 27, 70}),
    [](const ::testing::TestParamInfo<Extension>& info) { return std::string(info.param.label); });

TEST(JobManagement, OptimisersThatLayOutTheirSearchForTheBudgetRefuseALargerOne) {
  const fs::path dir = testing::ScratchDir("extend_refused");
  for (const char* optimizer : {"{name: grid}", "{name: annealing}"}) {
    const fs::path store = dir / (std::string(optimizer + 7, 4) + ".sqlite");
    ASSERT_EQ(RunJob(ManagedSpec(optimizer, 16, store), JobStart::kRun, SyntheticOptions()).run.status,
              JobStatus::kFinished);
    try {
      RunJob(ManagedSpec(optimizer, 32, store), JobStart::kResume, SyntheticOptions());
      ADD_FAILURE() << optimizer << ": a larger budget was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_CONTAINS(e.what(), "budget.evaluations = 32 (was 16)");
      EXPECT_CONTAINS(e.what(), "calib run --fresh --budget 32");
    }
    EXPECT_EQ(History(store).size(), 16u) << optimizer << ": nothing of the job changed";
  }
}

TEST(JobManagement, ABudgetCannotShrinkOnResume) {
  const fs::path dir = testing::ScratchDir("shrink_refused");
  const JobSpec spec = ManagedSpec("{name: random}", 20, dir / "r.sqlite");
  JobCommandOptions options = SyntheticOptions();
  options.wall_time_s = 1e-9;  // stops after its first batch
  ASSERT_EQ(RunJob(spec, JobStart::kRun, options).run.status, JobStatus::kStopped);
  try {
    RunJob(ManagedSpec("{name: random}", 10, dir / "r.sqlite"), JobStart::kResume, SyntheticOptions());
    ADD_FAILURE() << "a smaller budget was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "/budget/evaluations");
  }
}

// Pruning decides the history: its factor may not change, appear or go on
// resume; the same factor resumes.
TEST(JobManagement, ThePruneFactorCannotChangeOnResume) {
  const fs::path dir = testing::ScratchDir("prune_factor_refused");
  JobSpec spec = ManagedSpec("{name: random}", 20, dir / "r.sqlite");
  spec.budget.prune_factor = 2.0;
  JobCommandOptions first_batch = SyntheticOptions();
  first_batch.wall_time_s = 1e-9;
  ASSERT_EQ(RunJob(spec, JobStart::kRun, first_batch).run.status, JobStatus::kStopped);
  for (const std::optional<double> factor : {std::optional<double>(3.0), std::optional<double>()}) {
    JobSpec changed = spec;
    changed.budget.prune_factor = factor;
    try {
      RunJob(changed, JobStart::kResume, SyntheticOptions());
      ADD_FAILURE() << "prune factor " << factor.value_or(0.0) << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_CONTAINS(e.what(), "/budget/prune_factor");
    }
  }
  EXPECT_EQ(RunJob(spec, JobStart::kResume, SyntheticOptions()).run.status, JobStatus::kFinished);
}

TEST(JobManagement, FreshStartsOverAndRecordsEveryRun) {
  const fs::path dir = testing::ScratchDir("fresh");
  const JobSpec spec = ManagedSpec("{name: random}", 12, dir / "r.sqlite");
  JobCommandOptions options = SyntheticOptions();
  options.program_version = "calib 9.9.9";
  options.command = "run";
  const double before = std::chrono::duration<double>(
                            std::chrono::system_clock::now().time_since_epoch())
                            .count();
  ASSERT_EQ(RunJob(spec, JobStart::kRun, options).run.status, JobStatus::kFinished);
  const std::vector<EvaluationRecord> first = History(dir / "r.sqlite");

  try {
    RunJob(spec, JobStart::kRun, options);
    ADD_FAILURE() << "a second run was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "calib run --fresh");
  }
  {
    ResultStore store(dir / "r.sqlite");
    const int64_t job = store.FindJob("managed")->id;
    const std::vector<JobRunRecord> runs = store.JobRuns(job);
    ASSERT_EQ(runs.size(), 1u) << "the refused run is not recorded";
    EXPECT_EQ(runs[0].program_version, "calib 9.9.9");
    EXPECT_EQ(runs[0].command, "run");
    EXPECT_EQ(runs[0].host, ThisHostName());
    EXPECT_EQ(runs[0].pid, ::getpid());
    EXPECT_GE(runs[0].started_unix_s, before - 1.0);
    EXPECT_CONTAINS(JobResultsText(store, job), "by calib 9.9.9 on host " + ThisHostName());
    // A live process (another one) holds the job: fresh is refused too.
    JobLock other;
    other.pid = 1;  // init: alive, and not this process
    other.host = ThisHostName();
    other.token = "other";
    store.AcquireJobLock(job, other, [](const JobLock&, double) { return false; });
  }
  options.fresh = true;
  options.command = "run --fresh";
  EXPECT_THROW(RunJob(spec, JobStart::kRun, options), JobLockedError);
  EXPECT_EQ(History(dir / "r.sqlite").size(), first.size()) << "nothing deleted while held";
  {
    ResultStore store(dir / "r.sqlite");
    store.ReleaseJobLock(store.FindJob("managed")->id, "other");
  }
  const JobCommandResult again = RunJob(spec, JobStart::kRun, options);
  EXPECT_EQ(again.run.evaluated_now, 12) << "started over, nothing reused";
  testing::ExpectSameHistory(first, History(dir / "r.sqlite"), "fresh run");
  ResultStore store(dir / "r.sqlite");
  const std::vector<JobRunRecord> runs = store.JobRuns(store.FindJob("managed")->id);
  ASSERT_EQ(runs.size(), 1u) << "the old job's runs went with it";
  EXPECT_EQ(runs[0].command, "run --fresh");
}

TEST(JobManagement, AJobStoredAtTheEarlierDefaultPlaceIsFoundThere) {
  const fs::path dir = testing::ScratchDir("earlier_default");
  JobSpec spec = ManagedSpec("{name: random}", 8, dir / "out" / "jobs" / "managed.sqlite");
  spec.results.earlier_default_store = dir / "results" / "managed.sqlite";
  EXPECT_EQ(ResolveStorePath(spec, std::nullopt), spec.results.store) << "no store anywhere yet";
  fs::create_directories(dir / "results");
  JobCommandOptions options = SyntheticOptions();
  options.store = spec.results.earlier_default_store;
  ASSERT_EQ(RunJob(spec, JobStart::kRun, options).run.status, JobStatus::kFinished);
  EXPECT_EQ(ResolveStorePath(spec, std::nullopt), spec.results.earlier_default_store);
  EXPECT_EQ(ResolveStorePath(spec, dir / "x.sqlite"), dir / "x.sqlite") << "--store decides";
  const JobCommandResult resumed = RunJob(spec, JobStart::kResume, SyntheticOptions());
  EXPECT_EQ(resumed.store, spec.results.earlier_default_store);
  EXPECT_FALSE(fs::exists(spec.results.store)) << "no second store made";
}

}  // namespace
}  // namespace calib
