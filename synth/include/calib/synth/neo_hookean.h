#pragma once
// The per-element kernel of the truth model: one linear triangle of a
// compressible neo-Hookean sheet in plane stress, with optional strain
// stiffening. Pure functions on small Eigen types; the truth simulator loops
// over the mesh and calls them, the tests check them against differences.
//
// Energy density (per unit reference volume, J/m^3) of the in-plane
// deformation gradient F (2 x 2, dimensionless), I1 = tr(F^T F), J = det F:
//
//   W(F) = mu/2 (I1 - 2) - mu ln J + lambda/2 (ln J)^2 + s mu psi^2,
//   psi  = I1 - 2 - 2 ln J
//
// (Bonet & Wood, Nonlinear Continuum Mechanics, eq. 5.28, restricted to the
// plane). The last term is the strain stiffening with coefficient s >= 0:
// psi = sum_i (lambda_i^2 - 1 - 2 ln lambda_i) over the principal stretches
// is >= 0, zero only for rotations and second order in the strain, so the
// term is fourth order: it leaves the small-strain moduli (E, nu) unchanged
// and stiffens only large deformations. (I1 - 2)^2 would not: I1 - 2 is first
// order in the strain, so it would also raise the small-strain stiffness.
// For plane stress lambda is the plane-stress Lame parameter
// lambda* = 2 lambda mu / (lambda + 2 mu) = E nu / (1 - nu^2), so that the
// small-strain response is that of a thin plate (PlaneStressLame).
//
// A triangle (x0, x1, x2) in metres has the edge matrix Ds = [x1 - x0, x2 - x0]
// (2 x 2, columns) and F = Ds * rest_inverse, where rest_inverse is the inverse
// of the rest edge matrix Dm (1/m). Its energy is W(F) * volume, volume =
// rest area * thickness (m^3), in joules; gradients are in newtons (J/m).
// W is +infinity for J <= 0: an inverted or degenerate element is infeasible.

#include "calib/core/types.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>

namespace calib::synth {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// Lame parameters of the energy density, pascals. The Hencky law
/// (hencky.h) reads the same pair: its 2D bulk modulus is mu + lambda.
struct NeoHookeanParameters {
  double mu_pa = 0.0;        ///< shear modulus, > 0
  double lambda_pa = 0.0;    ///< (plane-stress) first Lame parameter, >= 0
  double stiffening = 0.0;   ///< s, dimensionless, >= 0
};

/// Plane-stress Lame parameters of Young's modulus E (Pa) and Poisson's ratio
/// nu: mu = E / (2 (1 + nu)), lambda* = E nu / (1 - nu^2); stiffening 0.
NeoHookeanParameters PlaneStressLame(double youngs_modulus_pa, double poisson_ratio);

/// W(F) in J/m^3. When J > 0 and `stress` is not null, writes the first
/// Piola-Kirchhoff stress P = dW/dF (Pa); when `stress_derivative` is not
/// null, writes dP/dF as a 4 x 4 matrix on vec(F) = (F00, F10, F01, F11)
/// (column-major, Eigen's order). Returns +infinity (and writes nothing) when
/// J <= 0.
double NeoHookeanDensity(const Eigen::Matrix2d& F, const NeoHookeanParameters& parameters,
                         Eigen::Matrix2d* stress, Eigen::Matrix4d* stress_derivative);

/// An energy density W(F) with the contract of NeoHookeanDensity (J/m^3; P
/// and dP/dF written where not null; +infinity for J <= 0).
using EnergyDensity = double (*)(const Eigen::Matrix2d& F, const NeoHookeanParameters& parameters,
                                 Eigen::Matrix2d* stress, Eigen::Matrix4d* stress_derivative);

/// Energy of one triangle of `density`, joules. x = (x0, y0, x1, y1, x2, y2)
/// in metres. When the element is not inverted, writes the gradient dE/dx
/// (N; the element's forces on its nodes are its negative) and the 6 x 6
/// Hessian (N/m) where the pointers are not null. With project_hessian, dP/dF
/// is projected onto the positive semi-definite cone before it is mapped to
/// the nodes, so the Hessian is PSD (the projected Newton method of Teran et
/// al. 2005); otherwise it is the exact second derivative. Returns +infinity
/// for J <= 0 (nothing written).
double TriangleEnergy(EnergyDensity density, const Vec6& x, const Eigen::Matrix2d& rest_inverse,
                      double volume_m3, const NeoHookeanParameters& parameters, Vec6* gradient,
                      Mat6* hessian, bool project_hessian);

/// TriangleEnergy of NeoHookeanDensity.
double NeoHookeanTriangleEnergy(const Vec6& x, const Eigen::Matrix2d& rest_inverse,
                                double volume_m3, const NeoHookeanParameters& parameters,
                                Vec6* gradient, Mat6* hessian, bool project_hessian);

/// The 4 x 6 matrix dvec(F)/dx of a linear triangle (constant in x).
Eigen::Matrix<double, 4, 6> DeformationGradientJacobian(const Eigen::Matrix2d& rest_inverse);

/// Replaces the symmetric matrix m by its projection onto the positive
/// semi-definite cone (negative eigenvalues set to zero). Reads the lower
/// triangle. A matrix whose Cholesky factorisation succeeds is positive
/// definite and left as it is (the common case, checked cheaply first).
template <int N>
void ProjectToPositiveSemiDefinite(Eigen::Matrix<double, N, N>& m) {
  if (Eigen::LLT<Eigen::Matrix<double, N, N>>(m).info() == Eigen::Success) return;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eigen(m);
  Eigen::Matrix<double, N, 1> values = eigen.eigenvalues();
  if (values.minCoeff() >= 0.0) return;
  values = values.cwiseMax(0.0);
  m = eigen.eigenvectors() * values.asDiagonal() * eigen.eigenvectors().transpose();
}

}  // namespace calib::synth
