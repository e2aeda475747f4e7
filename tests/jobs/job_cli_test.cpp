// The job commands end to end, through the calib executable, on a small
// job calibrating the bundled centre-push recording (a coarse mesh and few
// substeps, so that an evaluation is cheap):
//  - `calib run` killed with SIGKILL at random moments, several times, and
//    resumed each time, ends with the history of an uninterrupted run;
//  - `mpirun -np 3 calib run` gives the history of threads, and so does
//    `mpirun -np 3 calib compare-optimizers` for each run;
//  - a second run or resume of a held job is refused naming its holder, a
//    holder killed is shown as interrupted, and the resume takes over;
//  - a corrupted checkpoint is reported and the job falls back past it;
//  - progress is logged as plain lines when stderr is not a terminal;
//  - `calib results` prints and exports, `calib best` writes a parameter
//    file that `calib simulate` and `calib score` accept;
//  - a bad job spec is an error naming the file and the field.

#include "calib/results/store.h"
#include "jobs/job_test_support.h"
#include "support/csv_support.h"
#include "support/process_support.h"
#include "support/sqlite_support.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <random>
#include <thread>

namespace calib {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "text: " << (text) << "\nmissing: " << (part)

const std::string kCalib = CALIB_EXE;

// The job: CMA-ES over the base model on examples/push_centre with 40 px
// mesh edges and 4 substeps; 64 evaluations in generations of 4.
std::string JobYaml(const std::string& name) {
  return testing::SmallPushJobYaml(
      name, (fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre").string(), 3, 64,
      fmt::format("results: {{store: {}.sqlite, out_dir: {}_out}}", name, name));
}

std::vector<EvaluationRecord> History(const fs::path& db, const std::string& name = "cli_job") {
  StoreOptions options;
  options.read_only = true;
  ResultStore store(db, options);
  const std::optional<JobInfo> job = store.FindJob(name);
  if (!job) {
    ADD_FAILURE() << db << ": no job " << name;
    return {};
  }
  return store.Evaluations(job->id);
}

int64_t EvaluationCount(const fs::path& db, const std::string& name = "cli_job") {
  StoreOptions options;
  options.read_only = true;
  ResultStore store(db, options);
  return store.EvaluationCount(store.FindJob(name)->id);
}

// False also while the store is being created (an empty database).
bool HasEvaluations(const fs::path& db, const std::string& name = "cli_job") {
  if (!fs::exists(db)) return false;
  try {
    StoreOptions options;
    options.read_only = true;
    ResultStore store(db, options);
    const std::optional<JobInfo> job = store.FindJob(name);
    return job && (store.EvaluationCount(job->id) > 0 || store.CheckpointCount(job->id) > 0);
  } catch (const StoreError&) {
    return false;
  }
}

// One folder for the whole suite: the spec, the segmentation cache and the
// reference (uninterrupted, 2 threads) run.
class JobCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("calib_test_" + std::to_string(::getpid()) + "_job_cli"));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    spec_ = new fs::path(*dir_ / "cli_job.yaml");
    std::ofstream(*spec_) << JobYaml("cli_job");
    reference_ = new testing::ProcessResult(testing::RunProcess(
        Args({"run", spec_->string(), "--store", (*dir_ / "reference.sqlite").string(),
              "--no-report", "--progress", "auto", "--progress-interval", "0"}),
        *dir_));
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    delete spec_;
    delete reference_;
  }

  // calib with `args` and the suite's segmentation cache.
  static std::vector<std::string> Args(std::vector<std::string> args) {
    args.insert(args.begin(), kCalib);
    args.push_back("--cache-dir");
    args.push_back((*dir_ / "cache").string());
    return args;
  }

  void SetUp() override {
    ASSERT_EQ(reference_->exit_code, 0) << reference_->out << reference_->err;
  }

  static std::vector<EvaluationRecord> ReferenceHistory() {
    return History(*dir_ / "reference.sqlite");
  }

  static fs::path* dir_;
  static fs::path* spec_;
  static testing::ProcessResult* reference_;
};

