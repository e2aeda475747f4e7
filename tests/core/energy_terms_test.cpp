// Forces of every energy term against central differences of its energy, at
// random and nearly degenerate configurations and at coordinate scales 1e-3,
// 1 and 1e3; zero force at rest; invariance under rigid motion; damping never
// adds energy.

#include "calib/core/energy_terms.h"
#include "calib/core/mesh.h"
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

class EnergyTermScale : public ::testing::TestWithParam<double> {};

TEST_P(EnergyTermScale, DistanceForceIsNegativeGradient) {
  const double scale = GetParam();
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 50; ++trial) {
    const auto p = RandomPoints<2>(rng, scale);
    const double rest = scale * (0.2 + 0.01 * trial);
    const Term<2> term = [&](const std::array<Vec2, 2>& q, std::array<Vec2, 2>& f) {
      return DistanceEnergy(q[0], q[1], rest, 3.7, f[0], f[1]);
    };
    const double err = WorstForceError<2>(term, p, scale);
    EXPECT_LT(err, 1e-6) << "trial " << trial << " scale " << scale;
  }
}

TEST_P(EnergyTermScale, AreaForceIsNegativeGradient) {
  const double scale = GetParam();
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 50; ++trial) {
    const auto p = RandomPoints<3>(rng, scale);
    const double rest = scale * scale * 0.3;
    const Term<3> term = [&](const std::array<Vec2, 3>& q, std::array<Vec2, 3>& f) {
      return AreaEnergy(q[0], q[1], q[2], rest, 2.5, f[0], f[1], f[2]);
    };
    const double err = WorstForceError<3>(term, p, scale);
    EXPECT_LT(err, 1e-6) << "trial " << trial << " scale " << scale;
  }
}

TEST_P(EnergyTermScale, AngleForceIsNegativeGradient) {
  const double scale = GetParam();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> angle(0.2, 2.8);
  for (int trial = 0; trial < 50; ++trial) {
    const auto p = RandomPoints<3>(rng, scale);
    const double phi0 = angle(rng);
    const Term<3> term = [&](const std::array<Vec2, 3>& q, std::array<Vec2, 3>& f) {
      return AngleEnergy(q[0], q[1], q[2], std::cos(phi0), std::sin(phi0), 1.3, f[0], f[1], f[2]);
    };
    // Skip configurations right at the branch cut phi - phi0 = pi, where the
    // wrapped energy has a kink by construction.
    const Vec2 e1 = p[2] - p[1], e2 = p[0] - p[1];
    const double phi = std::atan2(Cross(e1, e2), e1.dot(e2));
    const double delta = std::remainder(phi - phi0, 2.0 * std::numbers::pi);
    if (std::abs(std::abs(delta) - std::numbers::pi) < 1e-3) continue;
    const double err = WorstForceError<3>(term, p, scale);
    EXPECT_LT(err, 1e-5) << "trial " << trial << " scale " << scale;
  }
}

TEST_P(EnergyTermScale, NearlyDegenerateTrianglesStillHaveExactForces) {
  const double scale = GetParam();
  // A sliver: the third node almost on the line of the first two.
  const std::array<Vec2, 3> p = {scale * Vec2(0, 0), scale * Vec2(1, 0), scale * Vec2(0.5, 1e-4)};
  const Term<3> area = [&](const std::array<Vec2, 3>& q, std::array<Vec2, 3>& f) {
    return AreaEnergy(q[0], q[1], q[2], 0.4 * scale * scale, 1.0, f[0], f[1], f[2]);
  };
  const Term<3> angle = [&](const std::array<Vec2, 3>& q, std::array<Vec2, 3>& f) {
    const double phi0 = std::numbers::pi / 3;
    return AngleEnergy(q[0], q[1], q[2], std::cos(phi0), std::sin(phi0), 1.0, f[0], f[1], f[2]);
  };
  EXPECT_LT(WorstForceError<3>(area, p, scale), 1e-6);
  EXPECT_LT(WorstForceError<3>(angle, p, scale * 1e-3), 1e-4);
  // A very short spring.
  const std::array<Vec2, 2> q = {scale * Vec2(0, 0), scale * Vec2(1e-3, 2e-3)};
  const Term<2> dist = [&](const std::array<Vec2, 2>& r, std::array<Vec2, 2>& f) {
    return DistanceEnergy(r[0], r[1], scale, 1.0, f[0], f[1]);
  };
  EXPECT_LT(WorstForceError<2>(dist, q, scale * 1e-3), 1e-6);
}

