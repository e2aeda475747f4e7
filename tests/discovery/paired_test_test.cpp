// The statistics of the keep rule: the Benjamini-Hochberg step-up on known
// cases, the automatic block length (short for white noise, long for a
// slowly varying series), the paired block sign-flip test's size under the
// null (white and autocorrelated differences), its power, determinism, and
// one test per kind of bad input naming the culprit; the keep rule's drop
// test beyond a relevant share.

#include "calib/discovery/paired_test.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {
namespace {

// n values of an AR(1) process x_t = phi x_{t-1} + e_t (unit innovations)
// plus `mean`.
std::vector<double> Ar1(int n, double phi, double mean, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<double> x(n);
  double state = normal(rng) / std::sqrt(1.0 - phi * phi);
  for (int i = 0; i < n; ++i) {
    state = phi * state + normal(rng);
    x[i] = state + mean;
  }
  return x;
}

std::string MessageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(BenjaminiHochberg, RejectsUpToTheLargestRankUnderItsLine) {
  // Sorted: 0.005 <= 0.0125, 0.01 <= 0.025, 0.03 <= 0.0375, 0.5 > 0.05.
  EXPECT_EQ(BenjaminiHochberg({0.01, 0.5, 0.03, 0.005}, 0.05),
            (std::vector<bool>{true, false, true, true}));
  // Step-up: 0.04 is above its own line 0.025, but 0.041 <= 0.05 at rank 2
  // rejects both.
  EXPECT_EQ(BenjaminiHochberg({0.04, 0.041}, 0.05), (std::vector<bool>{true, true}));
  // Nothing under the line.
  EXPECT_EQ(BenjaminiHochberg({0.03, 0.2, 0.9}, 0.05), (std::vector<bool>{false, false, false}));
  // One hypothesis: the plain level.
  EXPECT_EQ(BenjaminiHochberg({0.05}, 0.05), (std::vector<bool>{true}));
  EXPECT_EQ(BenjaminiHochberg({0.0501}, 0.05), (std::vector<bool>{false}));
  EXPECT_TRUE(BenjaminiHochberg({}, 0.05).empty());
}

TEST(BenjaminiHochberg, BadInputIsNamed) {
  EXPECT_NE(MessageOf([] { BenjaminiHochberg({0.1}, 0.0); }).find("false-discovery rate 0"),
            std::string::npos);
  EXPECT_NE(MessageOf([] { BenjaminiHochberg({0.1, 1.5}, 0.05); }).find("p-value 1 = 1.5"),
            std::string::npos);
  EXPECT_NE(MessageOf([] { BenjaminiHochberg({NAN}, 0.05); }).find("p-value 0"), std::string::npos);
}

TEST(AutomaticBlockLength, ShortForWhiteNoiseLongForASlowSeries) {
  const std::vector<double> white = Ar1(330, 0.0, 0.0, 3);
  const std::vector<double> slow = Ar1(330, 0.95, 0.0, 3);
  EXPECT_LE(AutomaticBlockLength(white), 3);
  EXPECT_GE(AutomaticBlockLength(slow), 8);
  EXPECT_LE(AutomaticBlockLength(slow), 55);  // min(3 sqrt(330), 330 / 3)
  EXPECT_EQ(AutomaticBlockLength(std::vector<double>(100, 2.0)), 1);
  EXPECT_EQ(AutomaticBlockLength(std::vector<double>{1, 2, 3}), 1);
}

// The share of series under the null (mean 0) whose p-value is <= 0.05.
double RejectionRate(double phi, int series) {
  int rejected = 0;
  for (int s = 0; s < series; ++s) {
    PairedTestOptions options;
    options.resamples = 499;
    options.seed = 100 + s;
    const PairedTestResult r = PairedBlockTest({Ar1(330, phi, 0.0, 1000 + s)}, options);
    if (r.p_value <= 0.05) ++rejected;
  }
  return static_cast<double>(rejected) / series;
}

TEST(PairedBlockTest, HoldsItsLevelUnderTheNull) {
  // 300 series: a rate of 5 % has a standard error of 1.3 %.
  EXPECT_LE(RejectionRate(0.0, 300), 0.09);
  // Strongly autocorrelated differences (as a push's frames are): blocks
  // keep the level near its nominal value (measured: 4.3 %) where flipping
  // single frames rejects several times too often.
  EXPECT_LE(RejectionRate(0.9, 300), 0.08);
}

TEST(PairedBlockTest, FindsAClearDropAndBracketsIt) {
  PairedTestOptions options;
  options.resamples = 999;
  const std::vector<double> d = Ar1(330, 0.5, 0.5, 7);
  const PairedTestResult r = PairedBlockTest({d}, options);
  EXPECT_LE(r.p_value, 0.002);
  EXPECT_EQ(r.frames, 330);
  double total = 0.0;
  for (double v : d) total += v;
  EXPECT_DOUBLE_EQ(r.total, total);
  EXPECT_LT(r.total_low, r.total);
  EXPECT_GT(r.total_high, r.total);
  EXPECT_GT(r.total_low, 0.0);
  // A drop of the same size the other way is no drop at all.
  std::vector<double> worse = d;
  for (double& v : worse) v = -v;
  EXPECT_GE(PairedBlockTest({worse}, options).p_value, 0.99);
}

// The keep rule's form: a consistent drop too small to matter (0.5 % of
// the error on every frame) is significant as a plain drop but not beyond a
// relevant share of 2 %; a 30 % drop is significant beyond it; the drop and
// its interval are reported as drops of the error, the share added back.
TEST(PairedDropTest, AsksForADropBeyondTheRelevantShare) {
  PairedTestOptions options;
  options.resamples = 999;
  std::vector<double> before(330), slightly(330), much(330);
  const std::vector<double> noise = Ar1(330, 0.5, 0.0, 3);
  for (int f = 0; f < 330; ++f) {
    before[f] = 1000.0 + 50.0 * std::sin(0.05 * f);
    slightly[f] = 0.995 * before[f];
    much[f] = 0.7 * before[f] + 5.0 * noise[f];
  }
  EXPECT_LE(PairedDropTest({before}, {slightly}, 0.0, options).p_value, 0.01);
  EXPECT_GE(PairedDropTest({before}, {slightly}, 0.02, options).p_value, 0.99);
  const PairedTestResult r = PairedDropTest({before}, {much}, 0.02, options);
  EXPECT_LE(r.p_value, 0.01);
  double drop = 0.0;
  for (int f = 0; f < 330; ++f) drop += before[f] - much[f];
  EXPECT_NEAR(r.total, drop, 1e-6 * drop);
  EXPECT_LT(r.total_low, drop);
  EXPECT_GT(r.total_high, drop);
}

TEST(PairedDropTest, BadInputIsNamed) {
  EXPECT_NE(MessageOf([] { PairedDropTest({{1.0}}, {{1.0}}, 1.5, {}); }).find("1.5"),
            std::string::npos);
  EXPECT_NE(MessageOf([] { PairedDropTest({{1.0}, {2.0}}, {{1.0}}, 0.02, {}); })
                .find("2 recordings before, 1 after"),
            std::string::npos);
  EXPECT_NE(MessageOf([] { PairedDropTest({{1.0, 2.0}}, {{1.0}}, 0.02, {}); })
                .find("recording 0: 2 frames before, 1 after"),
            std::string::npos);
}

TEST(PairedBlockTest, IsDeterministicAndDrawsWithinEachRecording) {
  PairedTestOptions options;
  options.resamples = 999;
  options.seed = 5;
  const std::vector<std::vector<double>> d = {Ar1(200, 0.8, 0.1, 1), Ar1(120, 0.2, 0.05, 2)};
  const PairedTestResult a = PairedBlockTest(d, options);
  const PairedTestResult b = PairedBlockTest(d, options);
  EXPECT_EQ(a.p_value, b.p_value);
  EXPECT_EQ(a.total_low, b.total_low);
  ASSERT_EQ(a.block_lengths.size(), 2u);
  EXPECT_EQ(a.block_lengths[0], TestBlockLength(d[0]));
  EXPECT_EQ(a.block_lengths[1], TestBlockLength(d[1]));
  EXPECT_LE(a.block_lengths[0], 20);  // at least 10 blocks
  EXPECT_LE(a.block_lengths[1], 12);
  EXPECT_EQ(a.frames, 320);
}

TEST(PairedBlockTest, IdenticalModelsGiveNoEvidence) {
  const PairedTestResult r = PairedBlockTest({std::vector<double>(50, 0.0)}, {});
  EXPECT_EQ(r.p_value, 1.0);
  EXPECT_EQ(r.total, 0.0);
}

TEST(PairedBlockTest, BadInputIsNamed) {
  EXPECT_NE(MessageOf([] { PairedBlockTest({{1.0, 2.0}, {0.5, INFINITY}}, {}); })
                .find("recording 1 frame 1"),
            std::string::npos);
  EXPECT_NE(MessageOf([] { PairedBlockTest({{}, {}}, {}); }).find("no frames"),
            std::string::npos);
  PairedTestOptions none;
  none.resamples = 0;
  EXPECT_NE(MessageOf([&] { PairedBlockTest({{1.0}}, none); }).find("resamples = 0"),
            std::string::npos);
}

}  // namespace
}  // namespace calib