fs::path* JobCli::dir_ = nullptr;
fs::path* JobCli::spec_ = nullptr;
testing::ProcessResult* JobCli::reference_ = nullptr;

TEST_F(JobCli, TheReferenceRunFinishesAndReportsItsBest) {
  EXPECT_CONTAINS(reference_->out, "status: finished");
  EXPECT_CONTAINS(reference_->out, "evaluations: 64 (");
  EXPECT_CONTAINS(reference_->out, "best: score ");
  const std::vector<EvaluationRecord> history = ReferenceHistory();
  ASSERT_EQ(history.size(), 64u);
  int ok = 0;
  for (const auto& e : history) ok += e.ok ? 1 : 0;
  EXPECT_GT(ok, 0);
}

TEST_F(JobCli, ProgressIsLoggedAsPlainLinesWhenNotATerminal) {
  const std::string& log = reference_->err;
  int lines = 0;
  for (size_t at = log.find("evaluations ("); at != std::string::npos;
       at = log.find("evaluations (", at + 1)) {
    ++lines;
  }
  EXPECT_GE(lines, 6) << "a line per batch at --progress-interval 0:\n" << log;
  EXPECT_CONTAINS(log, "64/64 evaluations (100.0 %)");
  EXPECT_CONTAINS(log, "eval/s, best ");
  EXPECT_CONTAINS(log, "ETA ");
  EXPECT_EQ(log.find('\r'), std::string::npos) << "no bar in a log";
  EXPECT_EQ(log.find('\033'), std::string::npos) << "no escape codes in a log";
}

TEST_F(JobCli, SigkillAtRandomMomentsAndResumeGivesTheUninterruptedHistory) {
  const fs::path dir = testing::ScratchDir("job_cli_kill");
  const fs::path db = dir / "killed.sqlite";
  // Each kill comes at a random moment (a fixed seed, so a failure
  // reproduces) after the invocation has recorded something new, so that
  // every one interrupts a running job; short delays keep a fast machine
  // from finishing the job before several kills.
  std::mt19937 rng(20261123);
  std::uniform_real_distribution<double> delay_s(0.0, 0.1);
  int kills = 0;
  bool finished = false;
  for (int attempt = 0; attempt < 12 && kills < 4 && !finished; ++attempt) {
    const int64_t before = HasEvaluations(db) ? EvaluationCount(db) : 0;
    const std::string verb = HasEvaluations(db) ? "resume" : "run";
    testing::ChildProcess child(
        Args({verb, spec_->string(), "--store", db.string(), "--no-report", "--progress", "log"}),
        dir);
    while (!child.Exited() && !(HasEvaluations(db) && EvaluationCount(db) > before)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(delay_s(rng)));
    child.Kill(SIGKILL);
    const testing::ProcessResult r = child.Wait();
    if (r.exit_code == 0) {
      finished = true;  // it ended before the kill
    } else {
      EXPECT_EQ(r.signal, SIGKILL) << verb << " exited " << r.exit_code << ":\n" << r.err;
      ++kills;
    }
  }
  EXPECT_GE(kills, 3) << "the job was too quick to be killed several times";
  if (!finished) {
    const std::string verb = HasEvaluations(db) ? "resume" : "run";
    const testing::ProcessResult r = testing::RunProcess(
        Args({verb, spec_->string(), "--store", db.string(), "--no-report", "--progress", "log"}),
        dir);
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    EXPECT_CONTAINS(r.out, "status: finished");
  }
  testing::ExpectSameHistory(ReferenceHistory(), History(db), "killed and resumed");
}

