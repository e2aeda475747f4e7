#include "calib/synth/neo_hookean.h"

#include <cmath>
#include <limits>

namespace calib::synth {

NeoHookeanParameters PlaneStressLame(double youngs_modulus_pa, double poisson_ratio) {
  NeoHookeanParameters p;
  p.mu_pa = youngs_modulus_pa / (2.0 * (1.0 + poisson_ratio));
  p.lambda_pa = youngs_modulus_pa * poisson_ratio / (1.0 - poisson_ratio * poisson_ratio);
  return p;
}

double NeoHookeanDensity(const Eigen::Matrix2d& F, const NeoHookeanParameters& parameters,
                         Eigen::Matrix2d* stress, Eigen::Matrix4d* stress_derivative) {
  const double J = F.determinant();
  if (!(J > 0.0)) return std::numeric_limits<double>::infinity();
  const double mu = parameters.mu_pa;
  const double lambda = parameters.lambda_pa;
  const double s = parameters.stiffening;
  const double log_j = std::log(J);
  const double i1_excess = F.squaredNorm() - 2.0;  // I1 - 2
  const double psi = i1_excess - 2.0 * log_j;      // >= 0, 0 only for rotations
  const double energy = 0.5 * mu * i1_excess - mu * log_j + 0.5 * lambda * log_j * log_j +
                        s * mu * psi * psi;
  if (stress == nullptr && stress_derivative == nullptr) return energy;

  // Volumetric part g(J) = -mu ln J + lambda/2 ln^2 J; dJ/dF = cof(F);
  // dpsi/dF = 2 F - 2 cof(F) / J.
  const double dg = (-mu + lambda * log_j) / J;
  const double ddg = (lambda + mu - lambda * log_j) / (J * J);
  Eigen::Matrix2d cofactor;
  cofactor << F(1, 1), -F(1, 0), -F(0, 1), F(0, 0);
  const Eigen::Matrix2d dpsi = 2.0 * F - (2.0 / J) * cofactor;
  const double c = 2.0 * s * mu;  // d(s mu psi^2) = c psi dpsi
  if (stress != nullptr) *stress = mu * F + dg * cofactor + (c * psi) * dpsi;
  if (stress_derivative != nullptr) {
    const Eigen::Map<const Eigen::Vector4d> vc(cofactor.data());
    const Eigen::Map<const Eigen::Vector4d> vd(dpsi.data());
    // d^2 J / dF^2 on vec(F) = (F00, F10, F01, F11): J = f0 f3 - f1 f2.
    Eigen::Matrix4d hess_j = Eigen::Matrix4d::Zero();
    hess_j(0, 3) = hess_j(3, 0) = 1.0;
    hess_j(1, 2) = hess_j(2, 1) = -1.0;
    const Eigen::Matrix4d identity = Eigen::Matrix4d::Identity();
    const Eigen::Matrix4d hess_psi =
        2.0 * identity - (2.0 / J) * hess_j + (2.0 / (J * J)) * vc * vc.transpose();
    *stress_derivative = mu * identity + ddg * vc * vc.transpose() + dg * hess_j +
                         c * (vd * vd.transpose() + psi * hess_psi);
  }
  return energy;
}

Eigen::Matrix<double, 4, 6> DeformationGradientJacobian(const Eigen::Matrix2d& rest_inverse) {
  // F_ij = sum_k Ds_ik B_kj with Ds_i0 = x1_i - x0_i, Ds_i1 = x2_i - x0_i, so
  // dF_ij / d(node a)_i = c_aj with c_0j = -(B_0j + B_1j), c_1j = B_0j,
  // c_2j = B_1j. vec index of F_ij is i + 2 j; x index of (node a)_i is 2a + i.
  const Eigen::Matrix2d& B = rest_inverse;
  Eigen::Matrix<double, 4, 6> D = Eigen::Matrix<double, 4, 6>::Zero();
  for (int j = 0; j < 2; ++j) {
    const double c[3] = {-(B(0, j) + B(1, j)), B(0, j), B(1, j)};
    for (int i = 0; i < 2; ++i) {
      for (int a = 0; a < 3; ++a) D(i + 2 * j, 2 * a + i) = c[a];
    }
  }
  return D;
}

double TriangleEnergy(EnergyDensity energy_density, const Vec6& x,
                      const Eigen::Matrix2d& rest_inverse, double volume_m3,
                      const NeoHookeanParameters& parameters, Vec6* gradient, Mat6* hessian,
                      bool project_hessian) {
  Eigen::Matrix2d Ds;
  Ds << x(2) - x(0), x(4) - x(0), x(3) - x(1), x(5) - x(1);
  const Eigen::Matrix2d F = Ds * rest_inverse;
  Eigen::Matrix2d P;
  Eigen::Matrix4d dPdF;
  const bool need_derivatives = gradient != nullptr || hessian != nullptr;
  const double density = energy_density(F, parameters, need_derivatives ? &P : nullptr,
                                        hessian != nullptr ? &dPdF : nullptr);
  if (!std::isfinite(density)) return density;
  if (gradient != nullptr) {
    // dE/d(node 1) = V P B^T col 0, node 2 col 1, node 0 minus their sum.
    const Eigen::Matrix2d G = volume_m3 * P * rest_inverse.transpose();
    gradient->segment<2>(2) = G.col(0);
    gradient->segment<2>(4) = G.col(1);
    gradient->segment<2>(0) = -(G.col(0) + G.col(1));
  }
  if (hessian != nullptr) {
    if (project_hessian) ProjectToPositiveSemiDefinite<4>(dPdF);
    const Eigen::Matrix<double, 4, 6> D = DeformationGradientJacobian(rest_inverse);
    hessian->noalias() = volume_m3 * D.transpose() * dPdF * D;
  }
  return volume_m3 * density;
}

double NeoHookeanTriangleEnergy(const Vec6& x, const Eigen::Matrix2d& rest_inverse,
                                double volume_m3, const NeoHookeanParameters& parameters,
                                Vec6* gradient, Mat6* hessian, bool project_hessian) {
  return TriangleEnergy(&NeoHookeanDensity, x, rest_inverse, volume_m3, parameters, gradient,
                        hessian, project_hessian);
}

}  // namespace calib::synth
