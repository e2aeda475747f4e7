#include "calib/synth/hencky.h"

#include <cmath>
#include <limits>

namespace calib::synth {
namespace {

Eigen::Matrix2d Rotation(double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Eigen::Matrix2d r;
  r << c, -s, s, c;
  return r;
}

Eigen::Vector4d Vec(const Eigen::Matrix2d& m) { return Eigen::Map<const Eigen::Vector4d>(m.data()); }

// (ln a - ln b) / (a - b) for a >= b > 0, accurate as a -> b.
double LogQuotient(double a, double b) {
  const double x = a / b - 1.0;
  if (x < 1e-4) return (1.0 - x * (0.5 - x * (1.0 / 3.0 - 0.25 * x))) / b;
  return std::log1p(x) / (a - b);
}

}  // namespace

double HenckyDensity(const Eigen::Matrix2d& F, const NeoHookeanParameters& parameters,
                     Eigen::Matrix2d* stress, Eigen::Matrix4d* stress_derivative) {
  const double J = F.determinant();
  if (!(J > 0.0)) return std::numeric_limits<double>::infinity();
  // Polar decomposition F = R S (S symmetric positive definite: trace > 0
  // by the choice of R, det S = J > 0), then S = V diag(l1, l2) V^T.
  const Eigen::Matrix2d R = Rotation(std::atan2(F(1, 0) - F(0, 1), F(0, 0) + F(1, 1)));
  const Eigen::Matrix2d S = R.transpose() * F;
  const double mean = 0.5 * (S(0, 0) + S(1, 1));
  const double half_difference = 0.5 * (S(0, 0) - S(1, 1));
  const double off = 0.5 * (S(0, 1) + S(1, 0));
  const double l1 = mean + std::hypot(half_difference, off);
  const double l2 = J / l1;  // = mean - hypot, without the cancellation
  const double e1 = std::log(l1), e2 = std::log(l2);

  const double mu = parameters.mu_pa;
  const double kappa = parameters.mu_pa + parameters.lambda_pa;
  const double c = parameters.stiffening * mu;
  const double psi = l1 * l1 - 1.0 - 2.0 * e1 + l2 * l2 - 1.0 - 2.0 * e2;
  const double shear = e1 - e2, volume = e1 + e2;
  const double energy = 0.5 * mu * shear * shear + 0.5 * kappa * volume * volume + c * psi * psi;
  if (stress == nullptr && stress_derivative == nullptr) return energy;

  // dW/dl_i: f_i / l_i (f of the log stretches) + stiffening.
  const double f1 = mu * shear + kappa * volume, f2 = -mu * shear + kappa * volume;
  const double p1 = 2.0 * (l1 - 1.0 / l1), p2 = 2.0 * (l2 - 1.0 / l2);  // dpsi/dl_i
  const double w1 = f1 / l1 + 2.0 * c * psi * p1;
  const double w2 = f2 / l2 + 2.0 * c * psi * p2;
  const Eigen::Matrix2d V = Rotation(0.5 * std::atan2(2.0 * off, 2.0 * half_difference));
  const Eigen::Matrix2d U = R * V;
  if (stress != nullptr) *stress = U * Eigen::Vector2d(w1, w2).asDiagonal() * V.transpose();
  if (stress_derivative != nullptr) {
    // d^2W/dl_i dl_j.
    Eigen::Matrix2d A;
    A(0, 0) = (mu + kappa - f1) / (l1 * l1) + 2.0 * c * (p1 * p1 + psi * (2.0 + 2.0 / (l1 * l1)));
    A(1, 1) = (mu + kappa - f2) / (l2 * l2) + 2.0 * c * (p2 * p2 + psi * (2.0 + 2.0 / (l2 * l2)));
    A(0, 1) = A(1, 0) = (kappa - mu) / (l1 * l2) + 2.0 * c * p1 * p2;
    const double twist = (w1 + w2) / (l1 + l2);
    // (w1 - w2) / (l1 - l2), each part divided out by hand.
    const double flip = (mu * (l1 + l2) * LogQuotient(l1, l2) - kappa * volume) / (l1 * l2) +
                        4.0 * c * psi * (1.0 + 1.0 / (l1 * l2));
    const Eigen::Vector2d u1 = U.col(0), u2 = U.col(1), v1 = V.col(0), v2 = V.col(1);
    const Eigen::Vector4d d1 = Vec(u1 * v1.transpose()), d2 = Vec(u2 * v2.transpose());
    const Eigen::Vector4d t = Vec(u2 * v1.transpose() - u1 * v2.transpose()) / std::sqrt(2.0);
    const Eigen::Vector4d l = Vec(u2 * v1.transpose() + u1 * v2.transpose()) / std::sqrt(2.0);
    *stress_derivative = A(0, 0) * d1 * d1.transpose() + A(1, 1) * d2 * d2.transpose() +
                         A(0, 1) * (d1 * d2.transpose() + d2 * d1.transpose()) +
                         twist * t * t.transpose() + flip * l * l.transpose();
  }
  return energy;
}

double HenckyTriangleEnergy(const Vec6& x, const Eigen::Matrix2d& rest_inverse, double volume_m3,
                            const NeoHookeanParameters& parameters, Vec6* gradient, Mat6* hessian,
                            bool project_hessian) {
  return TriangleEnergy(&HenckyDensity, x, rest_inverse, volume_m3, parameters, gradient, hessian,
                        project_hessian);
}

}  // namespace calib::synth