TEST_F(JobCli, ASecondProcessIsRefusedAndAKilledHolderIsShownInterruptedAndResumed) {
  const fs::path dir = testing::ScratchDir("job_cli_lock");
  const fs::path db = dir / "locked.sqlite";
  const auto calib = [&](const std::string& verb) {
    return Args({verb, spec_->string(), "--store", db.string(), "--no-report", "--progress", "none"});
  };
  testing::ChildProcess first(calib("run"), dir);
  while (!first.Exited() && !HasEvaluations(db)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_FALSE(first.Exited()) << "the job ended before it could be held";
  first.Kill(SIGSTOP);  // paused, alive, holding the job
  const std::string holder = fmt::format("by process {} on host '", first.pid());
  for (const std::string verb : {"resume", "run"}) {
    const testing::ProcessResult second = testing::RunProcess(calib(verb), dir);
    EXPECT_EQ(second.exit_code, 2) << verb << ": " << second.err;
    EXPECT_CONTAINS(second.err, holder);
  }
  const auto results = [&] {
    return testing::RunProcess({kCalib, "results", spec_->string(), "--store", db.string()}, dir);
  };
  EXPECT_CONTAINS(results().out, fmt::format("status: running, by process {}", first.pid()));
  first.Kill(SIGKILL);
  EXPECT_EQ(first.Wait().signal, SIGKILL);
  const testing::ProcessResult after = results();
  EXPECT_CONTAINS(after.out, "status: interrupted (left running by process");
  EXPECT_CONTAINS(after.out, "calib resume");
  const testing::ProcessResult resumed = testing::RunProcess(calib("resume"), dir);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_CONTAINS(resumed.err, "took over the lock of process");
  testing::ExpectSameHistory(ReferenceHistory(), History(db), "held, killed and resumed");
}

TEST_F(JobCli, CorruptedCheckpointIsReportedAndTheJobFallsBackPastIt) {
  const fs::path dir = testing::ScratchDir("job_cli_corrupt");
  const fs::path db = dir / "r.sqlite";
  // Stop it (resumably) part-way once a few checkpoints exist, by SIGHUP
  // (a closed terminal), which stops a job as SIGTERM and SIGINT do.
  {
    testing::ChildProcess child(
        Args({"run", spec_->string(), "--store", db.string(), "--no-report", "--progress", "log"}),
        dir);
    while (true) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      if (!HasEvaluations(db)) continue;
      StoreOptions options;
      options.read_only = true;
      ResultStore store(db, options);
      if (store.CheckpointCount(store.FindJob("cli_job")->id) >= 2) break;
    }
    child.Kill(SIGHUP);
    const testing::ProcessResult r = child.Wait();
    if (r.exit_code == 0) GTEST_SKIP() << "the job finished before it could be stopped";
    ASSERT_EQ(r.exit_code, 4) << "stopped resumably:\n" << r.out << r.err;
    EXPECT_CONTAINS(r.out, "status: stopped (interrupted)");
  }
  int64_t newest = 0;
  {
    StoreOptions options;
    options.read_only = true;
    ResultStore store(db, options);
    newest = store.LatestCheckpoint(store.FindJob("cli_job")->id).checkpoint->sequence;
  }
  testing::RawSql(db, fmt::format("UPDATE checkpoints SET state_json = substr(state_json, 1, 25) "
                                  "WHERE sequence = {}",
                                  newest));
  const testing::ProcessResult r = testing::RunProcess(
      Args({"resume", spec_->string(), "--store", db.string(), "--no-report", "--progress", "log"}),
      dir);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_CONTAINS(r.err, fmt::format("checkpoint {} is corrupted", newest));
  EXPECT_CONTAINS(r.out, fmt::format("resumed from checkpoint {}", newest - 1));
  testing::ExpectSameHistory(ReferenceHistory(), History(db), "resumed past a corrupted checkpoint");
}

// `mpirun -np 3` (on one machine without a network) of calib with `args`.
std::vector<std::string> ThreeMpiRanks(const std::vector<std::string>& args) {
  std::vector<std::string> command = {CALIB_MPIEXEC, "--allow-run-as-root", "--oversubscribe",
                                      "--bind-to", "none", "--mca", "btl", "self,vader", "--mca",
                                      "btl_vader_single_copy_mechanism", "none", "-np", "3"};
  command.insert(command.end(), args.begin(), args.end());
  return command;
}

