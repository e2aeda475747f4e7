#include "calib/core/implicit_step.h"

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

ImplicitFirstOrderStep::ImplicitFirstOrderStep(const Model& model, std::span<const double> movable,
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
    shape_factor_.analyzePattern(upper_);
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

  factor_.analyzePattern(A_);
  rhs_.setZero(m);
  solution_.setZero(m);
  turn_.setZero(m);
  inverse_turn_.setZero(m);
  step_.setZero(m);
  column_.setZero(m);
  inverse_column_of_unknown_.assign(m, -1);
  inverse_columns_.reserve(static_cast<size_t>(m) *
                           std::min(m, 4 * kMaxActiveContacts));  // a finger's and a pencil's
  normal_response_.setZero(m, kMaxActiveContacts);
  tangent_response_.setZero(m, kMaxActiveContacts);
}

void ImplicitFirstOrderStep::ProbeExtraStiffness(const ExtraForces& extra) {
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

bool ImplicitFirstOrderStep::Configure(const ModelParameters& params, double h,
                                       const ExtraForces* extra, std::string* error) {
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
  h_over_m_ = h / params.mass;
  for (int p : diagonal_) a[p] += mass_over_h;
  if (!configured_.empty()) std::copy(a, a + configured_.size(), configured_.begin());
  configured_params_ = params;
  configured_h_ = h;
  ForgetSolves();
  shape_active_ = false;
  if (A_.rows() == 0) return true;
  factor_.factorize(A_);
  return Factorized(factor_, params, h, error);
}

void ImplicitFirstOrderStep::ForgetSolves() {
  std::fill(inverse_column_of_unknown_.begin(), inverse_column_of_unknown_.end(), -1);
  inverse_columns_.clear();
  inverse_turn_valid_ = false;
}

template <class Factor>
bool ImplicitFirstOrderStep::Factorized(const Factor& factor, const ModelParameters& params,
                                        double h, std::string* error) const {
  if (factor.info() == Eigen::Success && factor.vectorD().minCoeff() > 0.0) return true;
  if (error != nullptr) {
    *error = fmt::format(
        "implicit first-order step: m / h + K0 + k_d / h D0 is not positive definite "
        "(k_distance = {}, k_area = {}, k_angle = {}, k_damping = {}, mass = {}, h = {}{})",
        params.k_distance, params.k_area, params.k_angle, params.k_damping, params.mass, h,
        has_extra_ ? "; with the effects' stiffness" : "");
  }
  return false;
}

void ImplicitFirstOrderStep::BeginShapeStiffness() {
  double* upper = upper_.valuePtr();
  for (size_t p = 0; p < configured_.size(); ++p) upper[upper_of_lower_[p]] = configured_[p];
}

void ImplicitFirstOrderStep::AddEdgeStiffness(int edge, double k, const Vec2& u) {
  const std::array<int, 10>& p = edge_positions_[edge];
  double* a = upper_.valuePtr();
  const double xx = k * u.x() * u.x(), yy = k * u.y() * u.y(), xy = k * u.x() * u.y();
  const double block[10] = {xx, yy, xy, xx, yy, xy, -xx, -xy, -xy, -yy};
  for (int t = 0; t < 10; ++t) {
    if (p[t] >= 0) a[p[t]] += block[t];
  }
}

bool ImplicitFirstOrderStep::FinishShapeStiffness(std::string* error) {
  ForgetSolves();
  shape_active_ = true;
  if (upper_.rows() == 0) return true;
  shape_factor_.factorize(upper_);
  if (!Factorized(shape_factor_, configured_params_, configured_h_, error)) {
    if (error != nullptr) *error += " with the springs' stiffness at the current shape";
    return false;
  }
  return true;
}

namespace {

Vec2 Tangent(const Vec2& normal) { return Vec2(-normal.y(), normal.x()); }

}  // namespace

void ImplicitFirstOrderStep::SetTurn(std::span<const Vec2> x) {
  turn_.setZero();
  turn_norm_sq_ = 0.0;
  if (free_turn_ == FreeTurn::kNone) return;
  // t_i = perp(x_i - pivot) over the movable nodes (centred on their
  // centroid for an unclamped mesh, hence orthogonal to the translations).
  Vec2 pivot = Vec2::Zero();
  if (free_turn_ == FreeTurn::kPivot) {
    pivot = x[pivot_];
  } else {
    for (const Vec2& p : x) pivot += p;
    pivot /= static_cast<double>(x.size());
  }
  for (int k = 0; k < num_unknowns(); ++k) {
    const int c = coordinate_of_unknown_[k];
    const Vec2 r = x[c / 2] - pivot;
    turn_[k] = c % 2 == 0 ? -r.y() : r.x();
  }
  turn_norm_sq_ = turn_.squaredNorm();
}

void ImplicitFirstOrderStep::FinishResponse(double g_dot_turn, Eigen::Ref<Eigen::VectorXd> y) const {
  if (!(turn_norm_sq_ > 0.0)) return;
  // y solves for the force without its turn; the body turns by h / m times
  // the turn's share instead of y's own turn (the turn field is that of the
  // positions before the step).
  const double turn_rate = g_dot_turn / turn_norm_sq_;
  const double solved_turn = y.dot(turn_) / turn_norm_sq_;
  y += (h_over_m_ * turn_rate - solved_turn) * turn_;
}

void ImplicitFirstOrderStep::Step(std::span<const Vec2> f, std::span<Vec2> x,
                                  std::span<const StepContact> contacts, double friction) {
  const int m = num_unknowns();
  if (m == 0) return;
  SetTurn(x);
  for (int k = 0; k < m; ++k) {
    const int c = coordinate_of_unknown_[k];
    rhs_[k] = f[c / 2][c % 2];
  }
  const double f_dot_turn = turn_norm_sq_ > 0.0 ? rhs_.dot(turn_) : 0.0;
  if (f_dot_turn != 0.0) rhs_ -= (f_dot_turn / turn_norm_sq_) * turn_;
  Solve(rhs_, solution_);
  FinishResponse(f_dot_turn, solution_);
  const Eigen::VectorXd* dx = &solution_;
  if (!contacts.empty()) {
    ContactSolve(contacts, friction);
    dx = &step_;
  }
  for (int k = 0; k < m; ++k) {
    const int c = coordinate_of_unknown_[k];
    x[c / 2][c % 2] += (*dx)[k];
  }
}

const double* ImplicitFirstOrderStep::InverseColumn(int unknown) {
  const size_t m = static_cast<size_t>(num_unknowns());
  int& slot = inverse_column_of_unknown_[unknown];
  if (slot < 0) {
    slot = static_cast<int>(inverse_columns_.size() / m);
    inverse_columns_.resize(inverse_columns_.size() + m);
    rhs_.setZero();  // free once the step's own solve is done
    rhs_[unknown] = 1.0;
    Solve(rhs_, Eigen::Map<Eigen::VectorXd>(inverse_columns_.data() + slot * m, m));
  }
  return inverse_columns_.data() + slot * m;
}

template <class Visit>
void ImplicitFirstOrderStep::ForEachUnknown(const StepContact& contact, const Vec2& direction,
                                            Visit&& visit) const {
  // The contact point's coordinates along `direction`: (unknown, weight x
  // direction component), clamped nodes skipped.
  for (int q = 0; q < 2; ++q) {
    const int node = contact.nodes[q];
    if (node < 0) continue;
    for (int d = 0; d < 2; ++d) {
      const int k = unknown_of_coordinate_[2 * node + d];
      const double g = contact.weights[q] * direction[d];
      if (k >= 0 && g != 0.0) visit(k, g);
    }
  }
}

void ImplicitFirstOrderStep::ResponseOf(const StepContact& contact, const Vec2& direction,
                                        Eigen::Ref<Eigen::VectorXd> out) {
  // A^-1 of the unit force along `direction` at the contact point, from the
  // cached columns, less A^-1 of its turn: then as any force.
  const int m = num_unknowns();
  out.setZero();
  double g_dot_turn = 0.0;
  ForEachUnknown(contact, direction, [&](int k, double g) {
    out += g * Eigen::Map<const Eigen::VectorXd>(InverseColumn(k), m);
    g_dot_turn += g * turn_[k];
  });
  if (turn_norm_sq_ > 0.0 && g_dot_turn != 0.0) {
    if (!inverse_turn_valid_) {
      Solve(turn_, inverse_turn_);
      inverse_turn_valid_ = true;
    }
    out -= (g_dot_turn / turn_norm_sq_) * inverse_turn_;
  }
  FinishResponse(g_dot_turn, out);
}

double ImplicitFirstOrderStep::Along(const StepContact& contact, const Vec2& direction,
                                     const Eigen::VectorXd& dx) const {
  double along = 0.0;
  ForEachUnknown(contact, direction, [&](int k, double g) { along += g * dx[k]; });
  return along;
}

namespace {

// A contact is broken, or slides against its friction, by more than this.
constexpr double kContactTolerancePx = 1e-9;

}  // namespace

void ImplicitFirstOrderStep::ContactSolve(std::span<const StepContact> contacts, double friction) {
  // Active set: start from the free step; add the contacts it breaks (held
  // as sticking when there is friction), solve for their forces, release a
  // contact that pulls, let a sticking contact slide whose tangential force
  // exceeds mu times its normal one and stop a sliding one that moves with
  // its friction; repeat until nothing changes. Each round's system has one
  // row per active contact's normal and per sticking contact's tangent.
  const int num_contacts = static_cast<int>(contacts.size());
  active_.clear();
  active_of_contact_.assign(num_contacts, -1);
  excluded_.assign(num_contacts, 0);
  inverse_turn_valid_ = false;
  step_ = solution_;
  const auto tangent_target = [&](const StepContact& c) {
    return Tangent(c.normal).dot(c.obstacle_step);
  };
  const auto remove = [&](int a) {
    for (int b = a; b + 1 < static_cast<int>(active_.size()); ++b) {
      active_[b] = active_[b + 1];
      normal_response_.col(b) = normal_response_.col(b + 1);
      tangent_response_.col(b) = tangent_response_.col(b + 1);
    }
    active_.pop_back();
  };
  const int max_rounds = 4 * kMaxActiveContacts;
  for (int round = 0; round < max_rounds; ++round) {
    bool changed = false;
    for (int j = 0; j < num_contacts; ++j) {
      if (active_of_contact_[j] >= 0 || excluded_[j] != 0) continue;
      if (static_cast<int>(active_.size()) == kMaxActiveContacts) break;
      const StepContact& c = contacts[j];
      if (!(Along(c, c.normal, step_) - c.gap < -kContactTolerancePx)) continue;
      const int a = static_cast<int>(active_.size());
      active_.push_back(ActiveContact{j, friction > 0.0, 0.0, 0.0, 0.0});
      active_of_contact_[j] = a;
      ResponseOf(c, c.normal, normal_response_.col(a));
      if (friction > 0.0) ResponseOf(c, Tangent(c.normal), tangent_response_.col(a));
      changed = true;
    }
    if (!changed) {
      // The contact pulling hardest is released.
      int pulling = -1;
      for (int a = 0; a < static_cast<int>(active_.size()); ++a) {
        if (active_[a].normal_force < 0.0 &&
            (pulling < 0 || active_[a].normal_force < active_[pulling].normal_force)) {
          pulling = a;
        }
      }
      if (pulling >= 0) {
        active_of_contact_[active_[pulling].contact] = -1;
        remove(pulling);
        changed = true;
      }
    }
    if (!changed && friction > 0.0) {
      for (ActiveContact& a : active_) {
        const StepContact& c = contacts[a.contact];
        if (a.stick && std::abs(a.tangent_force) > friction * a.normal_force) {
          a.stick = false;
          a.slip_sign = a.tangent_force > 0.0 ? 1.0 : -1.0;
          changed = true;
        } else if (!a.stick &&
                   a.slip_sign * (Along(c, Tangent(c.normal), step_) - tangent_target(c)) >
                       kContactTolerancePx) {
          a.stick = true;  // it would slide the way its friction pushes
          changed = true;
        }
      }
    }
    if (!changed) break;
    // A contact that repeats others (a node and the edge through it) makes
    // the system singular: the newest is left to the projections.
    while (!SolveActive(contacts, friction)) {
      const int last = static_cast<int>(active_.size()) - 1;
      excluded_[active_[last].contact] = 1;
      active_of_contact_[active_[last].contact] = -1;
      remove(last);
    }
  }
}

bool ImplicitFirstOrderStep::SolveActive(std::span<const StepContact> contacts, double friction) {
  const int k = static_cast<int>(active_.size());
  step_ = solution_;
  if (k == 0) return true;
  for (int a = 0; a < k; ++a) active_of_contact_[active_[a].contact] = a;
  // Unknowns: each active contact's normal force, then each sticking
  // contact's tangential force. A sliding contact's friction is slip_sign
  // mu times its normal force, so its normal force's column carries it.
  int rows = k;
  for (int a = 0; a < k; ++a) tangent_row_[a] = active_[a].stick ? rows++ : -1;
  const auto column = [&](int unknown) {
    if (unknown < k) {
      column_ = normal_response_.col(unknown);
      const ActiveContact& a = active_[unknown];
      if (!a.stick && friction > 0.0) {
        column_ += (a.slip_sign * friction) * tangent_response_.col(unknown);
      }
    } else {
      int a = 0;
      while (tangent_row_[a] != unknown) ++a;
      column_ = tangent_response_.col(a);
    }
  };
  system_.resize(rows, rows);
  system_rhs_.resize(rows);
  for (int a = 0; a < k; ++a) {
    const StepContact& c = contacts[active_[a].contact];
    system_rhs_[a] = c.gap - Along(c, c.normal, solution_);
    if (tangent_row_[a] >= 0) {
      const Vec2 t = Tangent(c.normal);
      system_rhs_[tangent_row_[a]] = t.dot(c.obstacle_step) - Along(c, t, solution_);
    }
  }
  for (int u = 0; u < rows; ++u) {
    column(u);
    for (int a = 0; a < k; ++a) {
      const StepContact& c = contacts[active_[a].contact];
      system_(a, u) = Along(c, c.normal, column_);
      if (tangent_row_[a] >= 0) system_(tangent_row_[a], u) = Along(c, Tangent(c.normal), column_);
    }
  }
  lu_.compute(system_);
  if (!lu_.isInvertible()) return false;
  forces_ = lu_.solve(system_rhs_);
  for (int u = 0; u < rows; ++u) {
    column(u);
    step_ += forces_[u] * column_;
  }
  for (int a = 0; a < k; ++a) {
    ActiveContact& active = active_[a];
    active.normal_force = forces_[a];
    active.tangent_force =
        active.stick ? forces_[tangent_row_[a]] : active.slip_sign * friction * forces_[a];
  }
  return true;
}

template <class Value>
Eigen::SparseMatrix<double> ImplicitFirstOrderStep::OverCoordinates(Value value) const {
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

Eigen::SparseMatrix<double> ImplicitFirstOrderStep::Stiffness(const ModelParameters& params) const {
  return OverCoordinates([&](int p) {
    return params.k_distance * distance_[p] + params.k_area * area_[p] + params.k_angle * angle_[p];
  });
}

Eigen::SparseMatrix<double> ImplicitFirstOrderStep::ExtraStiffness() const {
  return OverCoordinates([&](int p) { return has_extra_ ? extra_[p] : 0.0; });
}

}  // namespace calib
