// `calib compare-optimizers` without recordings: the comparison spec's
// validation (messages naming the file and key), runs on cheap analytic
// objectives of the unit box (a shifted Rosenbrock, a shifted Rastrigin)
// through the objective hook the job commands offer (the spec names the
// bundled push_centre recording, which the runner fingerprints but never
// simulates), the report's files
// and numbers, and a comparison killed (SIGKILL) mid-run and run again
// giving the results of an uninterrupted one at another thread count.

#include "calib/jobs/comparison.h"
#include "calib/results/gnuplot.h"
#include "calib/search/external_optimizer.h"
#include "jobs/job_test_support.h"
#include "support/csv_support.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <csignal>
#include <fstream>
#include <functional>
#include <numbers>
#include <sstream>

namespace calib {
namespace {

namespace fs = std::filesystem;

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "text: " << (text) << "\nmissing: " << (part)

using AnalyticFunction = std::function<double(const std::vector<double>& u)>;

// Rosenbrock's valley moved so that its minimum (0) is at u = 0.3 + 1/3 in
// every coordinate of the unit box.
double ShiftedRosenbrock(const std::vector<double>& u) {
  double f = 0.0;
  for (size_t i = 0; i + 1 < u.size(); ++i) {
    const double a = 3.0 * (u[i] - 0.3), b = 3.0 * (u[i + 1] - 0.3);
    f += 100.0 * (b - a * a) * (b - a * a) + (1.0 - a) * (1.0 - a);
  }
  return f;
}

// Rastrigin (many local minima), its global minimum (0) at u = 0.37.
double ShiftedRastrigin(const std::vector<double>& u) {
  double f = 10.0 * static_cast<double>(u.size());
  for (double v : u) {
    const double z = 5.12 * (v - 0.37);
    f += z * z - 10.0 * std::cos(2.0 * std::numbers::pi * z);
  }
  return f;
}

// Evaluations by every AnalyticWorker of this process; a child process
// kills itself at kill_at (0: never).
std::atomic<int64_t> g_evaluations{0};
int64_t g_kill_at = 0;

class AnalyticWorker final : public ObjectiveWorker {
 public:
  AnalyticWorker(SearchSpace space, AnalyticFunction f) : space_(std::move(space)), f_(std::move(f)) {}
  using ObjectiveWorker::Evaluate;
  ObjectiveResult Evaluate(const ParameterValues& values, const EarlyStop& /*stop*/) override {
    if (g_kill_at > 0 && ++g_evaluations == g_kill_at) std::raise(SIGKILL);
    ObjectiveResult r;
    r.status = CandidateStatus::kOk;
    r.score = f_(space_.ToUnit(values));
    r.iou.frames_total = r.iou.frames_scored = 1;
    r.iou.mean = r.iou.min = r.iou.max = 1.0 / (1.0 + r.score);
    return r;
  }

 private:
  SearchSpace space_;
  AnalyticFunction f_;
};

// f of the unit-box point of a candidate of the spec's search space.
class AnalyticObjective final : public Objective {
 public:
  AnalyticObjective(SearchSpace space, AnalyticFunction f) : space_(std::move(space)), f_(std::move(f)) {}
  std::unique_ptr<ObjectiveWorker> MakeWorker() const override {
    return std::make_unique<AnalyticWorker>(space_, f_);
  }
  std::string Describe() const override { return "analytic objective"; }