TEST_F(JobCli, ThreeMpiRanksGiveTheHistoryOfThreads) {
  const fs::path dir = testing::ScratchDir("job_cli_mpi");
  const fs::path db = dir / "mpi.sqlite";
  const testing::ProcessResult r = testing::RunProcess(
      ThreeMpiRanks(Args({"run", spec_->string(), "--store", db.string(), "--no-report",
                          "--progress", "log"})),
      dir, {}, 600.0);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_CONTAINS(r.err, "MPI: manager and 2 worker ranks");
  EXPECT_CONTAINS(r.out, "status: finished");
  const std::vector<EvaluationRecord> history = History(db);
  testing::ExpectSameHistory(ReferenceHistory(), history, "3 MPI ranks vs 2 threads");
  std::set<std::string> workers;
  for (const auto& e : history) workers.insert(e.worker);
  EXPECT_EQ(workers, (std::set<std::string>{"rank 1", "rank 2"}))
      << "the manager evaluates nothing; both workers do";
}

// With pruning the workers get their bounds in the kWork message and send
// the trace of the score so far back: the history is still that of threads.
TEST_F(JobCli, ThreeMpiRanksGiveTheHistoryOfThreadsWhenPruning) {
  const fs::path dir = testing::ScratchDir("job_cli_mpi_pruned");
  std::string yaml = JobYaml("cli_pruned");
  const std::string budget = "budget: {evaluations: 64}";
  ASSERT_NE(yaml.find(budget), std::string::npos);
  yaml.replace(yaml.find(budget), budget.size(), "budget: {evaluations: 32, prune_factor: 1.1}");
  const fs::path spec = dir / "cli_pruned.yaml";
  std::ofstream(spec) << yaml;
  const testing::ProcessResult threads = testing::RunProcess(
      Args({"run", spec.string(), "--store", (dir / "threads.sqlite").string(), "--no-report"}),
      dir);
  ASSERT_EQ(threads.exit_code, 0) << threads.out << threads.err;
  const testing::ProcessResult mpi = testing::RunProcess(
      ThreeMpiRanks(Args({"run", spec.string(), "--store", (dir / "mpi.sqlite").string(),
                          "--no-report", "--progress", "log"})),
      dir, {}, 600.0);
  ASSERT_EQ(mpi.exit_code, 0) << mpi.out << mpi.err;
  const std::vector<EvaluationRecord> reference = History(dir / "threads.sqlite", "cli_pruned");
  ASSERT_EQ(reference.size(), 32u);
  int pruned = 0;
  for (const auto& e : reference) pruned += e.pruned ? 1 : 0;
  EXPECT_GT(pruned, 0) << "the test needs pruned evaluations";
  EXPECT_CONTAINS(threads.out, fmt::format("{} pruned", pruned));
  testing::ExpectSameHistory(reference, History(dir / "mpi.sqlite", "cli_pruned"),
                             "3 MPI ranks vs 2 threads, pruning");
}

// A comparison (random with two seeds, DIRECT_L once) on the suite's small
// objective, its store and report in `out`.
fs::path WriteComparisonSpec(const fs::path& dir, const std::string& seeds) {
  const fs::path spec = dir / fmt::format("compare_{}.yaml", seeds.size());
  std::ofstream(spec) << fmt::format(R"yaml(
name: mpi_compare
train: [{}]
model:
  substeps: 4
  mesh: {{edge_length_px: 40}}
{}budget: {{evaluations: 12}}
optimizers:
  - {{name: random}}
  - {{name: nlopt:DIRECT_L}}
seeds: {}
checkpoint: {{every_evaluations: 4, every_seconds: 0}}
)yaml",
                                     (fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre").string(),
                                     testing::kBaseParametersYaml, seeds);
  return spec;
}

