#include "calib/core/implicit_step.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace calib {

ImplicitFirstOrderStep::ImplicitFirstOrderStep(const Model& model, std::span<const double> movable,
                                               bool edge_stiffness)
    : assembly_(model, movable, edge_stiffness),
      contacts_(assembly_.unknown_of_coordinate(), assembly_.num_unknowns()) {
  const int n = static_cast<int>(movable.size());
  const int m = assembly_.num_unknowns();
  int num_clamped = 0;
  for (int i = 0; i < n; ++i) {
    if (movable[i] != 0.0) continue;
    ++num_clamped;
    pivot_ = i;
  }
  free_turn_ = num_clamped == 0 ? FreeTurn::kFree
               : num_clamped == 1 ? FreeTurn::kPivot
                                  : FreeTurn::kNone;

  if (edge_stiffness) {
    const SparseMatrix& upper = assembly_.upper();
    shape_factor_.Analyse(upper);
    factorised_upper_.assign(upper.nonZeros(), 0.0);
    row_change_.assign(upper.rows(), 0.0);
    upper_diagonal_.assign(upper.rows(), -1);
    for (int k = 0; k < upper.outerSize(); ++k) {
      for (SparseMatrix::InnerIterator it(upper, k); it; ++it) {
        if (it.index() == k) upper_diagonal_[k] = static_cast<int>(&it.value() - upper.valuePtr());
      }
    }
  }
  factor_.analyzePattern(assembly_.lower());
  rhs_.setZero(m);
  solution_.setZero(m);
  turn_.setZero(m);
  inverse_turn_.setZero(m);
  solve_scratch_.assign(2 * static_cast<size_t>(m), 0.0);
  inverse_column_of_unknown_.assign(m, -1);
  column_dot_turn_.assign(m, 0.0);
  column_dot_turn_stamp_.assign(m, 0);
  inverse_columns_.reserve(static_cast<size_t>(m) *
                           std::min(m, 4 * kMaxActiveContacts));  // a finger's and a pencil's
}

bool ImplicitFirstOrderStep::Configure(const ModelParameters& params, double h,
                                       const ExtraForces* extra, std::string* error) {
  assembly_.Assemble(params, h, extra);
  h_over_m_ = h / params.mass;
  configured_params_ = params;
  configured_h_ = h;
  ForgetSolves();
  factor_view_ = {};
  if (assembly_.lower().rows() == 0) return true;
  factor_.factorize(assembly_.lower());
  shape_factorizations_ = 0;
  if (!factorised_upper_.empty()) {
    // The configured matrix is the one factorised, until a shape moves it.
    assembly_.BeginShapeStiffness();
    const double* upper = assembly_.upper().valuePtr();
    std::copy(upper, upper + factorised_upper_.size(), factorised_upper_.begin());
  }
  const bool ok = factor_.info() == Eigen::Success && factor_.vectorD().minCoeff() > 0.0;
  return Factorized(ok, ok ? ldlt::ViewOf(factor_, &factor_extras_) : ldlt::FactorView{}, params, h,
                    error);
}

void ImplicitFirstOrderStep::ForgetSolves() {
  std::fill(inverse_column_of_unknown_.begin(), inverse_column_of_unknown_.end(), -1);
  inverse_columns_.clear();
  inverse_turn_valid_ = false;
}

bool ImplicitFirstOrderStep::Factorized(bool ok, const ldlt::FactorView& view,
                                        const ModelParameters& params, double h,
                                        std::string* error) {
  if (ok) {
    factor_view_ = view;
    return true;
  }
  factor_view_ = {};
  if (error != nullptr) {
    *error = fmt::format(
        "implicit first-order step: m / h + K0 + k_d / h D0 is not positive definite "
        "(k_distance = {}, k_area = {}, k_angle = {}, k_damping = {}, mass = {}, h = {}{})",
        params.k_distance, params.k_area, params.k_angle, params.k_damping, params.mass, h,
        assembly_.has_extra() ? "; with the effects' stiffness" : "");
  }
  return false;
}