 private:
  SearchSpace space_;
  AnalyticFunction f_;
};

ComparisonOptions AnalyticOptions(AnalyticFunction f, int threads = 1) {
  ComparisonOptions o;
  o.threads = threads;
  o.progress = ProgressMode::kNone;
  o.make_objective = [f](const JobSpec& spec, const PreparationOptions&) -> std::unique_ptr<Objective> {
    return std::make_unique<AnalyticObjective>(SearchSpace(spec), f);
  };
  return o;
}

const char* const kOptimizers = R"yaml(optimizers:
  - {name: random}
  - {name: cmaes, label: cma}
  - {name: nlopt:BOBYQA}
  - {name: grid, settings: {resolution: 3}}
)yaml";

const std::string kFakeExternal = std::string(CALIB_SOURCE_DIR) + "/tests/search/fake_external_optimizer.py";
const std::string kExternalOptimizer = fmt::format(
    "optimizers:\n  - {{name: external, label: fake, command: [/usr/bin/python3, '{}', good], "
    "settings: {{batch: 4}}}}\n",
    kFakeExternal);

std::string ComparisonYaml(const std::string& keys, const std::string& optimizers = kOptimizers,
                           const std::string& budget = "budget: {evaluations: 40}\n") {
  // The runner fingerprints the recordings of every job (job_inputs.h):
  // a real one, read but never simulated (the objective is analytic).
  return fmt::format("name: cmp\ntrain: ['{}/examples/push_centre']\n{}{}{}{}", CALIB_SOURCE_DIR,
                     testing::kBaseParametersYaml, budget, optimizers, keys);
}

ComparisonSpec Parse(const std::string& text, const fs::path& out) {
  return ParseComparisonSpec(text, "cmp.yaml", fs::temp_directory_path(), out);
}

std::string ErrorOf(const std::string& text) {
  try {
    Parse(text, testing::ScratchDir("comparison_errors"));
  } catch (const JobSpecError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(ComparisonSpec, RunsEachOptimizerOncePerSeedAndSeedIndependentOnesOnce) {
  const fs::path out = testing::ScratchDir("comparison_spec");
  const ComparisonSpec spec = Parse(ComparisonYaml("seeds: [3, 5, 8]\n"), out);
  ASSERT_EQ(spec.runs.size(), 3u + 3u + 1u + 1u) << "random and cmaes per seed; BOBYQA and grid once";
  EXPECT_EQ(spec.runs[0].job.name, "cmp.random.s3");
  EXPECT_EQ(spec.runs[3].job.name, "cmp.cma.s3");
  EXPECT_EQ(spec.runs[6].job.name, "cmp.nlopt_BOBYQA.s3");
  EXPECT_EQ(spec.runs[6].job.optimizer.name, "nlopt:BOBYQA");
  EXPECT_EQ(spec.runs[7].job.optimizer.settings["resolution"], 3);
  EXPECT_EQ(spec.runs[7].job.optimizer.settings["max_evals"], 40) << "the budget filled in";
  EXPECT_EQ(spec.runs[4].job.seed, 5u);
  EXPECT_EQ(spec.out_dir, fs::absolute(out).lexically_normal());
  EXPECT_EQ(spec.store, fs::absolute(out).lexically_normal() / "comparison.sqlite");
  for (const ComparisonRun& r : spec.runs) EXPECT_EQ(r.job.results.store, spec.store) << r.job.name;
  EXPECT_EQ(spec.budget_evaluations, 40);
  EXPECT_EQ(spec.targets.kind, TargetKind::kRelative);

  const ComparisonSpec external = Parse(ComparisonYaml("seeds: 2\n", kExternalOptimizer), out);
  ASSERT_EQ(external.runs.size(), 2u) << "an external optimiser runs once per seed";
  EXPECT_EQ(external.runs[1].job.optimizer.settings["command"][2], "good") << "command goes into the settings";
  EXPECT_EQ(external.runs[1].job.optimizer.settings["max_evals"], 40);

  const ComparisonSpec defaults = Parse(ComparisonYaml(""), out);
  EXPECT_EQ(defaults.seeds.size(), 15u) << "15 seeds by default";
  // No folder given: out/compare/<name>/ in the current folder, as every
  // output's default place is under out/.
  const ComparisonSpec default_place = Parse(ComparisonYaml("seeds: 1\n"), fs::path());
  EXPECT_EQ(default_place.out_dir, (fs::absolute("out/compare") / "cmp").lexically_normal());
  EXPECT_EQ(default_place.store, default_place.out_dir / "comparison.sqlite");
  EXPECT_EQ(default_place.runs[0].job.results.out_dir, default_place.out_dir / "runs" / "cmp.random.s1");
  EXPECT_EQ(defaults.runs.size(), 15u + 15u + 1u + 1u);
  const ComparisonSpec absolute = Parse(ComparisonYaml("seeds: 2\ntargets: {absolute: [1, 0.5]}\n"), out);
  EXPECT_EQ(absolute.seeds, (std::vector<uint64_t>{1, 2}));
  EXPECT_EQ(absolute.targets.kind, TargetKind::kAbsolute);
  EXPECT_EQ(absolute.targets.values, (std::vector<double>{1.0, 0.5}));
}

TEST(ComparisonSpec, BadInputIsNamedByFileKeyAndValue) {
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers:\n  - {name: random}\n  - {name: simplex}\n")),
                  "cmp.yaml: optimizers[1].name = 'simplex': unknown optimiser");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers:\n  - {name: cmaes, settings: {population: 1}}\n")),
                  "cmp.yaml: optimizers[0].settings = ");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers:\n  - {name: cmaes, settings: {population: 1}}\n")),
                  "population");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers:\n  - {name: random}\n  - {name: random}\n")),
                  "optimizers[1].label = 'random': another optimiser has this label");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers:\n  - {name: random, lable: r}\n")),
                  "optimizers[0].lable = 'r': unknown key");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers: []\n")), "cmp.yaml: optimizers = ");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers:\n  - {name: random, command: [x]}\n")),
                  "cmp.yaml: optimizers[0].command = [x]: only an external optimiser runs a command");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", "optimizers:\n  - {name: external}\n")),
                  "cmp.yaml: optimizers[0].settings = ");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("seeds: 0\n")), "cmp.yaml: seeds = '0': must be >= 1");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("seeds: [1, 1]\n")), "cmp.yaml: seeds[1] = '1': repeats an earlier seed");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("targets: {relative: [-0.1]}\n")),
                  "cmp.yaml: targets.relative[0] = '-0.1': must be >= 0");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("targets: {relative: [0.1], absolute: [1]}\n")),
                  "cmp.yaml: targets = ");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("seed: 3\n")), "cmp.yaml: seed = '3': set per run by the comparison");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("optimizer: {name: random}\n")), "cmp.yaml: optimizer = ");
  // The objective's part is a job spec's: its messages are the job spec reader's.
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("", kOptimizers, "budget: {evaluations: 0}\n")),
                  "cmp.yaml: budget.evaluations = '0': must be >= 1");
  EXPECT_CONTAINS(ErrorOf(ComparisonYaml("treads: 2\n")), "cmp.yaml: treads = '2': unknown key");
}