// `mpirun -np 3 calib compare-optimizers`: every run spread over the ranks,
// each run's history that of threads; a comparison begun with threads
// (seed 1) is continued under MPI (seed 2 added) and ends as one run with
// threads throughout; --status counts the runs.
TEST_F(JobCli, ThreeMpiRanksCompareOptimizersAsThreadsDo) {
  const fs::path dir = testing::ScratchDir("job_cli_mpi_compare");
  const fs::path both = WriteComparisonSpec(dir, "[1, 2]");
  const testing::ProcessResult threads = testing::RunProcess(
      Args({"compare-optimizers", both.string(), "--out", (dir / "threads").string(),
            "--threads", "2", "--progress", "none"}),
      dir);
  ASSERT_EQ(threads.exit_code, 0) << threads.out << threads.err;
  EXPECT_CONTAINS(threads.out, "3 runs: 0 done before, 3 run now");

  const testing::ProcessResult first = testing::RunProcess(
      Args({"compare-optimizers", WriteComparisonSpec(dir, "[1]").string(), "--out",
            (dir / "mpi").string(), "--threads", "2", "--progress", "none"}),
      dir);
  ASSERT_EQ(first.exit_code, 0) << first.out << first.err;
  const testing::ProcessResult mpi = testing::RunProcess(
      ThreeMpiRanks(Args({"compare-optimizers", both.string(), "--out", (dir / "mpi").string(),
                          "--progress", "log"})),
      dir, {}, 600.0);
  ASSERT_EQ(mpi.exit_code, 0) << mpi.out << mpi.err;
  EXPECT_CONTAINS(mpi.out, "3 runs: 2 done before, 1 run now");
  EXPECT_CONTAINS(mpi.err, "MPI: manager and 2 worker ranks");
  EXPECT_CONTAINS(mpi.out, "report: ");

  for (const std::string job : {"mpi_compare.random.s1", "mpi_compare.random.s2",
                                "mpi_compare.nlopt_DIRECT_L.s1"}) {
    testing::ExpectSameHistory(History(dir / "threads" / "comparison.sqlite", job),
                               History(dir / "mpi" / "comparison.sqlite", job),
                               job + ": 3 MPI ranks (seed 2) vs 2 threads");
  }
  std::set<std::string> workers;
  for (const auto& e : History(dir / "mpi" / "comparison.sqlite", "mpi_compare.random.s2")) {
    workers.insert(e.worker);
  }
  EXPECT_EQ(workers, (std::set<std::string>{"rank 1", "rank 2"}));
  // The report's numbers are those of threads: the same scores, ranks and
  // statistics.
  for (const char* csv : {"runs.csv", "convergence.csv", "fixed_budget.csv", "fixed_target.csv", "pairwise.csv"}) {
    EXPECT_EQ(testing::ReadText(dir / "threads" / csv), testing::ReadText(dir / "mpi" / csv)) << csv;
  }

  // Run again under MPI: nothing left to run, the workers are let go at once.
  const testing::ProcessResult again = testing::RunProcess(
      ThreeMpiRanks(Args({"compare-optimizers", both.string(), "--out", (dir / "mpi").string(),
                          "--progress", "none"})),
      dir, {}, 600.0);
  ASSERT_EQ(again.exit_code, 0) << again.out << again.err;
  EXPECT_CONTAINS(again.out, "3 runs: 3 done before, 0 run now");

  const testing::ProcessResult status = testing::RunProcess(
      {kCalib, "compare-optimizers", both.string(), "--out", (dir / "mpi").string(), "--status"},
      dir);
  ASSERT_EQ(status.exit_code, 0) << status.err;
  EXPECT_CONTAINS(status.out, "random seed 2 (job mpi_compare.random.s2): finished (");
  EXPECT_CONTAINS(status.out, ", 12 evaluations\n");
  EXPECT_CONTAINS(status.out, "3 runs: 3 finished\n");
}