// Rest angles of a random positive triangle: cos and sin of its corners.
std::array<double, 6> RestCosSin(const std::array<Vec2, 3>& t) {
  std::array<double, 6> cs;
  for (int k = 0; k < 3; ++k) {
    const Vec2 e1 = t[(k + 1) % 3] - t[k], e2 = t[(k + 2) % 3] - t[k];
    const double phi = std::atan2(Cross(e1, e2), e1.dot(e2));
    cs[2 * k] = std::cos(phi);
    cs[2 * k + 1] = std::sin(phi);
  }
  return cs;
}

std::array<Vec2, 3> PositiveTriangle(std::mt19937_64& rng, double scale) {
  for (;;) {
    auto t = RandomPoints<3>(rng, scale);
    const double area = SignedArea(t[0], t[1], t[2]);
    if (std::abs(area) < 0.05 * scale * scale) continue;
    if (area < 0) std::swap(t[1], t[2]);
    return t;
  }
}

TEST_P(EnergyTermScale, TriangleAngleKernelEqualsThreeCornerKernels) {
  const double scale = GetParam();
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 100; ++trial) {
    const auto cs = RestCosSin(PositiveTriangle(rng, scale));
    // Deformed configurations, some of them inverted.
    const auto p = RandomPoints<3>(rng, scale);
    std::array<Vec2, 3> fused, corners;
    for (int i = 0; i < 3; ++i) fused[i].setZero(), corners[i].setZero();
    const double e_fused =
        TriangleAngleEnergy(p[0], p[1], p[2], cs, 1.7, fused[0], fused[1], fused[2]);
    double e_corners = 0.0;
    e_corners += AngleEnergy(p[2], p[0], p[1], cs[0], cs[1], 1.7, corners[2], corners[0], corners[1]);
    e_corners += AngleEnergy(p[0], p[1], p[2], cs[2], cs[3], 1.7, corners[0], corners[1], corners[2]);
    e_corners += AngleEnergy(p[1], p[2], p[0], cs[4], cs[5], 1.7, corners[1], corners[2], corners[0]);
    EXPECT_NEAR(e_fused, e_corners, 1e-9 * (1.0 + e_corners)) << "trial " << trial;
    double max_f = 0.0;
    for (const Vec2& f : corners) max_f = std::max(max_f, f.norm());
    for (int i = 0; i < 3; ++i) {
      EXPECT_LT((fused[i] - corners[i]).norm(), 1e-8 * (max_f + 1e-300)) << "trial " << trial;
    }
  }
}

TEST_P(EnergyTermScale, TriangleAngleForceIsNegativeGradient) {
  const double scale = GetParam();
  std::mt19937_64 rng(8);
  for (int trial = 0; trial < 50; ++trial) {
    const auto cs = RestCosSin(PositiveTriangle(rng, scale));
    const auto p = RandomPoints<3>(rng, scale);
    if (std::abs(SignedArea(p[0], p[1], p[2])) < 1e-3 * scale * scale) continue;
    const Term<3> term = [&](const std::array<Vec2, 3>& q, std::array<Vec2, 3>& f) {
      return TriangleAngleEnergy(q[0], q[1], q[2], cs, 0.9, f[0], f[1], f[2]);
    };
    EXPECT_LT(WorstForceError<3>(term, p, scale), 1e-5) << "trial " << trial;
  }
}

TEST(EnergyTerms, SmallAngleSeriesAgreesWithAtan2AtTheSwitch) {
  // Deviations on both sides of the series' range (|tan| = 0.1) give the same
  // energy as the exact atan2 to rounding.
  for (double delta : {0.0999, 0.1, 0.1001, -0.0999669, -0.0996687, 1e-9, 0.05}) {
    const Vec2 p(0, 0), next(1, 0), prev(std::cos(1.0 + delta), std::sin(1.0 + delta));
    Vec2 f0 = Vec2::Zero(), f1 = Vec2::Zero(), f2 = Vec2::Zero();
    const double e = AngleEnergy(prev, p, next, std::cos(1.0), std::sin(1.0), 2.0, f0, f1, f2);
    EXPECT_NEAR(e, delta * delta, 1e-15) << delta;
  }
}

INSTANTIATE_TEST_SUITE_P(Scales, EnergyTermScale, ::testing::Values(1e-3, 1.0, 1e3));

TEST(EnergyTerms, ZeroForceAndEnergyAtRest) {
  const Vec2 a(0, 0), b(3, 0), c(1, 2);
  Vec2 fa = Vec2::Zero(), fb = Vec2::Zero(), fc = Vec2::Zero();
  EXPECT_DOUBLE_EQ(DistanceEnergy(a, b, 3.0, 5.0, fa, fb), 0.0);
  const double area = SignedArea(a, b, c);
  EXPECT_NEAR(AreaEnergy(a, b, c, area, 5.0, fa, fb, fc), 0.0, 1e-30);
  const Vec2 e1 = b - a, e2 = c - a;
  const double phi = std::atan2(Cross(e1, e2), e1.dot(e2));
  EXPECT_NEAR(AngleEnergy(c, a, b, std::cos(phi), std::sin(phi), 5.0, fc, fa, fb), 0.0, 1e-28);
  for (const Vec2& f : {fa, fb, fc}) EXPECT_LT(f.norm(), 1e-12) << f.transpose();
}

