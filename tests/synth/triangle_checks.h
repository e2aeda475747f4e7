#pragma once
// Shared by the tests of the truth model's material laws (neo_hookean_test,
// hencky_test): a fixed rest triangle at a length scale, seeded random
// deformations of it, and the comparison of a triangle energy's gradient and
// Hessian with central differences.

#include "calib/synth/neo_hookean.h"

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace calib::testing {

using synth::Mat6;
using synth::NeoHookeanParameters;
using synth::Vec6;

/// A triangle energy with the contract of TriangleEnergy, for one law.
using TriangleFunction = double (*)(const Vec6& x, const Eigen::Matrix2d& rest_inverse,
                                    double volume_m3, const NeoHookeanParameters& parameters,
                                    Vec6* gradient, Mat6* hessian, bool project_hessian);

// A fixed, well-shaped rest triangle (metres) and its rest data.
struct RestTriangle {
  Vec6 x;
  Eigen::Matrix2d rest_inverse;
  double volume_m3;
};

inline RestTriangle MakeRest(double scale) {
  RestTriangle r;
  r.x << 0.0, 0.0, 1.0 * scale, 0.1 * scale, 0.3 * scale, 0.9 * scale;
  Eigen::Matrix2d dm;
  dm << r.x(2) - r.x(0), r.x(4) - r.x(0), r.x(3) - r.x(1), r.x(5) - r.x(1);
  r.rest_inverse = dm.inverse();
  r.volume_m3 = 0.5 * dm.determinant() * 0.02;
  return r;
}

/// E 30 kPa, nu 0.3 (plane stress) with the given stiffening.
inline NeoHookeanParameters Parameters(double stiffening) {
  NeoHookeanParameters p = synth::PlaneStressLame(30e3, 0.3);
  p.stiffening = stiffening;
  return p;
}

/// Random deformations: F = rotation * symmetric stretch in [0.6, 1.5], plus a
/// translation; seeded, so every run checks the same states.
inline std::vector<Vec6> Deformations(const RestTriangle& rest, double scale, int count) {
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

/// The largest error of an analytic derivative against central differences,
/// and the largest magnitude of the analytic one (the scale to judge it by).
struct DerivativeError {
  double worst = 0.0;
  double magnitude = 0.0;
};

/// The gradient at x against central differences of the energy (step h).
inline DerivativeError GradientError(TriangleFunction f, const RestTriangle& rest, const Vec6& x,
                                     const NeoHookeanParameters& p, double h) {
  Vec6 g;
  f(x, rest.rest_inverse, rest.volume_m3, p, &g, nullptr, false);
  DerivativeError e;
  e.magnitude = g.cwiseAbs().maxCoeff();
  for (int k = 0; k < 6; ++k) {
    Vec6 xp = x, xm = x;
    xp(k) += h;
    xm(k) -= h;
    const double numeric = (f(xp, rest.rest_inverse, rest.volume_m3, p, nullptr, nullptr, false) -
                            f(xm, rest.rest_inverse, rest.volume_m3, p, nullptr, nullptr, false)) /
                           (2.0 * h);
    e.worst = std::max(e.worst, std::abs(numeric - g(k)));
  }
  return e;
}

/// The exact Hessian at x against central differences of the gradient (step
/// h); *asymmetry (when not null) receives its largest |H - H^T| entry.
inline DerivativeError HessianError(TriangleFunction f, const RestTriangle& rest, const Vec6& x,
                                    const NeoHookeanParameters& p, double h, double* asymmetry) {
  Mat6 H;
  f(x, rest.rest_inverse, rest.volume_m3, p, nullptr, &H, false);
  Mat6 numeric;
  for (int k = 0; k < 6; ++k) {
    Vec6 xp = x, xm = x, gp, gm;
    xp(k) += h;
    xm(k) -= h;
    f(xp, rest.rest_inverse, rest.volume_m3, p, &gp, nullptr, false);
    f(xm, rest.rest_inverse, rest.volume_m3, p, &gm, nullptr, false);
    numeric.col(k) = (gp - gm) / (2.0 * h);
  }
  if (asymmetry != nullptr) *asymmetry = (H - H.transpose()).cwiseAbs().maxCoeff();
  return {(numeric - H).cwiseAbs().maxCoeff(), H.cwiseAbs().maxCoeff()};
}

/// Expects f's gradient to match central differences of its energy to 1e-6
/// of its largest component, over rest triangles of 1 mm, 1 m and 1 km,
/// stiffening 0 and 2, 10 deformations each.
inline void ExpectGradientMatchesDifferences(TriangleFunction f) {
  for (const double scale : {1e-3, 1.0, 1e3}) {
    for (const double stiffening : {0.0, 2.0}) {
      const RestTriangle rest = MakeRest(scale);
      const NeoHookeanParameters p = Parameters(stiffening);
      for (const Vec6& x : Deformations(rest, scale, 10)) {
        const DerivativeError e = GradientError(f, rest, x, p, 1e-6 * scale);
        EXPECT_LE(e.worst, 1e-6 * e.magnitude)
            << "scale " << scale << " stiffening " << stiffening << " worst error " << e.worst;
      }
    }
  }
}

/// The same for the exact Hessian against differences of the gradient; it
/// is also symmetric to `symmetry` of its largest entry.
inline void ExpectHessianMatchesDifferences(TriangleFunction f, double symmetry) {
  for (const double scale : {1e-3, 1.0, 1e3}) {
    for (const double stiffening : {0.0, 2.0}) {
      const RestTriangle rest = MakeRest(scale);
      const NeoHookeanParameters p = Parameters(stiffening);
      for (const Vec6& x : Deformations(rest, scale, 10)) {
        double asymmetry = 0.0;
        const DerivativeError e = HessianError(f, rest, x, p, 1e-6 * scale, &asymmetry);
        EXPECT_LE(e.worst, 1e-6 * e.magnitude)
            << "scale " << scale << " stiffening " << stiffening << " worst error " << e.worst;
        EXPECT_LE(asymmetry, symmetry * e.magnitude);
      }
    }
  }
}

/// Expects f's projected Hessian to be PSD at every state; returns at how
/// many of them the exact Hessian is indefinite (where projection worked).
inline int ExpectProjectedHessiansPsd(TriangleFunction f, const RestTriangle& rest,
                                      const std::vector<Vec6>& states, const NeoHookeanParameters& p) {
  int indefinite = 0;
  for (const Vec6& x : states) {
    Mat6 exact, projected;
    f(x, rest.rest_inverse, rest.volume_m3, p, nullptr, &exact, false);
    f(x, rest.rest_inverse, rest.volume_m3, p, nullptr, &projected, true);
    const Eigen::SelfAdjointEigenSolver<Mat6> eig_p(projected);
    EXPECT_GE(eig_p.eigenvalues().minCoeff(), -1e-9 * eig_p.eigenvalues().maxCoeff());
    const Eigen::SelfAdjointEigenSolver<Mat6> eig_e(exact);
    if (eig_e.eigenvalues().minCoeff() < -1e-9 * eig_e.eigenvalues().maxCoeff()) ++indefinite;
  }
  return indefinite;
}

/// Expects `density` at E 30 kPa, nu 0.3 under uniaxial plane stress,
/// F = diag(1 + e, 1 - nu e) with e = 1e-6, to give P00 = E e and P11 = 0 to
/// first order (Hooke's law of the plate).
inline void ExpectUniaxialPlaneStressHooke(synth::EnergyDensity density) {
  const double E = 30e3, nu = 0.3, e = 1e-6;
  const NeoHookeanParameters p = synth::PlaneStressLame(E, nu);
  Eigen::Matrix2d F = Eigen::Matrix2d::Identity();
  F(0, 0) += e;
  F(1, 1) -= nu * e;
  Eigen::Matrix2d P;
  density(F, p, &P, nullptr);
  EXPECT_NEAR(P(0, 0), E * e, 1e-4 * E * e);
  EXPECT_NEAR(P(1, 1), 0.0, 1e-4 * E * e);
  EXPECT_NEAR(P(0, 1), 0.0, 1e-12 * E);
}

}  // namespace calib::testing
