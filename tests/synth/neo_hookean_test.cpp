#include "calib/synth/neo_hookean.h"

#include "triangle_checks.h"

#include <gtest/gtest.h>

#include <cmath>

namespace calib::synth {
namespace {

using testing::Deformations;
using testing::MakeRest;
using testing::Parameters;
using testing::RestTriangle;

double Energy(const RestTriangle& r, const Vec6& x, const NeoHookeanParameters& p) {
  return NeoHookeanTriangleEnergy(x, r.rest_inverse, r.volume_m3, p, nullptr, nullptr, false);
}

TEST(NeoHookean, GradientMatchesCentralDifferencesAtAllScales) {
  testing::ExpectGradientMatchesDifferences(&NeoHookeanTriangleEnergy);
}

TEST(NeoHookean, HessianMatchesDifferencesOfTheGradient) {
  testing::ExpectHessianMatchesDifferences(&NeoHookeanTriangleEnergy, 1e-12);
}

TEST(NeoHookean, ZeroEnergyAndForceAtRestAndUnderRigidMotion) {
  const RestTriangle rest = MakeRest(1e-2);
  const NeoHookeanParameters p = Parameters(1.0);
  for (const double angle : {0.0, 0.7, 2.5, -1.9}) {
    Eigen::Matrix2d R;
    R << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
    Vec6 x;
    for (int a = 0; a < 3; ++a) x.segment<2>(2 * a) = R * rest.x.segment<2>(2 * a) + Vec2(0.3, -2.0);
    Vec6 g;
    const double e =
        NeoHookeanTriangleEnergy(x, rest.rest_inverse, rest.volume_m3, p, &g, nullptr, false);
    // Energy scale of a 1 % strain: V mu 1e-4.
    const double scale = rest.volume_m3 * p.mu_pa;
    EXPECT_LE(std::abs(e), 1e-12 * scale) << "angle " << angle << " energy " << e;
    EXPECT_LE(g.norm(), 1e-10 * scale / 1e-2) << "angle " << angle << " force " << g.norm();
  }
}

TEST(NeoHookean, EnergyAndForcesAreInvariantUnderRigidMotion) {
  const RestTriangle rest = MakeRest(1e-2);
  const NeoHookeanParameters p = Parameters(0.5);
  const double angle = 1.1;
  Eigen::Matrix2d R;
  R << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  for (const Vec6& x : Deformations(rest, 1e-2, 5)) {
    Vec6 moved, g, gm;
    for (int a = 0; a < 3; ++a) moved.segment<2>(2 * a) = R * x.segment<2>(2 * a) + Vec2(0.1, 0.2);
    const double e = NeoHookeanTriangleEnergy(x, rest.rest_inverse, rest.volume_m3, p, &g, nullptr, false);
    const double em =
        NeoHookeanTriangleEnergy(moved, rest.rest_inverse, rest.volume_m3, p, &gm, nullptr, false);
    EXPECT_NEAR(em, e, 1e-12 * std::abs(e));
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE((gm.segment<2>(2 * a) - R * g.segment<2>(2 * a)).norm(), 1e-9 * g.norm());
    }
    // Forces of an element sum to zero, and so do their moments.
    EXPECT_LE((g.segment<2>(0) + g.segment<2>(2) + g.segment<2>(4)).norm(), 1e-12 * g.norm());
    double moment = 0.0;
    for (int a = 0; a < 3; ++a) moment += Cross(x.segment<2>(2 * a), g.segment<2>(2 * a));
    EXPECT_LE(std::abs(moment), 1e-12 * g.norm());
  }
}

TEST(NeoHookean, SmallStrainMatchesPlaneStressHooke) {
  testing::ExpectUniaxialPlaneStressHooke(&NeoHookeanDensity);
}

TEST(NeoHookean, InvertedOrDegenerateElementIsInfeasible) {
  const RestTriangle rest = MakeRest(1.0);
  Vec6 flipped = rest.x;
  flipped(5) = -flipped(5);  // node 2 mirrored through the x axis: J < 0
  Vec6 g = Vec6::Constant(7.0);
  EXPECT_TRUE(std::isinf(
      NeoHookeanTriangleEnergy(flipped, rest.rest_inverse, rest.volume_m3, Parameters(0.0), &g,
                               nullptr, false)));
  EXPECT_EQ(g, Vec6::Constant(7.0)) << "nothing written for an infeasible element";
  Vec6 flat = rest.x;
  flat.segment<2>(4) = 0.5 * (flat.segment<2>(0) + flat.segment<2>(2));  // J = 0
  EXPECT_TRUE(std::isinf(Energy(rest, flat, Parameters(0.0))));
}

TEST(NeoHookean, ProjectedHessianIsPositiveSemiDefiniteAndExactWhereConvex) {
  const RestTriangle rest = MakeRest(1.0);
  const NeoHookeanParameters p = Parameters(1.0);
  const int indefinite_seen =
      testing::ExpectProjectedHessiansPsd(&NeoHookeanTriangleEnergy, rest, Deformations(rest, 1.0, 30), p);
  EXPECT_GT(indefinite_seen, 0) << "the sample should include indefinite (compressed) states";
  // At rest the energy is convex: projection changes nothing.
  Mat6 exact, projected;
  NeoHookeanTriangleEnergy(rest.x, rest.rest_inverse, rest.volume_m3, p, nullptr, &exact, false);
  NeoHookeanTriangleEnergy(rest.x, rest.rest_inverse, rest.volume_m3, p, nullptr, &projected, true);
  EXPECT_LE((exact - projected).cwiseAbs().maxCoeff(), 1e-10 * exact.cwiseAbs().maxCoeff());
}

TEST(NeoHookean, StrainStiffeningStiffensLargeStretchOnly) {
  const NeoHookeanParameters soft = Parameters(0.0), stiff = Parameters(1.0);
  Eigen::Matrix2d small = Eigen::Matrix2d::Identity(), large = Eigen::Matrix2d::Identity();
  small(0, 0) = 1.001;
  large(0, 0) = 1.5;
  const double ratio_small =
      NeoHookeanDensity(small, stiff, nullptr, nullptr) / NeoHookeanDensity(small, soft, nullptr, nullptr);
  const double ratio_large =
      NeoHookeanDensity(large, stiff, nullptr, nullptr) / NeoHookeanDensity(large, soft, nullptr, nullptr);
  EXPECT_LT(ratio_small, 1.01) << "no change at small strain";
  EXPECT_GT(ratio_large, 1.5) << "stiffer at 50 % stretch";
}

TEST(NeoHookean, ProjectionHelperClampsNegativeEigenvalues) {
  Eigen::Matrix3d m;
  m << 2.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.5;
  const Eigen::Matrix3d r = (Eigen::Matrix3d() << 1, 1, 0, -1, 1, 0, 0, 0, 1.41421356237).finished() / 1.41421356237;
  Eigen::Matrix3d a = r * m * r.transpose();
  ProjectToPositiveSemiDefinite<3>(a);
  const Eigen::Matrix3d expected = r * Eigen::Vector3d(2.0, 0.0, 0.5).asDiagonal() * r.transpose();
  EXPECT_LE((a - expected).cwiseAbs().maxCoeff(), 1e-12);
}

}  // namespace
}  // namespace calib::synth
