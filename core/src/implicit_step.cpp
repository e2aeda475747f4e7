#include "calib/core/implicit_step.h"

#include <Eigen/OrderingMethods>
#include <fmt/format.h>

#include <algorithm>

namespace calib {
namespace {

using SparseMatrix = Eigen::SparseMatrix<double>;
using Triplet = Eigen::Triplet<double>;

// Probe of the stiffness columns, px: truncation (probe / edge)^2 and
// rounding (1e-16 x coordinates / probe) both ~1e-10 of the force.
constexpr double kStiffnessProbePx = 1e-4;

// -dF/dq over the unknowns (central differences, symmetrised), where the
// forces of the model at the rest shape depend on q = positions
// (`velocity` false) or velocities (`velocity` true) through `params`.
SparseMatrix UnitJacobian(const Model& model, const ModelParameters& params, bool velocity,
                          const std::vector<int>& coordinate_of_unknown,
                          const std::vector<int>& unknown_of_coordinate) {
  const std::vector<Vec2>& rest = model.mesh().rest_positions;
  const size_t n = rest.size();
  ForceWorkspace workspace = model.MakeWorkspace();
  std::vector<Vec2> x(rest), v(n, Vec2::Zero()), plus(n), minus(n);
  std::vector<Vec2>& probed = velocity ? v : x;
  const double probe = velocity ? 1.0 : kStiffnessProbePx;
  std::vector<Triplet> entries;
  const int m = static_cast<int>(coordinate_of_unknown.size());
  for (int col = 0; col < m; ++col) {
    const int c = coordinate_of_unknown[col];
    double& q = probed[c / 2][c % 2];
    const double q0 = q;
    q = q0 + probe;
    model.ComputeForces(params, x, v, plus, workspace);
    q = q0 - probe;
    model.ComputeForces(params, x, v, minus, workspace);
    q = q0;
    for (size_t i = 0; i < n; ++i) {
      for (int d = 0; d < 2; ++d) {
        const int row = unknown_of_coordinate[2 * i + d];
        const double value = (minus[i][d] - plus[i][d]) / (2.0 * probe);
        if (row >= 0 && value != 0.0) entries.emplace_back(row, col, value);
      }
    }
  }
  SparseMatrix jacobian(m, m);
  jacobian.setFromTriplets(entries.begin(), entries.end());
  const SparseMatrix transpose = jacobian.transpose();
  return 0.5 * (jacobian + transpose);
}

}  // namespace

ImplicitFirstOrderStep::ImplicitFirstOrderStep(const Model& model, std::span<const double> movable) {
  const int n = static_cast<int>(movable.size());
  std::vector<int> coordinate_of_unknown;
  std::vector<int> unknown_of_coordinate(2 * static_cast<size_t>(n), -1);
  for (int i = 0; i < n; ++i) {
    if (movable[i] == 0.0) continue;
    for (int d = 0; d < 2; ++d) {
      unknown_of_coordinate[2 * i + d] = static_cast<int>(coordinate_of_unknown.size());
      coordinate_of_unknown.push_back(2 * i + d);
    }
  }
  const int m = static_cast<int>(coordinate_of_unknown.size());
  num_coordinates_ = 2 * n;
  movable_ = movable;
  int num_clamped = 0;
  for (int i = 0; i < n; ++i) {
    if (movable[i] != 0.0) continue;
    ++num_clamped;
    pivot_ = i;
  }
  free_turn_ = num_clamped == 0 ? FreeTurn::kFree
               : num_clamped == 1 ? FreeTurn::kPivot
                                  : FreeTurn::kNone;

  // One stiffness (or the damping) at 1, the others at their default 0.
  const auto unit_jacobian = [&](double ModelParameters::*stiffness, bool velocity) {
    ModelParameters unit;
    unit.*stiffness = 1.0;
    return UnitJacobian(model, unit, velocity, coordinate_of_unknown, unknown_of_coordinate);
  };
  const SparseMatrix distance = unit_jacobian(&ModelParameters::k_distance, false);
  const SparseMatrix area = unit_jacobian(&ModelParameters::k_area, false);
  const SparseMatrix angle = unit_jacobian(&ModelParameters::k_angle, false);
  const SparseMatrix damping = unit_jacobian(&ModelParameters::k_damping, true);

  // Renumber the unknowns by approximate minimum degree over the union of
  // the patterns (and the diagonal), so the factor stays sparse.
  SparseMatrix identity(m, m);
  identity.setIdentity();
  const SparseMatrix pattern = distance.cwiseAbs() + area.cwiseAbs() + angle.cwiseAbs() +
                               damping.cwiseAbs() + identity;
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse_order;
  Eigen::AMDOrdering<int>()(pattern, inverse_order);
  const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order =
      inverse_order.inverse();
  const auto renumbered = [&](int k) { return order.indices()[k]; };
  coordinate_of_unknown_.assign(m, 0);
  for (int k = 0; k < m; ++k) coordinate_of_unknown_[renumbered(k)] = coordinate_of_unknown[k];

  // A's lower triangle in the new numbering, then each unit matrix's values
  // at A's storage positions.
  std::vector<Triplet> lower;
  for (int col = 0; col < m; ++col) {
    for (SparseMatrix::InnerIterator it(pattern, col); it; ++it) {
      const int r = renumbered(static_cast<int>(it.row())), c = renumbered(col);
      if (r >= c) lower.emplace_back(r, c, 0.0);
    }
  }
  A_.resize(m, m);
  A_.setFromTriplets(lower.begin(), lower.end());
  A_.makeCompressed();
  const auto position = [&](int r, int c) {
    const int* begin = A_.innerIndexPtr() + A_.outerIndexPtr()[c];
    const int* end = A_.innerIndexPtr() + A_.outerIndexPtr()[c + 1];
    return static_cast<int>(std::lower_bound(begin, end, r) - A_.innerIndexPtr());
  };
  const auto values_on_pattern = [&](const SparseMatrix& unit_matrix) {
    std::vector<double> values(A_.nonZeros(), 0.0);
    for (int col = 0; col < m; ++col) {
      for (SparseMatrix::InnerIterator it(unit_matrix, col); it; ++it) {
        const int r = renumbered(static_cast<int>(it.row())), c = renumbered(col);
        if (r >= c) values[position(r, c)] = it.value();
      }
    }
    return values;
  };
  distance_ = values_on_pattern(distance);
  area_ = values_on_pattern(area);
  angle_ = values_on_pattern(angle);
  damping_ = values_on_pattern(damping);
  diagonal_.resize(m);
  for (int k = 0; k < m; ++k) diagonal_[k] = position(k, k);

  factor_.analyzePattern(A_);
  rhs_.setZero(m);
  solution_.setZero(m);
}

bool ImplicitFirstOrderStep::Configure(const ModelParameters& params, double h,
                                       std::string* error) {
  double* a = A_.valuePtr();
  const double damping_over_h = params.k_damping / h;
  for (size_t p = 0; p < distance_.size(); ++p) {
    a[p] = params.k_distance * distance_[p] + params.k_area * area_[p] +
           params.k_angle * angle_[p] + damping_over_h * damping_[p];
  }
  const double mass_over_h = params.mass / h;
  h_over_m_ = h / params.mass;
  for (int p : diagonal_) a[p] += mass_over_h;
  if (A_.rows() == 0) return true;
  factor_.factorize(A_);
  if (factor_.info() != Eigen::Success || !(factor_.vectorD().minCoeff() > 0.0)) {
    if (error != nullptr) {
      *error = fmt::format(
          "implicit first-order step: m / h + K0 + k_d / h D0 is not positive definite "
          "(k_distance = {}, k_area = {}, k_angle = {}, k_damping = {}, mass = {}, h = {})",
          params.k_distance, params.k_area, params.k_angle, params.k_damping, params.mass, h);
    }
    return false;
  }
  return true;
}

void ImplicitFirstOrderStep::Step(std::span<const Vec2> f, std::span<Vec2> x) {
  const int m = num_unknowns();
  if (m == 0) return;
  // The free turn at the current shape: t_i = perp(x_i - pivot) over the
  // movable nodes (centred on their centroid for an unclamped mesh, hence
  // orthogonal to the translations). Its share of f moves the body as the
  // explicit step does; the rest is solved and keeps no turn.
  double turn_rate = 0.0, turn_norm_sq = 0.0;
  Vec2 pivot = Vec2::Zero();
  const size_t n = x.size();
  const auto turn = [&](size_t i) {
    const Vec2 r = x[i] - pivot;
    return Vec2(-r.y(), r.x());
  };
  if (free_turn_ != FreeTurn::kNone) {
    if (free_turn_ == FreeTurn::kPivot) {
      pivot = x[pivot_];
    } else {
      for (size_t i = 0; i < n; ++i) pivot += x[i];
      pivot /= static_cast<double>(n);
    }
    for (size_t i = 0; i < n; ++i) {
      if (movable_[i] == 0.0) continue;
      const Vec2 t = turn(i);
      turn_rate += f[i].dot(t);
      turn_norm_sq += t.squaredNorm();
    }
    turn_rate = turn_norm_sq > 0.0 ? turn_rate / turn_norm_sq : 0.0;
  }
  for (int k = 0; k < m; ++k) {
    const int c = coordinate_of_unknown_[k];
    const size_t i = static_cast<size_t>(c / 2);
    rhs_[k] = f[i][c % 2] - (turn_rate != 0.0 ? turn_rate * turn(i)[c % 2] : 0.0);
  }
  solution_ = factor_.solve(rhs_);
  double solved_turn = 0.0;
  if (turn_norm_sq > 0.0) {
    for (int k = 0; k < m; ++k) {
      const int c = coordinate_of_unknown_[k];
      solved_turn += solution_[k] * turn(static_cast<size_t>(c / 2))[c % 2];
    }
    solved_turn /= turn_norm_sq;
  }
  // The turn field is that of the positions before the step: add the kept
  // turn to the solution first, then move the nodes.
  if (turn_norm_sq > 0.0) {
    const double kept_turn = h_over_m_ * turn_rate - solved_turn;
    for (int k = 0; k < m; ++k) {
      const int c = coordinate_of_unknown_[k];
      solution_[k] += kept_turn * turn(static_cast<size_t>(c / 2))[c % 2];
    }
  }
  for (int k = 0; k < m; ++k) {
    const int c = coordinate_of_unknown_[k];
    x[c / 2][c % 2] += solution_[k];
  }
}

Eigen::SparseMatrix<double> ImplicitFirstOrderStep::Stiffness(const ModelParameters& params) const {
  const int m = num_unknowns();
  std::vector<Triplet> entries;
  for (int col = 0; col < m; ++col) {
    for (int p = A_.outerIndexPtr()[col]; p < A_.outerIndexPtr()[col + 1]; ++p) {
      const int row = A_.innerIndexPtr()[p];
      const double value = params.k_distance * distance_[p] + params.k_area * area_[p] +
                           params.k_angle * angle_[p];
      if (value == 0.0) continue;
      const int r = coordinate_of_unknown_[row], c = coordinate_of_unknown_[col];
      entries.emplace_back(r, c, value);
      if (r != c) entries.emplace_back(c, r, value);
    }
  }
  SparseMatrix stiffness(num_coordinates_, num_coordinates_);
  stiffness.setFromTriplets(entries.begin(), entries.end());
  return stiffness;
}

}  // namespace calib