TEST_F(JobCli, ResultsPrintsAndExportsAndBestFeedsSimulate) {
  const fs::path dir = testing::ScratchDir("job_cli_results");
  const std::string db = (*dir_ / "reference.sqlite").string();
  const testing::ProcessResult results = testing::RunProcess(
      {kCalib, "results", spec_->string(), "--store", db, "--csv", (dir / "e.csv").string(),
       "--json", (dir / "e.json").string(), "--plot", (dir / "c.svg").string()},
      dir);
  ASSERT_EQ(results.exit_code, 0) << results.err;
  EXPECT_CONTAINS(results.out, "wrote " + (dir / "c.svg").string());
  const std::string svg = testing::ReadText(dir / "c.svg");
  EXPECT_CONTAINS(svg, "<svg");
  EXPECT_CONTAINS(svg, "cli_job: 64 evaluations, ");
  EXPECT_CONTAINS(results.out, "job: cli_job");
  EXPECT_CONTAINS(results.out, "status: finished");
  EXPECT_CONTAINS(results.out, "evaluations: 64 (");
  EXPECT_CONTAINS(results.out, "best parameters: k_A=");
  const testing::CsvRows rows = testing::ParseCsvFile(dir / "e.csv");
  ASSERT_EQ(rows.size(), 65u);
  EXPECT_EQ(rows[0][0], "id");
  EXPECT_TRUE(fs::file_size(dir / "e.json") > 0);

  // By name with --store, too.
  const testing::ProcessResult by_name =
      testing::RunProcess({kCalib, "results", "cli_job", "--store", db}, dir);
  EXPECT_EQ(by_name.exit_code, 0) << by_name.err;
  EXPECT_EQ(by_name.out, results.out.substr(0, by_name.out.size()));

  const fs::path best = dir / "best" / "params.json";
  const testing::ProcessResult b = testing::RunProcess(
      {kCalib, "best", spec_->string(), "--store", db, "--out", best.string()}, dir);
  ASSERT_EQ(b.exit_code, 0) << b.err;
  EXPECT_CONTAINS(b.out, "wrote " + best.string());
  std::optional<EvaluationRecord> expected;
  for (const auto& e : ReferenceHistory()) {
    if (e.ok && (!expected || e.score < expected->score)) expected = e;
  }
  ASSERT_TRUE(expected.has_value());
  EXPECT_CONTAINS(b.out, fmt::format("best: evaluation {}, score {}", expected->id, expected->score));

  const std::string example = (fs::path(CALIB_SOURCE_DIR) / "examples" / "push_centre").string();
  const testing::ProcessResult score = testing::RunProcess(
      Args({"score", example, "--params", best.string(), "--edge", "40", "--substeps", "4"}), dir);
  ASSERT_EQ(score.exit_code, 0) << score.out << score.err;
  EXPECT_CONTAINS(score.out, fmt::format(": {}\n", expected->score))
      << "calib score of the best file gives the job's best score";
  const testing::ProcessResult simulate = testing::RunProcess(
      Args({"simulate", example, "--params", best.string(), "--out", (dir / "sim").string(),
            "--edge", "40", "--substeps", "4", "--no-video"}),
      dir);
  EXPECT_EQ(simulate.exit_code, 0) << simulate.out << simulate.err;
  EXPECT_TRUE(fs::exists(dir / "sim" / "frames.csv"));
}

TEST_F(JobCli, RunTwiceAndResumeAFinishedJobSayWhatToDo) {
  const std::string db = (*dir_ / "reference.sqlite").string();
  const fs::path dir = testing::ScratchDir("job_cli_again");
  const testing::ProcessResult again =
      testing::RunProcess(Args({"run", spec_->string(), "--store", db, "--no-report"}), dir);
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_CONTAINS(again.err, "job 'cli_job' already exists");
  EXPECT_CONTAINS(again.err, "calib resume");
  const testing::ProcessResult resume =
      testing::RunProcess(Args({"resume", spec_->string(), "--store", db, "--no-report"}), dir);
  EXPECT_EQ(resume.exit_code, 0) << resume.err;
  EXPECT_CONTAINS(resume.out, "nothing to do: the job is already finished");
  const testing::ProcessResult absent = testing::RunProcess(
      {kCalib, "best", "nosuchjob", "--store", db, "--out", (dir / "p.json").string()}, dir);
  EXPECT_EQ(absent.exit_code, 2);
  EXPECT_CONTAINS(absent.err, "no job 'nosuchjob' (jobs there: cli_job)");
}

