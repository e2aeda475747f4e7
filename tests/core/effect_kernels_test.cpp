// The effect kernels of effect_kernels.h: forces against central differences
// of their energies at random configurations and at coordinate scales 1e-3,
// 1 and 1e3; zero force at rest; invariance under rigid motion; the rules of
// the effects without an energy (Coulomb friction on the step, the push's
// friction balance).

#include "calib/core/effect_kernels.h"
#include "support/force_check.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>

namespace calib {
namespace {

using calib::testing::RandomPoints;
using calib::testing::Term;
using calib::testing::WorstForceError;

class EffectKernelScale : public ::testing::TestWithParam<double> {};

TEST_P(EffectKernelScale, QuarticDistanceForceIsNegativeGradient) {
  const double scale = GetParam();
  std::mt19937_64 rng(21);
  for (int trial = 0; trial < 50; ++trial) {
    const auto p = RandomPoints<2>(rng, scale);
    const double rest = scale * (0.3 + 0.02 * trial);
    const Term<2> term = [&](const std::array<Vec2, 2>& q, std::array<Vec2, 2>& f) {
      return QuarticDistanceEnergy(q[0], q[1], rest, 4.2, f[0], f[1]);
    };
    EXPECT_LT(WorstForceError<2>(term, p, scale, 1e-300), 1e-6) << "trial " << trial << " scale " << scale;
  }
}

TEST_P(EffectKernelScale, RestShiftForceIsNegativeGradient) {
  const double scale = GetParam();
  std::mt19937_64 rng(22);
  std::uniform_real_distribution<double> u(0.2, 2.0);
  for (int trial = 0; trial < 50; ++trial) {
    const auto p = RandomPoints<2>(rng, scale);
    const double from = scale * u(rng), to = scale * u(rng);
    const Term<2> term = [&](const std::array<Vec2, 2>& q, std::array<Vec2, 2>& f) {
      return DistanceRestShiftEnergy(q[0], q[1], from, to, 3.1, f[0], f[1]);
    };
    EXPECT_LT(WorstForceError<2>(term, p, scale, 1e-300), 1e-6) << "trial " << trial << " scale " << scale;
  }
}

TEST_P(EffectKernelScale, BodyForceIsNegativeGradient) {
  const double scale = GetParam();
  std::mt19937_64 rng(23);
  for (int trial = 0; trial < 20; ++trial) {
    const auto p = RandomPoints<1>(rng, scale);
    const Vec2 g = RandomPoints<1>(rng, 1.0)[0];
    const Term<1> term = [&](const std::array<Vec2, 1>& q, std::array<Vec2, 1>& f) {
      return BodyForceEnergy(q[0], g, f[0]);
    };
    EXPECT_LT(WorstForceError<1>(term, p, scale, 1e-300), 1e-6) << "trial " << trial;
  }
}

INSTANTIATE_TEST_SUITE_P(Scales, EffectKernelScale, ::testing::Values(1e-3, 1.0, 1e3));

TEST(EffectKernels, RestShiftIsTheDifferenceOfTwoDistanceSprings) {
  std::mt19937_64 rng(24);
  for (int trial = 0; trial < 20; ++trial) {
    const auto p = RandomPoints<2>(rng, 10.0);
    Vec2 fi = Vec2::Zero(), fj = Vec2::Zero(), gi = Vec2::Zero(), gj = Vec2::Zero();
    const double shift = DistanceRestShiftEnergy(p[0], p[1], 7.0, 9.5, 2.0, fi, fj);
    double reference = DistanceEnergy(p[0], p[1], 9.5, 2.0, gi, gj);
    reference += DistanceEnergy(p[0], p[1], 7.0, -2.0, gi, gj);
    EXPECT_NEAR(shift, reference, 1e-12 * (1.0 + std::abs(reference))) << "trial " << trial;
    EXPECT_LT((fi - gi).norm(), 1e-12 * (1.0 + gi.norm())) << "trial " << trial;
    EXPECT_LT((fj - gj).norm(), 1e-12 * (1.0 + gj.norm())) << "trial " << trial;
  }
  // No shift, no force.
  Vec2 fi = Vec2::Zero(), fj = Vec2::Zero();
  EXPECT_EQ(DistanceRestShiftEnergy(Vec2(0, 0), Vec2(3, 4), 4.0, 4.0, 5.0, fi, fj), 0.0);
  EXPECT_EQ(fi, Vec2::Zero());
}

TEST(EffectKernels, QuarticSpringIsFlatAtRestAndInvariantUnderRigidMotion) {
  Vec2 fi = Vec2::Zero(), fj = Vec2::Zero();
  EXPECT_EQ(QuarticDistanceEnergy(Vec2(1, 2), Vec2(4, 6), 5.0, 10.0, fi, fj), 0.0);
  EXPECT_EQ(fi.norm(), 0.0);
  const Vec2 a(0.3, -1.2), b(4.1, 2.2);
  const double c = std::cos(0.7), s = std::sin(0.7);
  const auto move = [&](const Vec2& p) {
    return Vec2(c * p.x() - s * p.y() + 9, s * p.x() + c * p.y() - 3);
  };
  const double e = QuarticDistanceEnergy(a, b, 3.0, 2.0, fi, fj);
  EXPECT_NEAR(QuarticDistanceEnergy(move(a), move(b), 3.0, 2.0, fi, fj), e, 1e-12 * e);
  // Its force grows as the cube of the strain: 8x for twice the strain.
  Vec2 f1i = Vec2::Zero(), f1j = Vec2::Zero(), f2i = Vec2::Zero(), f2j = Vec2::Zero();
  QuarticDistanceEnergy(Vec2(0, 0), Vec2(11, 0), 10.0, 1.0, f1i, f1j);
  QuarticDistanceEnergy(Vec2(0, 0), Vec2(12, 0), 10.0, 1.0, f2i, f2j);
  EXPECT_NEAR(f2j.norm() / f1j.norm(), 8.0, 1e-9);
}

TEST(EffectKernels, TriangleAngleDeviationsAreThoseOfTheAngleEnergy) {
  std::mt19937_64 rng(25);
  for (int trial = 0; trial < 50; ++trial) {
    auto t = RandomPoints<3>(rng, 5.0);
    if (SignedArea(t[0], t[1], t[2]) < 0) std::swap(t[1], t[2]);
    std::array<double, 6> cs;
    for (int k = 0; k < 3; ++k) {
      const Vec2 e1 = t[(k + 1) % 3] - t[k], e2 = t[(k + 2) % 3] - t[k];
      const double phi = std::atan2(Cross(e1, e2), e1.dot(e2));
      cs[2 * k] = std::cos(phi);
      cs[2 * k + 1] = std::sin(phi);
    }
    const auto p = RandomPoints<3>(rng, 5.0);
    std::array<double, 3> d;
    ASSERT_TRUE(TriangleAngleDeviations(p[0], p[1], p[2], cs, d));
    std::array<Vec2, 3> f = {Vec2::Zero(), Vec2::Zero(), Vec2::Zero()};
    const double energy = TriangleAngleEnergy(p[0], p[1], p[2], cs, 2.0, f[0], f[1], f[2]);
    EXPECT_NEAR(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], energy, 1e-9 * (1.0 + energy));
    for (double dk : d) {
      EXPECT_GT(dk, -std::numbers::pi);
      EXPECT_LE(dk, std::numbers::pi);
    }
  }
  std::array<double, 3> d;
  EXPECT_FALSE(TriangleAngleDeviations(Vec2(1, 1), Vec2(1, 1), Vec2(2, 3), {1, 0, 1, 0, -1, 0}, d));
}

TEST(EffectKernels, CoulombStepOnlyShortensTheStepOrHoldsTheNode) {
  std::mt19937_64 rng(26);
  std::uniform_real_distribution<double> u(-2.0, 2.0), slip(0.0, 3.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec2 start(u(rng), u(rng));
    const Vec2 moved = start + Vec2(u(rng), u(rng));
    const double max_slip = slip(rng);
    Vec2 x = moved;
    const double taken = CoulombLimitStep(start, x, max_slip);
    const Vec2 before = moved - start, after = x - start;
    EXPECT_LE(after.norm(), before.norm() + 1e-15) << "trial " << trial;
    EXPECT_GE(after.dot(before), 0.0) << "friction reversed the step, trial " << trial;
    if (before.norm() <= max_slip) {
      EXPECT_EQ(x, start) << "a step shorter than the limit sticks, trial " << trial;
    } else {
      EXPECT_NEAR(after.norm(), before.norm() - max_slip, 1e-12) << "trial " << trial;
      EXPECT_NEAR(taken, max_slip, 1e-15);
    }
  }
}

TEST(EffectKernels, PushBalanceMovesTheBodyOnlyBeyondFriction) {
  const Vec2 push(3.0, 4.0);  // |P| = 5
  // No friction: the base model's split.
  PushSplit base = FrictionBalancedPush(push, 0.3, 0.0);
  EXPECT_EQ(base.node_force, (1.0 - 0.3) * push);
  EXPECT_EQ(base.spread_total, 0.3 * push);
  // Net external force is max(0, |P| - F_c) along P.
  for (double friction : {0.0, 1.0, 4.99, 5.0, 7.0}) {
    for (double tau : {0.0, 0.4, 1.0}) {
      const PushSplit split = FrictionBalancedPush(push, tau, friction);
      const Vec2 net = split.node_force + split.spread_total;
      const Vec2 expected = std::max(0.0, 5.0 - friction) / 5.0 * push;
      EXPECT_LT((net - expected).norm(), 1e-12) << "F_c " << friction << " tau " << tau;
      EXPECT_LT((split.node_force - (1.0 - tau) * push).norm(), 1e-15);
    }
  }
  const PushSplit none = FrictionBalancedPush(Vec2::Zero(), 0.5, 2.0);
  EXPECT_EQ(none.node_force, Vec2::Zero());
  EXPECT_EQ(none.spread_total, Vec2::Zero());
}

}  // namespace
}  // namespace calib
