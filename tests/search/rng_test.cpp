#include "calib/search/rng.h"

#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

namespace calib::search {
namespace {

TEST(Rng, SplitMix64MatchesTheReferenceSequence) {
  // Reference values of splitmix64 from seed 0 (Vigna's splitmix64.c).
  uint64_t state = 0;
  EXPECT_EQ(SplitMix64(state), 0xe220a8397b1dcdafULL);
  EXPECT_EQ(SplitMix64(state), 0x6e789e6aa1b965f4ULL);
  EXPECT_EQ(SplitMix64(state), 0x06c45d188009454fULL);
}

TEST(Rng, SameSeedSameNumbersDifferentSeedDifferent) {
  Rng a(42), b(42), c(43);
  for (int i = 0; i < 100; ++i) {
    const uint64_t va = a.NextU64();
    EXPECT_EQ(va, b.NextU64()) << "draw " << i;
    EXPECT_NE(va, c.NextU64()) << "draw " << i;
  }
}

TEST(Rng, UniformIsInRangeWithTheRightMoments) {
  Rng rng(7);
  double sum = 0, sum2 = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double u = rng.Uniform01();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    sum += u;
    sum2 += u * u;
  }
  EXPECT_NEAR(sum / n, 0.5, 0.005);
  EXPECT_NEAR(sum2 / n - 0.25, 1.0 / 12, 0.003);
  for (int i = 0; i < 1000; ++i) {
    const uint64_t k = rng.UniformInt(7);
    ASSERT_LT(k, 7u);
  }
}

TEST(Rng, NormalHasZeroMeanUnitVarianceAndLightTails) {
  Rng rng(11);
  double sum = 0, sum2 = 0, sum4 = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double z = rng.Normal();
    sum += z;
    sum2 += z * z;
    sum4 += z * z * z * z;
  }
  EXPECT_NEAR(sum / n, 0.0, 0.01);
  EXPECT_NEAR(sum2 / n, 1.0, 0.015);
  EXPECT_NEAR(sum4 / n, 3.0, 0.1) << "fourth moment of N(0,1) is 3";
}

TEST(Rng, SaveRestoreContinuesExactlyIncludingTheSpareNormal) {
  Rng rng(99);
  rng.Normal();  // leaves a spare
  const std::string saved = rng.Save().dump();
  Rng restored(0);
  restored.Restore(nlohmann::json::parse(saved));
  EXPECT_TRUE(restored == rng);
  for (int i = 0; i < 50; ++i) {
    const double a = rng.Normal(), b = restored.Normal();
    EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "normal " << i;
    EXPECT_EQ(rng.NextU64(), restored.NextU64()) << "draw " << i;
  }
}

TEST(Rng, RestoreRejectsForeignJsonByName) {
  Rng rng;
  try {
    rng.Restore(nlohmann::json{{"state", 1}});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("xoshiro256"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace calib::search