// calib `args` (with the suite's cache) run in the folder `cwd`.
std::vector<std::string> InFolder(const fs::path& cwd, std::vector<std::string> args) {
  args.insert(args.begin(), {"/bin/sh", "-c", "cd \"$0\" && exec \"$@\"", cwd.string()});
  return args;
}

TEST_F(JobCli, ValidateFreshSeedNameBudgetAndTheResumeCommandOfAStoppedRun) {
  const fs::path dir = testing::ScratchDir("job_cli_manage");
  std::string text = JobYaml("cli_job");
  const std::string results = "results: {store: cli_job.sqlite, out_dir: cli_job_out}";
  ASSERT_NE(text.find(results), std::string::npos);
  text.erase(text.find(results), results.size());  // the default places, under out/
  const fs::path spec = dir / "spec" / "job.yaml";
  fs::create_directories(spec.parent_path());
  std::ofstream(spec) << text;
  const fs::path store = dir / "out" / "jobs" / "cli_job.sqlite";

  const testing::ProcessResult valid =
      testing::RunProcess(InFolder(dir, {kCalib, "validate", spec.string()}), dir);
  EXPECT_EQ(valid.exit_code, 0) << valid.err;
  EXPECT_CONTAINS(valid.out, "valid: job 'cli_job', 5 searched parameters, optimiser cmaes, 64 evaluations");
  EXPECT_CONTAINS(valid.out, "store: " + store.string());
  EXPECT_FALSE(fs::exists(dir / "out")) << "validate writes nothing";

  // A finished job extended with a larger budget: the history of the
  // uninterrupted reference run at that budget.
  const testing::ProcessResult small = testing::RunProcess(
      InFolder(dir, Args({"run", spec.string(), "--budget", "16", "--no-report", "--progress", "none"})),
      dir);
  ASSERT_EQ(small.exit_code, 0) << small.err;
  EXPECT_EQ(EvaluationCount(store), 16);
  const testing::ProcessResult extended = testing::RunProcess(
      InFolder(dir, Args({"resume", spec.string(), "--budget", "32", "--no-report", "--progress", "none"})),
      dir);
  ASSERT_EQ(extended.exit_code, 0) << extended.err;
  std::vector<EvaluationRecord> first32 = ReferenceHistory();
  first32.resize(32);  // CMA-ES proposes the same whatever its budget
  testing::ExpectSameHistory(first32, History(store), "extended from 16 to 32");
  const testing::ProcessResult shown =
      testing::RunProcess(InFolder(dir, {kCalib, "results", spec.string()}), dir);
  EXPECT_CONTAINS(shown.out, "resume --budget 32: ");
  EXPECT_CONTAINS(shown.out, "by calib ");

  // Again: refused, naming --fresh; --fresh starts over, with --seed.
  const testing::ProcessResult again = testing::RunProcess(
      InFolder(dir, Args({"run", spec.string(), "--no-report", "--progress", "none"})), dir);
  EXPECT_EQ(again.exit_code, 2);
  EXPECT_CONTAINS(again.err, "calib run --fresh");
  const testing::ProcessResult fresh = testing::RunProcess(
      InFolder(dir, Args({"run", spec.string(), "--fresh", "--seed", "3", "--budget", "8",
                          "--no-report", "--progress", "none"})),
      dir);
  ASSERT_EQ(fresh.exit_code, 0) << fresh.err;
  std::vector<EvaluationRecord> first8 = ReferenceHistory();
  first8.resize(8);
  testing::ExpectSameHistory(first8, History(store), "fresh, seed 3 as the spec's");
  const testing::ProcessResult reseeded = testing::RunProcess(
      InFolder(dir, Args({"run", spec.string(), "--fresh", "--seed", "4", "--budget", "8",
                          "--no-report", "--progress", "none"})),
      dir);
  ASSERT_EQ(reseeded.exit_code, 0) << reseeded.err;
  EXPECT_NE(History(store).at(0).x, first8.at(0).x) << "--seed 4 searches elsewhere";

  // A stopped run prints the command that continues it, overrides and all.
  const testing::ProcessResult stopped = testing::RunProcess(
      InFolder(dir, Args({"run", spec.string(), "--name", "renamed", "--budget", "8", "--wall-time",
                          "0.001", "--no-report", "--progress", "none"})),
      dir);
  EXPECT_EQ(stopped.exit_code, 4) << stopped.err;
  const std::string resume_command = "calib resume " + spec.string() + " --name renamed --budget 8";
  EXPECT_CONTAINS(stopped.out, "continue it with: " + resume_command);
  EXPECT_TRUE(fs::exists(dir / "out" / "jobs" / "renamed.sqlite")) << "the default store follows --name";
  const testing::ProcessResult resumed = testing::RunProcess(
      InFolder(dir, Args({"resume", spec.string(), "--name", "renamed", "--budget", "8",
                          "--no-report", "--progress", "none"})),
      dir);
  EXPECT_EQ(resumed.exit_code, 0) << resumed.err;
  EXPECT_EQ(EvaluationCount(dir / "out" / "jobs" / "renamed.sqlite", "renamed"), 8);
}

