#include "calib/core/implicit_assembly.h"

#include <Eigen/OrderingMethods>
#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

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

ImplicitStepAssembly::ImplicitStepAssembly(const Model& model, std::span<const double> movable,
                                           bool edge_stiffness) {
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
  SparseMatrix pattern = distance.cwiseAbs() + area.cwiseAbs() + angle.cwiseAbs() +
                         damping.cwiseAbs() + identity;
  const Mesh& mesh = model.mesh();
  if (edge_stiffness) {
    // Every edge's node blocks, whatever the unit matrices' exact zeros.
    std::vector<Triplet> blocks;
    for (const auto& [i, j] : mesh.edges) {
      for (int a : {2 * i, 2 * i + 1, 2 * j, 2 * j + 1}) {
        for (int b : {2 * i, 2 * i + 1, 2 * j, 2 * j + 1}) {
          const int r = unknown_of_coordinate[a], c = unknown_of_coordinate[b];
          if (r >= 0 && c >= 0) blocks.emplace_back(r, c, 1.0);
        }
      }
    }
    SparseMatrix edge_pattern(m, m);
    edge_pattern.setFromTriplets(blocks.begin(), blocks.end());
    pattern += edge_pattern;
  }
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
  if (edge_stiffness) {
    upper_ = A_.transpose();
    upper_.makeCompressed();
    const auto upper_position = [&](int r, int c) {  // r <= c, on the pattern
      const int* begin = upper_.innerIndexPtr() + upper_.outerIndexPtr()[c];
      const int* end = upper_.innerIndexPtr() + upper_.outerIndexPtr()[c + 1];
      const int* found = std::lower_bound(begin, end, r);
      if (found == end || *found != r) {
        throw std::logic_error(fmt::format("implicit step: entry ({}, {}) is not on the pattern", r, c));
      }
      return static_cast<int>(found - upper_.innerIndexPtr());
    };
    upper_of_lower_.resize(A_.nonZeros());
    for (int c = 0; c < m; ++c) {
      for (int p = A_.outerIndexPtr()[c]; p < A_.outerIndexPtr()[c + 1]; ++p) {
        upper_of_lower_[p] = upper_position(c, A_.innerIndexPtr()[p]);
      }
    }
    const auto entry = [&](int coordinate_a, int coordinate_b) {
      const int a = unknown_of_coordinate[coordinate_a], b = unknown_of_coordinate[coordinate_b];
      if (a < 0 || b < 0) return -1;
      const int r = renumbered(a), c = renumbered(b);
      return upper_position(std::min(r, c), std::max(r, c));
    };
    edge_positions_.reserve(mesh.edges.size());
    for (const auto& [i, j] : mesh.edges) {
      const int ix = 2 * i, iy = 2 * i + 1, jx = 2 * j, jy = 2 * j + 1;
      edge_positions_.push_back({entry(ix, ix), entry(iy, iy), entry(ix, iy), entry(jx, jx),
                                 entry(jy, jy), entry(jx, jy), entry(ix, jx), entry(ix, jy),
                                 entry(iy, jx), entry(iy, jy)});
    }
    configured_.assign(A_.nonZeros(), 0.0);
  }

  // For the extra forces' stiffness: each column's rows over the whole
  // (symmetric) pattern with the position of their lower-triangle entry,
  // and colour groups of columns that share no row (greedy), probed
  // together.
  std::vector<int> count(m + 1, 0);
  for (int col = 0; col < m; ++col) count[renumbered(col) + 1] += static_cast<int>(
      pattern.outerIndexPtr()[col + 1] - pattern.outerIndexPtr()[col]);
  for (int k = 0; k < m; ++k) count[k + 1] += count[k];
  row_begin_ = count;
  rows_.resize(count[m]);
  row_position_.resize(count[m]);
  for (int col = 0; col < m; ++col) {
    const int c = renumbered(col);
    int slot = row_begin_[c];
    for (SparseMatrix::InnerIterator it(pattern, col); it; ++it, ++slot) {
      const int r = renumbered(static_cast<int>(it.row()));
      rows_[slot] = r;
      row_position_[slot] = position(std::max(r, c), std::min(r, c));
    }
  }
  std::vector<int> colour_of(m, -1);
  std::vector<std::vector<uint8_t>> row_taken;  // per colour
  for (int k = 0; k < m; ++k) {
    for (int colour = 0; colour_of[k] < 0; ++colour) {
      if (colour == static_cast<int>(row_taken.size())) row_taken.emplace_back(m, 0);
      std::vector<uint8_t>& taken = row_taken[colour];
      bool free = true;
      for (int i = row_begin_[k]; i < row_begin_[k + 1] && free; ++i) free = taken[rows_[i]] == 0;
      if (!free) continue;
      for (int i = row_begin_[k]; i < row_begin_[k + 1]; ++i) taken[rows_[i]] = 1;
      colour_of[k] = colour;
    }
  }
  colour_begin_.assign(row_taken.size() + 1, 0);
  for (int k = 0; k < m; ++k) ++colour_begin_[colour_of[k] + 1];
  for (size_t g = 0; g + 1 < colour_begin_.size(); ++g) colour_begin_[g + 1] += colour_begin_[g];
  coloured_unknowns_.resize(m);
  {
    std::vector<int> cursor(colour_begin_.begin(), colour_begin_.end() - 1);
    for (int k = 0; k < m; ++k) coloured_unknowns_[cursor[colour_of[k]]++] = k;
  }
  extra_.assign(A_.nonZeros(), 0.0);
  rest_ = model.mesh().rest_positions;
  probe_x_ = rest_;
  probe_plus_.assign(rest_.size(), Vec2::Zero());
  probe_minus_.assign(rest_.size(), Vec2::Zero());

  unknown_of_coordinate_.assign(2 * static_cast<size_t>(n), -1);
  for (int k = 0; k < m; ++k) unknown_of_coordinate_[coordinate_of_unknown_[k]] = k;
}