// The numbers the report's files hold, as text.
std::string Read(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(Comparison, AnalyticObjectivesRunAsJobsAndTheReportHoldsTheirStatistics) {
  for (const auto& [name, f] : std::vector<std::pair<std::string, AnalyticFunction>>{
           {"rosenbrock", ShiftedRosenbrock}, {"rastrigin", ShiftedRastrigin}}) {
    const fs::path out = testing::ScratchDir("comparison_" + name);
    const ComparisonSpec spec = Parse(ComparisonYaml("seeds: 5\n"), out);
    const ComparisonResult result = RunComparison(spec, out, AnalyticOptions(f));
    ASSERT_FALSE(result.stopped) << name;
    EXPECT_EQ(result.runs, 12) << name;
    EXPECT_EQ(result.run_now, 12) << name;
    ASSERT_TRUE(result.analysis.has_value()) << name;
    const ComparisonAnalysis& a = *result.analysis;

    // Every run is a finished job of the one store; its final score is
    // the best of its evaluations there.
    ResultStore store(spec.store);
    ASSERT_EQ(store.Jobs().size(), 12u) << name;
    std::map<std::string, std::vector<double>> finals;
    for (const ComparisonRun& run : spec.runs) {
      const auto info = store.FindJob(run.job.name);
      ASSERT_TRUE(info.has_value()) << run.job.name;
      EXPECT_EQ(info->status, JobStatus::kFinished) << run.job.name;
      EXPECT_LE(store.EvaluationCount(info->id), 40) << run.job.name;
      finals[run.label].push_back(store.Best(info->id)->score);
    }
    ASSERT_EQ(a.optimizers.size(), 4u);
    for (size_t i = 0; i < a.optimizers.size(); ++i) {
      const OptimizerSummary& o = a.optimizers[i];
      std::vector<double> expected = finals.at(o.optimizer);
      EXPECT_EQ(o.final_scores, expected) << name << " " << o.optimizer;
      std::sort(expected.begin(), expected.end());
      const double median = expected.size() % 2 == 1
                                ? expected[expected.size() / 2]
                                : 0.5 * (expected[expected.size() / 2 - 1] + expected[expected.size() / 2]);
      EXPECT_DOUBLE_EQ(o.fixed_budget.back().median, median) << name << " " << o.optimizer << ": at 100 %";
      EXPECT_EQ(o.fixed_budget.back().x, 40.0);
      EXPECT_EQ(o.fixed_budget.front().x, 4.0) << "10 % of 40";
      if (i > 0) {
        EXPECT_LE(a.optimizers[i - 1].fixed_budget.back().median, median) << "best median first";
      }
      EXPECT_EQ(o.ert.size(), 5u);
      EXPECT_EQ(o.failed, 0);
    }
    for (const OptimizerSummary& o : a.optimizers) {
      EXPECT_EQ(o.runs, o.optimizer == "grid" || o.optimizer == "nlopt_BOBYQA" ? 1 : 5) << o.optimizer;
    }
    EXPECT_EQ(a.pairs.size(), 6u);
    EXPECT_CONTAINS(a.verdict, fmt::format("On this objective, at 40 evaluations, {} is best",
                                           a.optimizers.front().optimizer));
    // The best run reaches every relative target; ERT of a success rate 1
    // target is the mean hit time, finite.
    double best = INFINITY;
    for (const auto& [label, v] : finals) best = std::min(best, *std::min_element(v.begin(), v.end()));
    EXPECT_EQ(a.best_score, best);
    EXPECT_DOUBLE_EQ(a.target_scores[0], best + 0.1 * std::abs(best));

    for (const char* file : {"report.html", "runs.csv", "convergence.csv", "fixed_budget.csv", "fixed_target.csv",
                             "pairwise.csv", "comparison.json"}) {
      EXPECT_TRUE(fs::exists(out / file)) << name << ": " << file;
    }
    EXPECT_EQ(testing::ParseCsvFile(out / "runs.csv").size(), 13u) << "a header and 12 runs";
    EXPECT_EQ(testing::ParseCsvFile(out / "pairwise.csv").size(), 7u) << "a header and 6 pairs";
    const std::string html = Read(out / "report.html");
    EXPECT_CONTAINS(html, "Verdict");
    EXPECT_CONTAINS(html, "Mann-Whitney");
    std::string message;
    if (GnuplotAvailable("gnuplot", &message)) {
      EXPECT_EQ(result.report->plots, 3) << "against evaluations, against time, the ECDF";
      EXPECT_CONTAINS(html, "<svg");
    }

    // Run again: nothing is rerun, the same report.
    const std::string pairwise = Read(out / "pairwise.csv");
    const ComparisonResult again = RunComparison(spec, out, AnalyticOptions(f));
    EXPECT_EQ(again.already_done, 12);
    EXPECT_EQ(again.run_now, 0);
    EXPECT_EQ(Read(out / "pairwise.csv"), pairwise);

    // Another objective into the same folder: named, not mixed in.
    const ComparisonSpec changed =
        Parse(ComparisonYaml("seeds: 5\n", kOptimizers, "budget: {evaluations: 30}\n"), out);
    try {
      RunComparison(changed, out, AnalyticOptions(f));
      ADD_FAILURE() << "a changed comparison reused the runs";
    } catch (const std::invalid_argument& e) {
      EXPECT_CONTAINS(e.what(), "job 'cmp.random.s1' was started with another spec (/budget/evaluations");
    }
  }
}

TEST(Comparison, KilledMidwayAndRunAgainGivesTheUninterruptedResultsAtAnotherThreadCount) {
  const fs::path killed = testing::ScratchDir("comparison_killed");
  const fs::path reference = testing::ScratchDir("comparison_reference");
  // The external optimiser first: the kill lands in its second run, and its
  // program (killed with its parent's pipes closed) restarts from the
  // checkpoint's saved state.
  const std::string yaml = ComparisonYaml("seeds: 3\ncheckpoint: {every_evaluations: 8}\n",
                                          std::string(kExternalOptimizer) + std::string(kOptimizers).substr(12));
  // The child dies (SIGKILL, no cleanup) in the middle of the third run,
  // between checkpoints. It forks before this process starts any thread.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    g_kill_at = 40 + 29;
    try {
      RunComparison(Parse(yaml, killed), killed, AnalyticOptions(ShiftedRastrigin, 1));
    } catch (...) {
    }
    ::_exit(0);  // not reached: killed first
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << "the child was to be killed";

  const ComparisonSpec spec = Parse(yaml, killed);
  const ComparisonResult resumed = RunComparison(spec, killed, AnalyticOptions(ShiftedRastrigin, 1));
  EXPECT_EQ(resumed.already_done, 1) << "the run finished before the kill is not run again";
  EXPECT_EQ(resumed.run_now, 10);
  const ComparisonSpec ref_spec = Parse(yaml, reference);
  const ComparisonResult uninterrupted = RunComparison(ref_spec, reference, AnalyticOptions(ShiftedRastrigin, 2));
  ASSERT_TRUE(resumed.analysis && uninterrupted.analysis);

  ResultStore a(spec.store), b(ref_spec.store);
  for (const ComparisonRun& run : spec.runs) {
    testing::ExpectSameHistory(b.Evaluations(b.FindJob(run.job.name)->id),
                               a.Evaluations(a.FindJob(run.job.name)->id), run.job.name);
  }
  // Everything but time: the same numbers.
  for (const char* file : {"runs.csv", "convergence.csv", "fixed_budget.csv", "fixed_target.csv", "pairwise.csv"}) {
    EXPECT_EQ(Read(killed / file), Read(reference / file)) << file;
  }
}

TEST(Comparison, AnExternalOptimizerThatExitsIsANamedErrorAndWhatWasStoredStays) {
  const fs::path out = testing::ScratchDir("comparison_external_exit");
  const std::string optimizers = fmt::format(
      "optimizers:\n  - {{name: random}}\n  - {{name: external, label: quitter, command: [/usr/bin/python3, "
      "'{}', exit, '3'], settings: {{batch: 4}}}}\n",
      kFakeExternal);
  const ComparisonSpec spec = Parse(ComparisonYaml("seeds: 1\ncheckpoint: {every_evaluations: 4}\n", optimizers), out);
  try {
    RunComparison(spec, out, AnalyticOptions(ShiftedRosenbrock));
    ADD_FAILURE() << "the comparison went on";
  } catch (const search::ExternalOptimizerError& e) {
    EXPECT_EQ(e.kind(), search::ExternalOptimizerError::Kind::kExited);
    EXPECT_CONTAINS(e.what(), "exited with status 3 without replying to 'ask'");
  }
  ResultStore store(spec.store);
  const auto random = store.FindJob("cmp.random.s1");
  ASSERT_TRUE(random.has_value());
  EXPECT_EQ(random->status, JobStatus::kFinished);
  EXPECT_EQ(store.EvaluationCount(random->id), 40);
  const auto quitter = store.FindJob("cmp.quitter.s1");
  ASSERT_TRUE(quitter.has_value());
  EXPECT_EQ(quitter->status, JobStatus::kFailed);
  EXPECT_CONTAINS(quitter->stop_reason, "exited with status 3");
  EXPECT_EQ(store.EvaluationCount(quitter->id), 8) << "the two batches evaluated before it exited are kept";
}

}  // namespace
}  // namespace calib
