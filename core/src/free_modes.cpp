#include "calib/core/free_modes.h"

#include "calib/core/model.h"
#include "calib/core/parameters.h"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

namespace calib {

double SlowestModeRate(const Mesh& mesh, std::span<const uint8_t> clamped,
                       std::span<const Vec2> rest, bool area_weighted) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const int n = mesh.NumNodes();
  if (clamped.size() != static_cast<size_t>(n) || rest.size() != static_cast<size_t>(n)) return kNaN;
  Model model(mesh);
  if (model.SetRestShape(rest) >= 0) return kNaN;
  const AreaWeights weights = area_weighted ? ComputeAreaWeights(mesh) : AreaWeights{};
  if (area_weighted) model.SetElementWeights(weights.edge, weights.triangle, weights.angle);
  std::vector<int> free_nodes;
  for (int i = 0; i < n; ++i) {
    if (clamped[i] == 0) free_nodes.push_back(i);
  }
  const int dofs = 2 * static_cast<int>(free_nodes.size());
  if (dofs == 0) return kNaN;

  ModelParameters unit;
  unit.k_distance = unit.k_area = unit.k_angle = 1.0;
  unit.k_damping = 0.0;
  ForceWorkspace workspace = model.MakeWorkspace();
  std::vector<Vec2> x(rest.begin(), rest.end());
  const std::vector<Vec2> v(n, Vec2::Zero());
  std::vector<Vec2> plus(n), minus(n);
  // A probe a millionth of the mesh's size: central differences of the
  // forces are then exact to about 1e-10 of the stiffness.
  double extent = 0.0;
  for (const Vec2& p : rest) extent = std::max(extent, (p - rest[0]).norm());
  const double probe = 1e-6 * std::max(extent, 1.0);

  Eigen::MatrixXd k1(dofs, dofs);
  for (int c = 0; c < dofs; ++c) {
    const int node = free_nodes[c / 2], axis = c % 2;
    x[node][axis] = rest[node][axis] + probe;
    model.ComputeForces(unit, x, v, plus, workspace);
    x[node][axis] = rest[node][axis] - probe;
    model.ComputeForces(unit, x, v, minus, workspace);
    x[node][axis] = rest[node][axis];
    for (int r = 0; r < dofs; ++r) {
      const int at = free_nodes[r / 2], along = r % 2;
      k1(r, c) = -(plus[at][along] - minus[at][along]) / (2.0 * probe);
    }
  }
  if (area_weighted) {
    // The mass matrix W = diag(w): the rates of W^-1 K1 are those of the
    // symmetric W^-1/2 K1 W^-1/2.
    Eigen::VectorXd scale(dofs);
    for (int r = 0; r < dofs; ++r) scale(r) = 1.0 / std::sqrt(weights.node[free_nodes[r / 2]]);
    k1 = scale.asDiagonal() * k1 * scale.asDiagonal();
  }
  const Eigen::MatrixXd symmetric = 0.5 * (k1 + k1.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(symmetric, Eigen::EigenvaluesOnly);
  if (solver.info() != Eigen::Success) return kNaN;
  const double lowest = solver.eigenvalues()(0);
  const double highest = solver.eigenvalues()(dofs - 1);
  // A mesh the clamps do not hold has a zero mode (a rigid motion), which
  // the differences leave at rounding level.
  if (!(lowest > 1e-9 * highest)) return kNaN;
  return lowest;
}

double SwingStiffness(double rate, double period_s, double mass) {
  if (!(rate > 0.0) || !(period_s > 0.0) || !(mass > 0.0) || !std::isfinite(rate)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const double omega = 2.0 * std::numbers::pi / period_s;
  return mass * omega * omega / rate;
}

}  // namespace calib
