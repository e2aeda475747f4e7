// The comparison statistics (optimizer_stats.h) against values computed by
// SciPy and NumPy (scripts/optimizer-stats-expected.py wrote
// optimizer_stats_expected.json beside this file), and their properties.

#include "calib/results/optimizer_stats.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace calib::optimizer_stats {
namespace {

nlohmann::json Expected() {
  const std::string path = std::string(CALIB_SOURCE_DIR) + "/tests/results/optimizer_stats_expected.json";
  std::ifstream in(path);
  EXPECT_TRUE(in) << "cannot open " << path;
  return nlohmann::json::parse(in);
}

// Relative agreement of two numbers (absolute near 0).
void ExpectNear(double expected, double actual, double rel, const std::string& what) {
  EXPECT_NEAR(actual, expected, rel * std::max(1.0, std::abs(expected))) << what;
}

TEST(OptimizerStats, RankSumTestAgreesWithScipyMannWhitneyu) {
  const nlohmann::json doc = Expected();
  ASSERT_GE(doc["rank_sum"].size(), 5u);
  for (const auto& c : doc["rank_sum"]) {
    const std::string name = c["name"];
    const auto x = c["x"].get<std::vector<double>>();
    const auto y = c["y"].get<std::vector<double>>();
    const RankSumTest t = MannWhitneyU(x, y);
    EXPECT_EQ(t.u, c["u"].get<double>()) << name << ": U of x";
    ExpectNear(c["p_value"].get<double>(), t.p_value, 1e-10, name + ": two-sided p");
    ExpectNear(c["z"].get<double>(), t.z, 1e-8, name + ": z");
    ExpectNear(c["a12"].get<double>(), t.a12, 1e-14, name + ": Vargha-Delaney A");
    EXPECT_DOUBLE_EQ(t.rank_biserial, 2.0 * t.a12 - 1.0) << name;
    // Swapping the samples: U -> n m - U, the same p.
    const RankSumTest s = MannWhitneyU(y, x);
    EXPECT_DOUBLE_EQ(s.u, static_cast<double>(x.size() * y.size()) - t.u) << name;
    EXPECT_DOUBLE_EQ(s.p_value, t.p_value) << name;
  }
}

TEST(OptimizerStats, RankSumTestOfAllTiedValuesIsNotSignificantAndEmptyIsNaN) {
  const std::vector<double> a{2.0, 2.0, 2.0}, b{2.0, 2.0};
  const RankSumTest t = MannWhitneyU(a, b);
  EXPECT_EQ(t.p_value, 1.0);
  EXPECT_EQ(t.a12, 0.5);
  const std::vector<double> none;
  EXPECT_TRUE(std::isnan(MannWhitneyU(a, none).p_value));
  // NaN (a run with no finished evaluation) is left out.
  const std::vector<double> with_nan{1.0, std::numeric_limits<double>::quiet_NaN(), 3.0};
  EXPECT_EQ(MannWhitneyU(with_nan, b).u, MannWhitneyU(std::vector<double>{1.0, 3.0}, b).u);
}

TEST(OptimizerStats, QuantilesAgreeWithNumpyLinear) {
  const nlohmann::json doc = Expected();
  for (const auto& c : doc["quantiles"]) {
    const auto values = c["values"].get<std::vector<double>>();
    const auto qs = c["q"].get<std::vector<double>>();
    const auto expected = c["expected"].get<std::vector<double>>();
    for (size_t i = 0; i < qs.size(); ++i) {
      ExpectNear(expected[i], Quantile(values, qs[i]), 1e-14,
                 "q = " + std::to_string(qs[i]) + " of " + std::to_string(values.size()) + " values");
    }
  }
  EXPECT_TRUE(std::isnan(Quantile(std::vector<double>{}, 0.5)));
}

TEST(OptimizerStats, HolmAdjustmentAgreesWithItsDefinition) {
  const nlohmann::json doc = Expected();
  for (const auto& c : doc["holm"]) {
    const auto p = c["p"].get<std::vector<double>>();
    const auto expected = c["expected"].get<std::vector<double>>();
    const std::vector<double> adjusted = HolmAdjust(p);
    ASSERT_EQ(adjusted.size(), expected.size());
    for (size_t i = 0; i < p.size(); ++i) {
      ExpectNear(expected[i], adjusted[i], 1e-14, "p[" + std::to_string(i) + "] = " + std::to_string(p[i]));
      EXPECT_GE(adjusted[i], p[i]) << "never below the raw p";
    }
  }
}

TEST(OptimizerStats, ExpectedRunningTimeAgreesWithCocosDefinition) {
  const nlohmann::json doc = Expected();
  for (const auto& c : doc["ert"]) {
    std::vector<TargetRun> runs;
    for (const auto& r : c["runs"]) runs.push_back({r["evaluations"].get<int64_t>(), r["hit"].get<int64_t>()});
    const double ert = ExpectedRunningTime(runs);
    if (c["expected"].is_string()) {
      EXPECT_TRUE(std::isinf(ert)) << "no success: infinite, got " << ert;
    } else {
      ExpectNear(c["expected"].get<double>(), ert, 1e-14, c["runs"].dump());
    }
  }
  EXPECT_TRUE(std::isnan(ExpectedRunningTime(std::vector<TargetRun>{})));
}

TEST(OptimizerStats, BestSoFarSkipsFailuresAndTargetsCountEvaluations) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> scores{nan, 5.0, 7.0, nan, 3.0, 4.0};
  const std::vector<double> best = BestSoFar(scores);
  ASSERT_EQ(best.size(), scores.size());
  EXPECT_TRUE(std::isnan(best[0])) << "nothing finished yet";
  EXPECT_EQ(best[1], 5.0);
  EXPECT_EQ(best[2], 5.0);
  EXPECT_EQ(best[3], 5.0);
  EXPECT_EQ(best[4], 3.0);
  EXPECT_EQ(best[5], 3.0);
  EXPECT_EQ(EvaluationsToTarget(best, 5.0), 2);
  EXPECT_EQ(EvaluationsToTarget(best, 3.5), 5);
  EXPECT_EQ(EvaluationsToTarget(best, 1.0), -1);
  const std::vector<int64_t> hits{2, 5, -1, 10};
  EXPECT_EQ(FractionReached(hits, 1), 0.0);
  EXPECT_EQ(FractionReached(hits, 5), 0.5);
  EXPECT_EQ(FractionReached(hits, 100), 0.75);
}

}  // namespace
}  // namespace calib::optimizer_stats
