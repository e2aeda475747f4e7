#include "calib/core/contact_active_set.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

namespace calib {
namespace {

// A contact is broken, or slides against its friction, by more than this.
constexpr double kContactTolerancePx = 1e-9;

Vec2 Tangent(const Vec2& normal) { return Vec2(-normal.y(), normal.x()); }

}  // namespace

ContactActiveSet::ContactActiveSet(std::span<const int> unknown_of_coordinate, int num_unknowns)
    : unknown_of_coordinate_(unknown_of_coordinate) {
  step_.setZero(num_unknowns);
  slot_of_unknown_.assign(num_unknowns, -1);
  local_of_unknown_.assign(num_unknowns, -1);
  local_unknowns_.reserve(num_unknowns);
  // The responses at every unknown at most: no allocation in Solve.
  normal_values_.assign(static_cast<size_t>(kMaxActiveContacts) * num_unknowns, 0.0);
  tangent_values_.assign(static_cast<size_t>(kMaxActiveContacts) * num_unknowns, 0.0);
  combination_unknowns_.reserve(4 * kMaxRows);
  combination_weights_.reserve(4 * kMaxRows);
}

double ContactActiveSet::Along(const ContactTerms& terms, const Eigen::VectorXd& dx) const {
  double along = 0.0;
  for (int q = 0; q < terms.count; ++q) along += terms.g[q] * dx[terms.unknown[q]];
  return along;
}

const Eigen::VectorXd& ContactActiveSet::Solve(std::span<const StepContact> contacts,
                                               double friction, const Eigen::VectorXd& free_step,
                                               ContactResponses& responses) {
  // Active set: start from the free step; add the contacts it breaks (held
  // as sticking when there is friction), solve for their forces, release a
  // contact that pulls, let a sticking contact slide whose tangential force
  // exceeds mu times its normal one and stop a sliding one that moves with
  // its friction; repeat until nothing changes. Each round's system has one
  // row per active contact's normal and per sticking contact's tangent.
  const int num_contacts = static_cast<int>(contacts.size());
  local_unknowns_.clear();
  for (const StepContact& c : contacts) {
    ForEachContactUnknown(c, Vec2(1.0, 1.0), unknown_of_coordinate_, [&](int k, double) {
      if (local_of_unknown_[k] >= 0) return;
      local_of_unknown_[k] = static_cast<int>(local_unknowns_.size());
      local_unknowns_.push_back(k);
    });
  }
  const size_t num_local = local_unknowns_.size();
  // Each contact's coordinates along its normal and its tangent, once.
  terms_.resize(2 * contacts.size());
  for (size_t j = 0; j < contacts.size(); ++j) {
    const StepContact& c = contacts[j];
    for (const int side : {0, 1}) {
      ContactTerms& terms = terms_[2 * j + side];
      terms.count = 0;
      ForEachContactUnknown(c, side == 0 ? c.normal : Tangent(c.normal), unknown_of_coordinate_,
                            [&](int k, double g) {
                              terms.unknown[terms.count] = k;
                              terms.local[terms.count] = local_of_unknown_[k];
                              terms.g[terms.count] = g;
                              ++terms.count;
                            });
    }
  }
  active_.clear();
  active_of_contact_.assign(num_contacts, -1);
  excluded_.assign(num_contacts, 0);
  num_rows_ = 0;
  const auto tangent_target = [&](const StepContact& c) {
    return Tangent(c.normal).dot(c.obstacle_step);
  };
  const auto remove = [&](int a) {
    for (int b = a; b + 1 < static_cast<int>(active_.size()); ++b) {
      active_[b] = active_[b + 1];
      normal_response_[b] = normal_response_[b + 1];
      tangent_response_[b] = tangent_response_[b + 1];
      for (std::vector<double>* values : {&normal_values_, &tangent_values_}) {
        const auto next = values->begin() + static_cast<std::ptrdiff_t>((b + 1) * num_local);
        std::copy(next, next + static_cast<std::ptrdiff_t>(num_local),
                  next - static_cast<std::ptrdiff_t>(num_local));
      }
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
      if (!(StepAlong(terms_[2 * j], free_step) - c.gap < -kContactTolerancePx)) continue;
      const int a = static_cast<int>(active_.size());
      active_.push_back(ActiveContact{j, friction > 0.0, 0.0, 0.0, 0.0});
      active_of_contact_[j] = a;
      responses.ResponseOf(c, c.normal, &normal_response_[a]);
      responses.ResponseValues(normal_response_[a], local_unknowns_,
                               normal_values_.data() + a * num_local);
      if (friction > 0.0) {
        responses.ResponseOf(c, Tangent(c.normal), &tangent_response_[a]);
        responses.ResponseValues(tangent_response_[a], local_unknowns_,
                                 tangent_values_.data() + a * num_local);
      }
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
        } else if (!a.stick && a.slip_sign * (StepAlong(terms_[2 * a.contact + 1], free_step) -
                                              tangent_target(c)) > kContactTolerancePx) {
          a.stick = true;  // it would slide the way its friction pushes
          changed = true;
        }
      }
    }
    if (!changed) break;
    // A contact that repeats others (a node and the edge through it) makes
    // the system singular: the newest is left to the projections.
    while (!SolveActive(contacts, friction, free_step)) {
      const int last = static_cast<int>(active_.size()) - 1;
      excluded_[active_[last].contact] = 1;
      active_of_contact_[active_[last].contact] = -1;
      remove(last);
    }
  }
  // The step itself, once: free_step plus each row's force times its
  // column, the columns' combinations merged so that each vector the step
  // keeps is added once.
  combination_unknowns_.clear();
  combination_weights_.clear();
  combination_inverse_turn_ = 0.0;
  combination_turn_ = 0.0;
  for (int u = 0; u < num_rows_; ++u) {
    const Row& row = rows_[u];
    if (row.slides) {
      AddToCombination(normal_response_[row.response], forces_[u]);
      AddToCombination(tangent_response_[row.response], forces_[u] * row.slip);
    } else if (row.tangent) {
      AddToCombination(tangent_response_[row.response], forces_[u]);
    } else {
      AddToCombination(normal_response_[row.response], forces_[u]);
    }
  }
  for (const int k : combination_unknowns_) slot_of_unknown_[k] = -1;
  for (const int k : local_unknowns_) local_of_unknown_[k] = -1;
  step_ = free_step;
  if (num_rows_ > 0) {
    responses.AddCombination(combination_unknowns_, combination_weights_, combination_inverse_turn_,
                             combination_turn_, step_);
  }
  return step_;
}