TEST(EnergyTerms, EnergyInvariantUnderRigidMotion) {
  std::mt19937_64 rng(4);
  const auto p = RandomPoints<3>(rng, 10.0);
  const double theta = 0.7;
  Eigen::Matrix2d rot;
  rot << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta);
  const Vec2 shift(123.4, -56.7);
  std::array<Vec2, 3> q;
  for (int i = 0; i < 3; ++i) q[i] = rot * p[i] + shift;
  Vec2 f[6];
  for (auto& f_i : f) f_i.setZero();
  EXPECT_NEAR(DistanceEnergy(p[0], p[1], 4.0, 2.0, f[0], f[1]),
              DistanceEnergy(q[0], q[1], 4.0, 2.0, f[3], f[4]), 1e-9);
  EXPECT_NEAR(AreaEnergy(p[0], p[1], p[2], 20.0, 2.0, f[0], f[1], f[2]),
              AreaEnergy(q[0], q[1], q[2], 20.0, 2.0, f[3], f[4], f[5]), 1e-9);
  EXPECT_NEAR(AngleEnergy(p[0], p[1], p[2], 0.5, std::sqrt(0.75), 2.0, f[0], f[1], f[2]),
              AngleEnergy(q[0], q[1], q[2], 0.5, std::sqrt(0.75), 2.0, f[3], f[4], f[5]), 1e-9);
}

TEST(EnergyTerms, InternalForcesSumToZeroAndHaveNoTorque) {
  std::mt19937_64 rng(5);
  const auto p = RandomPoints<3>(rng, 5.0);
  std::array<Vec2, 3> f;
  for (auto& fi : f) fi.setZero();
  AreaEnergy(p[0], p[1], p[2], 3.0, 2.0, f[0], f[1], f[2]);
  AngleEnergy(p[0], p[1], p[2], 0.3, std::sqrt(1 - 0.09), 2.0, f[0], f[1], f[2]);
  DistanceEnergy(p[0], p[2], 1.0, 2.0, f[0], f[2]);
  EXPECT_LT((f[0] + f[1] + f[2]).norm(), 1e-9);
  EXPECT_NEAR(Cross(p[0], f[0]) + Cross(p[1], f[1]) + Cross(p[2], f[2]), 0.0, 1e-9);
}

TEST(EnergyTerms, InvertedTriangleIsPushedBackToPositiveArea) {
  // c below the a-b line: negative signed area. The force on c points to the
  // positive side.
  const Vec2 a(0, 0), b(1, 0), c(0.5, -0.3);
  ASSERT_LT(SignedArea(a, b, c), 0.0);
  Vec2 fa = Vec2::Zero(), fb = Vec2::Zero(), fc = Vec2::Zero();
  AreaEnergy(a, b, c, 0.25, 1.0, fa, fb, fc);
  EXPECT_GT(fc.y(), 0.0);
  Vec2 ga = Vec2::Zero(), gb = Vec2::Zero(), gc = Vec2::Zero();
  // Rest corner at a is +60 degrees; the inverted corner is negative.
  AngleEnergy(c, a, b, 0.5, std::sqrt(0.75), 1.0, gc, ga, gb);
  EXPECT_GT(gc.y(), 0.0);
}

TEST(EnergyTerms, DampingNeverAddsEnergy) {
  std::mt19937_64 rng(6);
  for (int trial = 0; trial < 200; ++trial) {
    const auto p = RandomPoints<4>(rng, 3.0);  // two positions, two velocities
    Vec2 fi = Vec2::Zero(), fj = Vec2::Zero();
    DistanceDamping(p[0], p[1], p[2], p[3], 1.5, 0.8, fi, fj);
    const double power = fi.dot(p[2]) + fj.dot(p[3]);
    EXPECT_LE(power, 1e-15) << "trial " << trial;
    EXPECT_LT((fi + fj).norm(), 1e-12);
  }
  // Rigid translation: no damping force.
  Vec2 fi = Vec2::Zero(), fj = Vec2::Zero();
  DistanceDamping(Vec2(0, 0), Vec2(1, 1), Vec2(2, 3), Vec2(2, 3), 1.0, 5.0, fi, fj);
  EXPECT_LT(fi.norm() + fj.norm(), 1e-15);
}

}  // namespace
}  // namespace calib