void ImplicitStepAssembly::ProbeExtraStiffness(const ExtraForces& extra) {
  std::fill(extra_.begin(), extra_.end(), 0.0);
  std::copy(rest_.begin(), rest_.end(), probe_x_.begin());
  // The forces with the group's coordinates at rest + offset (0: back at
  // rest).
  const auto evaluate = [&](double offset, size_t g, std::vector<Vec2>* f) {
    for (int i = colour_begin_[g]; i < colour_begin_[g + 1]; ++i) {
      const int c = coordinate_of_unknown_[coloured_unknowns_[i]];
      probe_x_[c / 2][c % 2] = rest_[c / 2][c % 2] + offset;
    }
    if (f == nullptr) return;
    std::fill(f->begin(), f->end(), Vec2::Zero());
    extra(probe_x_, *f);
  };
  for (size_t g = 0; g + 1 < colour_begin_.size(); ++g) {
    evaluate(kStiffnessProbePx, g, &probe_plus_);
    evaluate(-kStiffnessProbePx, g, &probe_minus_);
    evaluate(0.0, g, nullptr);
    // The group's columns share no row: each row's change belongs to one
    // column. Symmetrised as the unit matrices are: half of each
    // off-diagonal entry from either side.
    for (int i = colour_begin_[g]; i < colour_begin_[g + 1]; ++i) {
      const int k = coloured_unknowns_[i];
      for (int j = row_begin_[k]; j < row_begin_[k + 1]; ++j) {
        const int r = rows_[j];
        const int c = coordinate_of_unknown_[r];
        const double value =
            (probe_minus_[c / 2][c % 2] - probe_plus_[c / 2][c % 2]) / (2.0 * kStiffnessProbePx);
        extra_[row_position_[j]] += r == k ? value : 0.5 * value;
      }
    }
  }
}

void ImplicitStepAssembly::Assemble(const ModelParameters& params, double h,
                                    const ExtraForces* extra) {
  double* a = A_.valuePtr();
  const double damping_over_h = params.k_damping / h;
  for (size_t p = 0; p < distance_.size(); ++p) {
    a[p] = params.k_distance * distance_[p] + params.k_area * area_[p] +
           params.k_angle * angle_[p] + damping_over_h * damping_[p];
  }
  has_extra_ = extra != nullptr && *extra;
  if (has_extra_) {
    ProbeExtraStiffness(*extra);
    for (size_t p = 0; p < extra_.size(); ++p) a[p] += extra_[p];
  }
  const double mass_over_h = params.mass / h;
  for (int p : diagonal_) a[p] += mass_over_h;
  if (!configured_.empty()) std::copy(a, a + configured_.size(), configured_.begin());
}

void ImplicitStepAssembly::BeginShapeStiffness() {
  double* upper = upper_.valuePtr();
  for (size_t p = 0; p < configured_.size(); ++p) upper[upper_of_lower_[p]] = configured_[p];
}

void ImplicitStepAssembly::AddEdgeStiffness(int edge, double k, const Vec2& u) {
  const std::array<int, 10>& p = edge_positions_[edge];
  double* a = upper_.valuePtr();
  const double xx = k * u.x() * u.x(), yy = k * u.y() * u.y(), xy = k * u.x() * u.y();
  const double block[10] = {xx, yy, xy, xx, yy, xy, -xx, -xy, -xy, -yy};
  for (int t = 0; t < 10; ++t) {
    if (p[t] >= 0) a[p[t]] += block[t];
  }
}

template <class Value>
SparseMatrix ImplicitStepAssembly::OverCoordinates(Value value) const {
  std::vector<Triplet> entries;
  for (int col = 0; col < num_unknowns(); ++col) {
    for (int p = A_.outerIndexPtr()[col]; p < A_.outerIndexPtr()[col + 1]; ++p) {
      const double v = value(p);
      if (v == 0.0) continue;
      const int r = coordinate_of_unknown_[A_.innerIndexPtr()[p]], c = coordinate_of_unknown_[col];
      entries.emplace_back(r, c, v);
      if (r != c) entries.emplace_back(c, r, v);
    }
  }
  SparseMatrix matrix(num_coordinates_, num_coordinates_);
  matrix.setFromTriplets(entries.begin(), entries.end());
  return matrix;
}

SparseMatrix ImplicitStepAssembly::Stiffness(const ModelParameters& params) const {
  return OverCoordinates([&](int p) {
    return params.k_distance * distance_[p] + params.k_area * area_[p] + params.k_angle * angle_[p];
  });
}

SparseMatrix ImplicitStepAssembly::ExtraStiffness() const {
  return OverCoordinates([&](int p) { return has_extra_ ? extra_[p] : 0.0; });
}

}  // namespace calib