void ContactActiveSet::AddToCombination(const StepResponse& response, double weight) {
  for (int j = 0; j < response.count; ++j) {
    const int k = response.unknown[j];
    int& slot = slot_of_unknown_[k];
    if (slot < 0) {
      slot = static_cast<int>(combination_unknowns_.size());
      combination_unknowns_.push_back(k);
      combination_weights_.push_back(0.0);
    }
    combination_weights_[slot] += weight * response.weight[j];
  }
  combination_inverse_turn_ += weight * response.inverse_turn;
  combination_turn_ += weight * response.turn;
}

double ContactActiveSet::ColumnAt(int u, int local) const {
  const Row& row = rows_[u];
  const size_t at = row.response * local_unknowns_.size() + local;
  if (row.slides) return normal_values_[at] + row.slip * tangent_values_[at];
  return row.tangent ? tangent_values_[at] : normal_values_[at];
}

double ContactActiveSet::StepAlong(const ContactTerms& terms,
                                   const Eigen::VectorXd& free_step) const {
  double along = 0.0;
  for (int q = 0; q < terms.count; ++q) {
    double step = free_step[terms.unknown[q]];
    for (int u = 0; u < num_rows_; ++u) step += forces_[u] * ColumnAt(u, terms.local[q]);
    along += terms.g[q] * step;
  }
  return along;
}

bool ContactActiveSet::SolveActive(std::span<const StepContact> contacts, double friction,
                                   const Eigen::VectorXd& free_step) {
  const int k = static_cast<int>(active_.size());
  num_rows_ = 0;
  if (k == 0) return true;
  for (int a = 0; a < k; ++a) active_of_contact_[active_[a].contact] = a;
  // Unknowns: each active contact's normal force, then each sticking
  // contact's tangential force. A sliding contact's friction is slip_sign
  // mu times its normal force, so its normal force's column carries it.
  int rows = k;
  for (int a = 0; a < k; ++a) {
    const ActiveContact& active = active_[a];
    rows_[a] = Row{a, false, !active.stick && friction > 0.0, active.slip_sign * friction};
  }
  for (int a = 0; a < k; ++a) {
    tangent_row_[a] = -1;
    if (!active_[a].stick) continue;
    tangent_row_[a] = rows;
    rows_[rows++] = Row{a, true, false, 0.0};
  }
  system_.resize(rows, rows);
  system_rhs_.resize(rows);
  for (int a = 0; a < k; ++a) {
    const int j = active_[a].contact;
    const StepContact& c = contacts[j];
    system_rhs_[a] = c.gap - Along(terms_[2 * j], free_step);
    if (tangent_row_[a] >= 0) {
      const Vec2 t = Tangent(c.normal);
      system_rhs_[tangent_row_[a]] = t.dot(c.obstacle_step) - Along(terms_[2 * j + 1], free_step);
    }
  }
  // Each column's entries at the contacts' own unknowns: all the system
  // reads of the m-long column.
  for (int u = 0; u < rows; ++u) {
    const auto along = [&](const ContactTerms& terms) {
      double sum = 0.0;
      for (int q = 0; q < terms.count; ++q) sum += terms.g[q] * ColumnAt(u, terms.local[q]);
      return sum;
    };
    for (int a = 0; a < k; ++a) {
      const int j = active_[a].contact;
      system_(a, u) = along(terms_[2 * j]);
      if (tangent_row_[a] >= 0) system_(tangent_row_[a], u) = along(terms_[2 * j + 1]);
    }
  }
  lu_.compute(system_);
  if (!lu_.isInvertible()) return false;
  forces_ = lu_.solve(system_rhs_);
  num_rows_ = rows;
  for (int a = 0; a < k; ++a) {
    ActiveContact& active = active_[a];
    active.normal_force = forces_[a];
    active.tangent_force =
        active.stick ? forces_[tangent_row_[a]] : active.slip_sign * friction * forces_[a];
  }
  return true;
}

}  // namespace calib
