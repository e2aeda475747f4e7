// The loop benchmark's statistics: Wilson score intervals against published
// values, type-7 quartiles against known cases, and confusion counting.

#include "calib/discovery/benchmark_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace calib {
namespace {

constexpr double kFourDigits = 5e-5;

void ExpectInterval(int64_t k, int64_t n, double lower, double upper) {
  const Proportion p = WilsonInterval(k, n);
  EXPECT_EQ(p.successes, k);
  EXPECT_EQ(p.trials, n);
  EXPECT_DOUBLE_EQ(p.rate, static_cast<double>(k) / n) << k << "/" << n;
  EXPECT_NEAR(p.lower, lower, kFourDigits) << k << "/" << n;
  EXPECT_NEAR(p.upper, upper, kFourDigits) << k << "/" << n;
}

// Newcombe (1998), "Two-sided confidence intervals for the single
// proportion", Statistics in Medicine 17, Table II, method 3 (Wilson score).
TEST(WilsonInterval, MatchesNewcombesPublishedIntervals) {
  ExpectInterval(81, 263, 0.2553, 0.3662);
  ExpectInterval(15, 148, 0.0624, 0.1605);
  ExpectInterval(0, 20, 0.0, 0.1611);
  ExpectInterval(1, 29, 0.0061, 0.1718);
  ExpectInterval(29, 29, 0.8830, 1.0);
}

// The test cases of "Compute the Wilson score interval" (Code Golf Stack
// Exchange, question 105389), with z = 1.96: successes, failures => bounds.
TEST(WilsonInterval, MatchesPublishedFullPrecisionCasesAtZ196) {
  struct Case {
    int64_t successes, failures;
    double lower, upper;
  };
  const Case cases[] = {{0, 1, 0.0, 0.7934567085261071},
                        {1, 10, 0.016231752262825982, 0.3773646254862038},
                        {10, 90, 0.05522854161313612, 0.1743673043676654},
                        {75, 25, 0.6569535362992417, 0.8245490599627573},
                        {100, 0, 0.9630051925239981, 1.0}};
  for (const Case& c : cases) {
    const Proportion p = WilsonInterval(c.successes, c.successes + c.failures, 1.96);
    EXPECT_NEAR(p.lower, c.lower, 1e-12) << c.successes << ", " << c.failures;
    EXPECT_NEAR(p.upper, c.upper, 1e-12) << c.successes << ", " << c.failures;
  }
}

// 5 of 6: 0.4365 to 0.9699. Each bound pi solves the score equation
// (p - pi)^2 = z^2 pi (1 - pi) / n that defines the interval.
TEST(WilsonInterval, FiveOfSixBoundsSolveTheScoreEquation) {
  const Proportion p = WilsonInterval(5, 6);
  EXPECT_NEAR(p.lower, 0.4365, 5e-5);
  EXPECT_NEAR(p.upper, 0.9699, 5e-5);
  for (const double pi : {p.lower, p.upper}) {
    EXPECT_NEAR((5.0 / 6.0 - pi) * (5.0 / 6.0 - pi), kZ95 * kZ95 * pi * (1.0 - pi) / 6.0, 1e-14)
        << pi;
  }
}

TEST(WilsonInterval, IsSymmetricBetweenSuccessesAndFailures) {
  const Proportion a = WilsonInterval(3, 11);
  const Proportion b = WilsonInterval(8, 11);
  EXPECT_NEAR(a.lower, 1.0 - b.upper, 1e-12);
  EXPECT_NEAR(a.upper, 1.0 - b.lower, 1e-12);
}

TEST(WilsonInterval, NoTrialsKnowsNothing) {
  const Proportion p = WilsonInterval(0, 0);
  EXPECT_TRUE(std::isnan(p.rate));
  EXPECT_EQ(p.lower, 0.0);
  EXPECT_EQ(p.upper, 1.0);
}

TEST(WilsonInterval, ImpossibleCountsAreRejected) {
  EXPECT_THROW(WilsonInterval(3, 2), std::invalid_argument);
  EXPECT_THROW(WilsonInterval(-1, 2), std::invalid_argument);
  EXPECT_THROW(WilsonInterval(1, 2, 0.0), std::invalid_argument);
}

// numpy.percentile([1, 2, 3, 4], [25, 50, 75]) = 1.75, 2.5, 3.25.
TEST(QuartilesOf, InterpolatesBetweenOrderStatisticsAsRAndNumpy) {
  const Quartiles q = QuartilesOf({4.0, 1.0, 3.0, 2.0});
  EXPECT_EQ(q.count, 4);
  EXPECT_DOUBLE_EQ(q.min, 1.0);
  EXPECT_DOUBLE_EQ(q.q1, 1.75);
  EXPECT_DOUBLE_EQ(q.median, 2.5);
  EXPECT_DOUBLE_EQ(q.q3, 3.25);
  EXPECT_DOUBLE_EQ(q.max, 4.0);
  // R: quantile(c(-0.7, -0.1, 0.05, 0.2, 0.9)) = -0.7 -0.1 0.05 0.2 0.9.
  const Quartiles odd = QuartilesOf({0.2, -0.7, 0.9, 0.05, -0.1});
  EXPECT_DOUBLE_EQ(odd.q1, -0.1);
  EXPECT_DOUBLE_EQ(odd.median, 0.05);
  EXPECT_DOUBLE_EQ(odd.q3, 0.2);
}

TEST(QuartilesOf, LeavesOutNaNAndIsNaNWhenEmpty) {
  const Quartiles one = QuartilesOf({NAN, 7.0, NAN});
  EXPECT_EQ(one.count, 1);
  EXPECT_DOUBLE_EQ(one.q1, 7.0);
  EXPECT_DOUBLE_EQ(one.median, 7.0);
  EXPECT_DOUBLE_EQ(one.q3, 7.0);
  const Quartiles none = QuartilesOf({});
  EXPECT_EQ(none.count, 0);
  EXPECT_TRUE(std::isnan(none.median));
  EXPECT_TRUE(std::isnan(none.q1));
}

TEST(CountConfusion, CountsEachKeptEffectAndNothingPerEffectPresent) {
  const std::vector<std::string> effects = {"plasticity", "table_friction"};
  const ConfusionTable t =
      CountConfusion(effects, {
                                  {"plasticity", {"plasticity"}},
                                  {"plasticity", {}},
                                  {"plasticity", {"table_friction"}},
                                  {"table_friction", {"plasticity", "table_friction"}},
                                  {"", {}},
                                  {"", {"viscoelastic"}},
                              });
  EXPECT_EQ(t.rows,
            (std::vector<std::string>{"plasticity", "table_friction", "viscoelastic", "none"}));
  EXPECT_EQ(t.columns,
            (std::vector<std::string>{"plasticity", "table_friction", "viscoelastic", "nothing"}));
  EXPECT_EQ(t.At("plasticity", "plasticity"), 1);
  EXPECT_EQ(t.At("plasticity", "nothing"), 1);
  EXPECT_EQ(t.At("plasticity", "table_friction"), 1);
  EXPECT_EQ(t.At("table_friction", "plasticity"), 1);
  EXPECT_EQ(t.At("table_friction", "table_friction"), 1);
  EXPECT_EQ(t.At("none", "nothing"), 1);
  EXPECT_EQ(t.At("none", "viscoelastic"), 1);
  EXPECT_EQ(t.At("viscoelastic", "nothing"), 0);
  EXPECT_EQ(t.At("unknown", "nothing"), 0);
  EXPECT_EQ(t.row_objects, (std::vector<int64_t>{3, 1, 0, 2}));
  int64_t total = 0;
  for (const auto& row : t.counts) {
    for (int64_t c : row) total += c;
  }
  EXPECT_EQ(total, 7);  // six objects, one of which kept two effects
}

}  // namespace
}  // namespace calib