TEST_F(JobCli, BadJobSpecIsNamedByFileFieldAndValue) {
  const fs::path dir = testing::ScratchDir("job_cli_bad");
  struct Case {
    std::string from, to, message;
  };
  const std::vector<Case> cases = {
      {"budget: {evaluations: 64}", "budget: {evaluations: 0}", "budget.evaluations = '0': must be >= 1"},
      {"upper: 50,", "uper: 50,", "parameters[1].upper: missing"},
      {"scale: log}\n  - {name: k_d", "scale: lin}\n  - {name: k_d", "parameters[0].scale = 'lin'"},
      {"name: cmaes", "name: cmaez", "optimizer.name = 'cmaez'"},
      {"population: 4", "population: 1", "optimizer.settings"},
      {"seed: 3", "seed: -3", "seed = '-3'"},
  };
  const std::string good = JobYaml("bad_job");
  for (const Case& c : cases) {
    std::string text = good;
    const size_t at = text.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    text.replace(at, c.from.size(), c.to);
    const fs::path spec = dir / "bad.yaml";
    std::ofstream(spec) << text;
    const testing::ProcessResult r =
        testing::RunProcess({kCalib, "run", spec.string(), "--no-report"}, dir);
    EXPECT_EQ(r.exit_code, 2) << c.to;
    EXPECT_CONTAINS(r.err, spec.string() + ": ");
    EXPECT_CONTAINS(r.err, c.message);
    EXPECT_FALSE(fs::exists(dir / "bad_job.sqlite")) << "nothing starts before the spec is valid";
  }
  // A report folder that cannot be made is named before any evaluation.
  std::ofstream(dir / "a_file") << "not a folder";
  std::string text = good;
  const std::string results = "results: {store: bad_job.sqlite, out_dir: bad_job_out}";
  ASSERT_NE(text.find(results), std::string::npos);
  text.replace(text.find(results), results.size(),
               "results: {store: unwritable.sqlite, out_dir: a_file/report}");
  const fs::path spec = dir / "unwritable.yaml";
  std::ofstream(spec) << text;
  const testing::ProcessResult unwritable =
      testing::RunProcess({kCalib, "run", spec.string(), "--progress", "none"}, dir);
  EXPECT_EQ(unwritable.exit_code, 2) << unwritable.err;
  EXPECT_CONTAINS(unwritable.err, "results.out_dir = '" + (dir / "a_file/report").string() + "'");
  EXPECT_CONTAINS(unwritable.err, "cannot create the folder");
  EXPECT_FALSE(fs::exists(dir / "unwritable.sqlite")) << "nothing evaluated or stored";
  const testing::ProcessResult missing =
      testing::RunProcess({kCalib, "run", (dir / "absent.yaml").string()}, dir);
  EXPECT_EQ(missing.exit_code, 2);
  EXPECT_CONTAINS(missing.err, "absent.yaml");
}

}  // namespace
}  // namespace calib
