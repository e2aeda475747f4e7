// The NLopt adapter keeps NLopt's behaviour: ask/tell proposes exactly the
// points a direct nlopt_optimize run evaluates, and replays fail loudly when
// stored evaluations do not match.
#include <nlopt.h>

#include <cstring>

#include <gtest/gtest.h>

#include "harness.h"

namespace calib::search {
namespace {

struct DirectRun {
  std::vector<std::vector<double>> points;
};

double RecordingObjective(unsigned n, const double* x, double*, void* data) {
  auto* run = static_cast<DirectRun*>(data);
  run->points.emplace_back(x, x + n);
  return testing::Rosenbrock(run->points.back());
}

// NLopt driving its own loop, as it would without the adapter.
DirectRun RunDirectly(nlopt_algorithm algorithm, int n, int maxeval, unsigned long seed) {
  DirectRun run;
  nlopt_opt opt = nlopt_create(algorithm, n);
  std::vector<double> lo(n, -2), hi(n, 2), x(n, 0.0);
  nlopt_set_lower_bounds(opt, lo.data());
  nlopt_set_upper_bounds(opt, hi.data());
  nlopt_set_maxeval(opt, maxeval);
  nlopt_set_xtol_rel(opt, 1e-8);
  if (algorithm == NLOPT_G_MLSL_LDS) {
    nlopt_opt local = nlopt_create(NLOPT_LN_BOBYQA, n);
    nlopt_set_xtol_rel(local, 1e-4);
    nlopt_set_local_optimizer(opt, local);
    nlopt_destroy(local);
  }
  nlopt_set_min_objective(opt, RecordingObjective, &run);
  nlopt_srand(seed);
  double f;
  nlopt_optimize(opt, x.data(), &f);
  nlopt_destroy(opt);
  return run;
}

TEST(Nlopt, AskTellProposesExactlyWhatNloptEvaluatesOnItsOwn) {
  const std::vector<std::pair<std::string, nlopt_algorithm>> algorithms = {
      {"BOBYQA", NLOPT_LN_BOBYQA}, {"SBPLX", NLOPT_LN_SBPLX},     {"COBYLA", NLOPT_LN_COBYLA},
      {"DIRECT", NLOPT_GN_DIRECT}, {"CRS2_LM", NLOPT_GN_CRS2_LM}, {"ESCH", NLOPT_GN_ESCH},
      {"ISRES", NLOPT_GN_ISRES},   {"MLSL", NLOPT_G_MLSL_LDS}};
  for (const auto& [name, algorithm] : algorithms) {
    const DirectRun direct = RunDirectly(algorithm, 3, 150, 77);
    CheckedOptimizer opt = MakeOptimizer("nlopt:" + name, {{"maxeval", 150}}, testing::Box(3, -2, 2), 77);
    const testing::History h = testing::RunOptimizer(opt, testing::Rosenbrock, 1);
    // maxeval is a hard limit in the adapter; NLopt may overshoot it.
    ASSERT_EQ(h.asked.size(), std::min<size_t>(direct.points.size(), 150)) << name;
    for (size_t i = 0; i < h.asked.size(); ++i) {
      ASSERT_EQ(std::memcmp(h.asked[i].x.data(), direct.points[i].data(), 3 * sizeof(double)), 0)
          << name << ": evaluation " << i << " differs from NLopt's own run";
    }
    EXPECT_NE(opt.StopReason().find("NLopt returned"), std::string::npos) << opt.StopReason();
  }
}

TEST(Nlopt, StopsOnItsToleranceBeforeTheBudget) {
  CheckedOptimizer opt = MakeOptimizer("nlopt:BOBYQA", {{"maxeval", 5000}, {"xtol_rel", 1e-6}},
                                       testing::Box(3, -5, 5), 1);
  const testing::History h = testing::RunOptimizer(opt, testing::Sphere, 1);
  EXPECT_TRUE(opt.Done());
  EXPECT_LT(h.asked.size(), 5000u);
  EXPECT_NE(opt.StopReason().find("XTOL_REACHED"), std::string::npos) << opt.StopReason();
  EXPECT_LT(h.best, 1e-8);
}

TEST(Nlopt, OneCandidateAtATimeAndNoneWhileOneIsOutstanding) {
  CheckedOptimizer opt = MakeOptimizer("nlopt:SBPLX", nullptr, testing::Box(2, -1, 1), 1);
  EXPECT_EQ(opt.Ask(8).size(), 1u);
  EXPECT_TRUE(opt.Ask(8).empty());
  EXPECT_FALSE(opt.Done());
}

TEST(Nlopt, TamperedStateFailsLoudlyOnReplay) {
  CheckedOptimizer opt = MakeOptimizer("nlopt:NELDERMEAD", nullptr, testing::Box(2, -1, 1), 1);
  testing::RunOptimizer(opt, testing::Sphere, 1, testing::TellOrder::kInOrder, 10);
  nlohmann::json state = opt.SaveState();
  state["plugin"]["evaluations"][4]["raw_x"][0] = 0.123456;
  CheckedOptimizer fresh = MakeOptimizer("nlopt:NELDERMEAD", nullptr, testing::Box(2, -1, 1), 1);
  try {
    fresh.RestoreState(state);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("replay diverged at evaluation 4"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace calib::search
