#include "calib/synth/neo_hookean.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace calib::synth {
namespace {

// A fixed, well-shaped rest triangle (metres) and its rest data.
struct RestTriangle {
  Vec6 x;
  Eigen::Matrix2d rest_inverse;
  double volume_m3;
};

RestTriangle MakeRest(double scale) {
  RestTriangle r;
  r.x << 0.0, 0.0, 1.0 * scale, 0.1 * scale, 0.3 * scale, 0.9 * scale;
  Eigen::Matrix2d dm;
  dm << r.x(2) - r.x(0), r.x(4) - r.x(0), r.x(3) - r.x(1), r.x(5) - r.x(1);
  r.rest_inverse = dm.inverse();
  r.volume_m3 = 0.5 * dm.determinant() * 0.02;
  return r;
}

NeoHookeanParameters Parameters(double stiffening) {
  NeoHookeanParameters p = PlaneStressLame(30e3, 0.3);
  p.stiffening = stiffening;
  return p;
}

// Random deformations: F = rotation * symmetric stretch in [0.6, 1.5], plus a
// translation; seeded, so every run checks the same states.
std::vector<Vec6> Deformations(const RestTriangle& rest, double scale, int count) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec6> out;
  for (int k = 0; k < count; ++k) {
    const double angle = 6.28 * u(rng);
    Eigen::Matrix2d R;
    R << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
    const double s1 = 0.6 + 0.9 * u(rng), s2 = 0.6 + 0.9 * u(rng), phi = 3.14 * u(rng);
    Eigen::Matrix2d Q;
    Q << std::cos(phi), -std::sin(phi), std::sin(phi), std::cos(phi);
    const Eigen::Matrix2d F = R * Q * Eigen::Vector2d(s1, s2).asDiagonal() * Q.transpose();
    const Vec2 t(scale * u(rng), scale * u(rng));
    Vec6 x;
    for (int a = 0; a < 3; ++a) x.segment<2>(2 * a) = F * rest.x.segment<2>(2 * a) + t;
    out.push_back(x);
  }
  return out;
}

double Energy(const RestTriangle& r, const Vec6& x, const NeoHookeanParameters& p) {
  return NeoHookeanTriangleEnergy(x, r.rest_inverse, r.volume_m3, p, nullptr, nullptr, false);
}

TEST(NeoHookean, GradientMatchesCentralDifferencesAtAllScales) {
  for (const double scale : {1e-3, 1.0, 1e3}) {
    for (const double stiffening : {0.0, 2.0}) {
      const RestTriangle rest = MakeRest(scale);
      const NeoHookeanParameters p = Parameters(stiffening);
      for (const Vec6& x : Deformations(rest, scale, 10)) {
        Vec6 g;
        NeoHookeanTriangleEnergy(x, rest.rest_inverse, rest.volume_m3, p, &g, nullptr, false);
        const double h = 1e-6 * scale;
        double worst = 0.0;
        for (int k = 0; k < 6; ++k) {
          Vec6 xp = x, xm = x;
          xp(k) += h;
          xm(k) -= h;
          const double numeric = (Energy(rest, xp, p) - Energy(rest, xm, p)) / (2.0 * h);
          worst = std::max(worst, std::abs(numeric - g(k)));
        }
        EXPECT_LE(worst, 1e-6 * g.cwiseAbs().maxCoeff())
            << "scale " << scale << " stiffening " << stiffening << " worst error " << worst;
      }
    }
  }
}

TEST(NeoHookean, HessianMatchesDifferencesOfTheGradient) {
  for (const double scale : {1e-3, 1.0, 1e3}) {
    for (const double stiffening : {0.0, 2.0}) {
      const RestTriangle rest = MakeRest(scale);
      const NeoHookeanParameters p = Parameters(stiffening);
      for (const Vec6& x : Deformations(rest, scale, 10)) {
        Mat6 H;
        Vec6 g;
        NeoHookeanTriangleEnergy(x, rest.rest_inverse, rest.volume_m3, p, &g, &H, false);
        const double h = 1e-6 * scale;
        Mat6 numeric;
        for (int k = 0; k < 6; ++k) {
          Vec6 xp = x, xm = x, gp, gm;
          xp(k) += h;
          xm(k) -= h;
          NeoHookeanTriangleEnergy(xp, rest.rest_inverse, rest.volume_m3, p, &gp, nullptr, false);
          NeoHookeanTriangleEnergy(xm, rest.rest_inverse, rest.volume_m3, p, &gm, nullptr, false);
          numeric.col(k) = (gp - gm) / (2.0 * h);
        }
        const double worst = (numeric - H).cwiseAbs().maxCoeff();
        EXPECT_LE(worst, 1e-6 * H.cwiseAbs().maxCoeff())
            << "scale " << scale << " stiffening " << stiffening << " worst error " << worst;
        EXPECT_LE((H - H.transpose()).cwiseAbs().maxCoeff(), 1e-12 * H.cwiseAbs().maxCoeff());
      }
    }
  }
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
  // Uniaxial stress in plane stress: F = diag(1 + e, 1 - nu e) gives
  // P00 = E e and P11 = 0 to first order.
  const double E = 30e3, nu = 0.3, e = 1e-6;
  const NeoHookeanParameters p = PlaneStressLame(E, nu);
  Eigen::Matrix2d F = Eigen::Matrix2d::Identity();
  F(0, 0) += e;
  F(1, 1) -= nu * e;
  Eigen::Matrix2d P;
  NeoHookeanDensity(F, p, &P, nullptr);
  EXPECT_NEAR(P(0, 0), E * e, 1e-4 * E * e);
  EXPECT_NEAR(P(1, 1), 0.0, 1e-4 * E * e);
  EXPECT_NEAR(P(0, 1), 0.0, 1e-12 * E);
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
  int indefinite_seen = 0;
  for (const Vec6& x : Deformations(rest, 1.0, 30)) {
    Mat6 exact, projected;
    NeoHookeanTriangleEnergy(x, rest.rest_inverse, rest.volume_m3, p, nullptr, &exact, false);
    NeoHookeanTriangleEnergy(x, rest.rest_inverse, rest.volume_m3, p, nullptr, &projected, true);
    const Eigen::SelfAdjointEigenSolver<Mat6> eig_p(projected);
    EXPECT_GE(eig_p.eigenvalues().minCoeff(), -1e-9 * eig_p.eigenvalues().maxCoeff());
    const Eigen::SelfAdjointEigenSolver<Mat6> eig_e(exact);
    if (eig_e.eigenvalues().minCoeff() < -1e-9 * eig_e.eigenvalues().maxCoeff()) ++indefinite_seen;
  }
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
