// CMA-ES against known behaviour of the standard (mu/mu_w, lambda)-CMA-ES
// (Hansen 2016): linear convergence on the sphere, learning an
// ill-conditioned ellipsoid's shape, solving Rosenbrock, and the optimum on
// the boundary reached through repair with penalty.
#include <cmath>

#include <gtest/gtest.h>

#include "harness.h"

namespace calib::search {
namespace {

// Evaluations until f < target (or -1).
int64_t EvalsToTarget(const testing::Objective& f, const Bounds& box, double target,
                      int64_t budget, uint64_t seed, nlohmann::json settings = {}) {
  settings["max_evals"] = budget;
  CheckedOptimizer opt = MakeOptimizer("cmaes", settings, box, seed);
  while (!opt.Done()) {
    for (const Candidate& c : opt.Ask(100)) {
      const Evaluation e = testing::Evaluate(f, c);
      opt.Tell(e);
      if (e.value < target) return c.id + 1;
    }
  }
  return -1;
}

TEST(Cmaes, ConvergesLinearlyOnTheSphere) {
  // Default lambda = 10 in 10-D: about 1.2e3 evaluations to 1e-8 from sigma
  // 3 (Hansen's reference runs); allow 2x.
  for (uint64_t seed : {1, 2, 3}) {
    const int64_t evals = EvalsToTarget(testing::Sphere, testing::Box(10, -5, 5), 1e-8, 5000, seed);
    EXPECT_GT(evals, 0) << "seed " << seed << " never reached 1e-8";
    EXPECT_LT(evals, 2500) << "seed " << seed;
  }
}

TEST(Cmaes, LearnsAnIllConditionedEllipsoid) {
  // Condition number 1e6: an isotropic search would need orders of
  // magnitude more evaluations than on the sphere.
  const testing::Objective ellipsoid = [](const std::vector<double>& x) {
    double f = 0;
    for (size_t i = 0; i < x.size(); ++i) {
      f += std::pow(1e6, static_cast<double>(i) / (x.size() - 1)) * std::pow(x[i] - 0.5, 2);
    }
    return f;
  };
  for (uint64_t seed : {1, 2}) {
    const int64_t evals = EvalsToTarget(ellipsoid, testing::Box(5, -5, 5), 1e-8, 20000, seed);
    EXPECT_GT(evals, 0) << "seed " << seed;
    EXPECT_LT(evals, 5000) << "seed " << seed;
  }
}

TEST(Cmaes, SolvesRosenbrock) {
  int solved = 0;
  for (uint64_t seed : {1, 2, 3, 4}) {
    if (EvalsToTarget(testing::Rosenbrock, testing::Box(5, -2, 2), 1e-8, 8000, seed) > 0) ++solved;
  }
  EXPECT_GE(solved, 3) << "CMA-ES solves 5-D Rosenbrock in most runs";
}

TEST(Cmaes, ReachesAnOptimumOnTheBoundary) {
  // Minimum at the corner x = (5, 5, 5) of the box, outside the sphere's
  // unconstrained optimum at 6.
  const testing::Objective f = [](const std::vector<double>& x) {
    double s = 0;
    for (double v : x) s += (v - 6) * (v - 6);
    return s;
  };
  CheckedOptimizer opt = MakeOptimizer("cmaes", {{"max_evals", 1500}}, testing::Box(3, -5, 5), 9);
  testing::RunOptimizer(opt, f, 100);
  ASSERT_TRUE(opt.Best().has_value());
  EXPECT_LT(opt.Best()->value, 3.0 + 1e-6) << "constrained minimum is 3 at the corner";
}

}  // namespace
}  // namespace calib::search