double ImplicitFirstOrderStep::ShapeChange() {
  const SparseMatrix& upper = assembly_.upper();
  const int* outer = upper.outerIndexPtr();
  const int* inner = upper.innerIndexPtr();
  const double* value = upper.valuePtr();
  std::fill(row_change_.begin(), row_change_.end(), 0.0);
  for (int k = 0; k < upper.outerSize(); ++k) {
    for (int p = outer[k]; p < outer[k + 1]; ++p) {
      const double change = std::abs(value[p] - factorised_upper_[p]);
      row_change_[inner[p]] += change;
      if (inner[p] != k) row_change_[k] += change;  // the symmetric entry
    }
  }
  double largest = 0.0;
  for (size_t i = 0; i < row_change_.size(); ++i) {
    const double relative = row_change_[i] / factorised_upper_[upper_diagonal_[i]];
    if (std::isnan(relative)) return relative;  // refactorised, and refused
    largest = std::max(largest, relative);
  }
  return largest;
}

bool ImplicitFirstOrderStep::FinishShapeStiffness(std::string* error) {
  if (assembly_.upper().rows() == 0) return true;
  // The factor in use is that of the matrix factorised last (the
  // configured one, or a shape's); it stays while the matrix moved little.
  if (factor_view_.n > 0 && ShapeChange() <= shape_tolerance_) return true;
  ForgetSolves();
  factor_view_ = {};
  ++shape_factorizations_;
  const double* upper = assembly_.upper().valuePtr();
  std::copy(upper, upper + factorised_upper_.size(), factorised_upper_.begin());
  const bool ok = shape_factor_.Factorize(assembly_.upper());
  if (!Factorized(ok, shape_factor_.view(), configured_params_, configured_h_, error)) {
    if (error != nullptr) *error += " with the springs' stiffness at the current shape";
    return false;
  }
  return true;
}

