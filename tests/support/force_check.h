#pragma once
// Finite-difference check of a force kernel against its energy, shared by
// the tests of the base terms and of the effects.

#include "calib/core/types.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <random>

namespace calib::testing {

/// N points uniform in [-scale, scale]^2.
template <int N>
std::array<Vec2, N> RandomPoints(std::mt19937_64& rng, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::array<Vec2, N> p;
  for (auto& pi : p) pi = scale * Vec2(u(rng), u(rng));
  return p;
}

/// A term as a function of N stacked node positions: returns the energy and
/// adds its forces to the second argument.
template <int N>
using Term = std::function<double(const std::array<Vec2, N>&, std::array<Vec2, N>&)>;

/// Worst |analytic - numeric| force component, numeric = -dE/dp by central
/// differences with step 1e-6 * scale, relative to the largest analytic
/// force component plus `floor`.
template <int N>
double WorstForceError(const Term<N>& term, const std::array<Vec2, N>& p, double scale,
                       double floor = 1e-12) {
  std::array<Vec2, N> f;
  for (auto& fi : f) fi.setZero();
  term(p, f);
  double max_force = 0.0;
  for (const auto& fi : f) max_force = std::max(max_force, fi.cwiseAbs().maxCoeff());
  const double h = 1e-6 * scale;
  double worst = 0.0;
  for (int i = 0; i < N; ++i) {
    for (int d = 0; d < 2; ++d) {
      auto plus = p, minus = p;
      plus[i][d] += h;
      minus[i][d] -= h;
      std::array<Vec2, N> unused;
      for (auto& u : unused) u.setZero();
      const double e_plus = term(plus, unused);
      const double e_minus = term(minus, unused);
      const double numeric = -(e_plus - e_minus) / (2.0 * h);
      worst = std::max(worst, std::abs(numeric - f[i][d]) / (max_force + floor));
    }
  }
  return worst;
}

}  // namespace calib::testing