void ImplicitFirstOrderStep::SetTurn(std::span<const Vec2> x) {
  ++step_stamp_;  // the turn's dot products are this step's
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
  const std::span<const int> coordinate_of_unknown = assembly_.coordinate_of_unknown();
  for (int k = 0; k < num_unknowns(); ++k) {
    const int c = coordinate_of_unknown[k];
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
  const std::span<const int> coordinate_of_unknown = assembly_.coordinate_of_unknown();
  SetTurn(x);
  for (int k = 0; k < m; ++k) {
    const int c = coordinate_of_unknown[k];
    rhs_[k] = f[c / 2][c % 2];
  }
  const double f_dot_turn = turn_norm_sq_ > 0.0 ? rhs_.dot(turn_) : 0.0;
  if (f_dot_turn != 0.0) rhs_ -= (f_dot_turn / turn_norm_sq_) * turn_;
  solution_ = rhs_;
  if (!contacts.empty() && turn_norm_sq_ > 0.0) {
    // The contacts' responses need A^-1 turn_ for this step's turn: solved
    // beside the step's own right-hand side, in one pass.
    inverse_turn_ = turn_;
    ldlt::SolveInPlace2(factor_view_, solution_.data(), inverse_turn_.data(),
                        solve_scratch_.data());
    inverse_turn_valid_ = true;
  } else {
    ldlt::SolveInPlace(factor_view_, solution_.data());
    inverse_turn_valid_ = false;
  }
  FinishResponse(f_dot_turn, solution_);
  const Eigen::VectorXd* dx = &solution_;
  if (!contacts.empty()) dx = &contacts_.Solve(contacts, friction, solution_, *this);
  for (int k = 0; k < m; ++k) {
    const int c = coordinate_of_unknown[k];
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

void ImplicitFirstOrderStep::SolveMissingColumns(const StepContact& contact,
                                                 const Vec2& direction) {
  std::array<int, 4> missing;  // two nodes' two coordinates at most
  int num_missing = 0;
  ForEachContactUnknown(contact, direction, assembly_.unknown_of_coordinate(), [&](int k, double) {
    if (inverse_column_of_unknown_[k] < 0) missing[num_missing++] = k;
  });
  const size_t m = static_cast<size_t>(num_unknowns());
  for (int a = 0; a + 1 < num_missing; a += 2) {
    const int slot = static_cast<int>(inverse_columns_.size() / m);
    inverse_columns_.resize(inverse_columns_.size() + 2 * m, 0.0);
    double* first = inverse_columns_.data() + slot * m;
    double* second = first + m;
    std::fill(first, first + 2 * m, 0.0);
    first[missing[a]] = 1.0;
    second[missing[a + 1]] = 1.0;
    ldlt::SolveInPlace2(factor_view_, first, second, solve_scratch_.data());
    inverse_column_of_unknown_[missing[a]] = slot;
    inverse_column_of_unknown_[missing[a + 1]] = slot + 1;
  }
  if (num_missing % 2 == 1) InverseColumn(missing[num_missing - 1]);
}

double ImplicitFirstOrderStep::ColumnDotTurn(int unknown) {
  if (column_dot_turn_stamp_[unknown] != step_stamp_) {
    column_dot_turn_stamp_[unknown] = step_stamp_;
    column_dot_turn_[unknown] =
        Eigen::Map<const Eigen::VectorXd>(CachedColumn(unknown), num_unknowns()).dot(turn_);
  }
  return column_dot_turn_[unknown];
}

double ImplicitFirstOrderStep::InverseTurnDotTurn() {
  if (inverse_turn_dot_turn_stamp_ != step_stamp_) {
    inverse_turn_dot_turn_stamp_ = step_stamp_;
    inverse_turn_dot_turn_ = inverse_turn_.dot(turn_);
  }
  return inverse_turn_dot_turn_;
}

void ImplicitFirstOrderStep::ResponseOf(const StepContact& contact, const Vec2& direction,
                                        StepResponse* out) {
  // A^-1 of the unit force along `direction` at the contact point, from the
  // cached columns, less A^-1 of its turn: then as any force
  // (FinishResponse), whose y . turn_ is the combination's.
  SolveMissingColumns(contact, direction);
  StepResponse& r = *out;
  r = StepResponse{};
  double g_dot_turn = 0.0;
  ForEachContactUnknown(contact, direction, assembly_.unknown_of_coordinate(), [&](int k, double g) {
    r.unknown[r.count] = k;
    r.weight[r.count] = g;
    ++r.count;
    g_dot_turn += g * turn_[k];
  });
  if (!(turn_norm_sq_ > 0.0)) return;
  if (g_dot_turn != 0.0) {
    if (!inverse_turn_valid_) {
      Solve(turn_, inverse_turn_);
      inverse_turn_valid_ = true;
    }
    r.inverse_turn = -(g_dot_turn / turn_norm_sq_);
  }
  double y_dot_turn = 0.0;
  for (int j = 0; j < r.count; ++j) y_dot_turn += r.weight[j] * ColumnDotTurn(r.unknown[j]);
  if (r.inverse_turn != 0.0) y_dot_turn += r.inverse_turn * InverseTurnDotTurn();
  r.turn = h_over_m_ * (g_dot_turn / turn_norm_sq_) - y_dot_turn / turn_norm_sq_;
}

void ImplicitFirstOrderStep::ResponseValues(const StepResponse& response,
                                            std::span<const int> unknowns, double* out) const {
  // Each entry summed in the combination's order.
  const size_t n = unknowns.size();
  std::fill(out, out + n, 0.0);
  for (int j = 0; j < response.count; ++j) {
    const double w = response.weight[j];
    const double* column = CachedColumn(response.unknown[j]);
    for (size_t i = 0; i < n; ++i) out[i] += w * column[unknowns[i]];
  }
  if (response.inverse_turn != 0.0) {
    for (size_t i = 0; i < n; ++i) out[i] += response.inverse_turn * inverse_turn_[unknowns[i]];
  }
  if (response.turn != 0.0) {
    for (size_t i = 0; i < n; ++i) out[i] += response.turn * turn_[unknowns[i]];
  }
}

void ImplicitFirstOrderStep::AddCombination(std::span<const int> unknowns,
                                            std::span<const double> weights, double inverse_turn,
                                            double turn, Eigen::VectorXd& step) const {
  const int m = num_unknowns();
  for (size_t j = 0; j < unknowns.size(); ++j) {
    step += weights[j] * Eigen::Map<const Eigen::VectorXd>(CachedColumn(unknowns[j]), m);
  }
  if (inverse_turn != 0.0) step += inverse_turn * inverse_turn_;
  if (turn != 0.0) step += turn * turn_;
}

}  // namespace calib
