#include "calib/core/contact_active_set.h"

#include <cmath>

namespace calib {
namespace {

// A contact is broken, or slides against its friction, by more than this.
constexpr double kContactTolerancePx = 1e-9;

Vec2 Tangent(const Vec2& normal) { return Vec2(-normal.y(), normal.x()); }

}  // namespace

ContactActiveSet::ContactActiveSet(std::span<const int> unknown_of_coordinate, int num_unknowns)
    : unknown_of_coordinate_(unknown_of_coordinate) {
  step_.setZero(num_unknowns);
  normal_response_.setZero(num_unknowns, kMaxActiveContacts);
  tangent_response_.setZero(num_unknowns, kMaxActiveContacts);
}

double ContactActiveSet::Along(const StepContact& contact, const Vec2& direction,
                               const Eigen::VectorXd& dx) const {
  double along = 0.0;
  ForEachContactUnknown(contact, direction, unknown_of_coordinate_,
                        [&](int k, double g) { along += g * dx[k]; });
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
      if (!(StepAlong(c, c.normal, free_step) - c.gap < -kContactTolerancePx)) continue;
      const int a = static_cast<int>(active_.size());
      active_.push_back(ActiveContact{j, friction > 0.0, 0.0, 0.0, 0.0});
      active_of_contact_[j] = a;
      responses.ResponseOf(c, c.normal, normal_response_.col(a));
      if (friction > 0.0) responses.ResponseOf(c, Tangent(c.normal), tangent_response_.col(a));
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
                   a.slip_sign * (StepAlong(c, Tangent(c.normal), free_step) - tangent_target(c)) >
                       kContactTolerancePx) {
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
  // column, the rows in order (the operations StepAlong makes per entry).
  step_ = free_step;
  for (int u = 0; u < num_rows_; ++u) {
    const Row& row = rows_[u];
    if (row.slides) {
      step_ += forces_[u] *
               (normal_response_.col(row.response) + row.slip * tangent_response_.col(row.response));
    } else if (row.tangent) {
      step_ += forces_[u] * tangent_response_.col(row.response);
    } else {
      step_ += forces_[u] * normal_response_.col(row.response);
    }
  }
  return step_;
}

double ContactActiveSet::ColumnAt(int u, int k) const {
  const Row& row = rows_[u];
  if (row.slides) return normal_response_(k, row.response) + row.slip * tangent_response_(k, row.response);
  return row.tangent ? tangent_response_(k, row.response) : normal_response_(k, row.response);
}

double ContactActiveSet::StepAlong(const StepContact& contact, const Vec2& direction,
                                   const Eigen::VectorXd& free_step) const {
  double along = 0.0;
  ForEachContactUnknown(contact, direction, unknown_of_coordinate_, [&](int k, double g) {
    double step = free_step[k];
    for (int u = 0; u < num_rows_; ++u) step += forces_[u] * ColumnAt(u, k);
    along += g * step;
  });
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
    const StepContact& c = contacts[active_[a].contact];
    system_rhs_[a] = c.gap - Along(c, c.normal, free_step);
    if (tangent_row_[a] >= 0) {
      const Vec2 t = Tangent(c.normal);
      system_rhs_[tangent_row_[a]] = t.dot(c.obstacle_step) - Along(c, t, free_step);
    }
  }
  // Each column's entries at the contacts' own unknowns: all the system
  // reads of the m-long column.
  for (int u = 0; u < rows; ++u) {
    const auto along = [&](const StepContact& c, const Vec2& direction) {
      double sum = 0.0;
      ForEachContactUnknown(c, direction, unknown_of_coordinate_,
                            [&](int unknown, double g) { sum += g * ColumnAt(u, unknown); });
      return sum;
    };
    for (int a = 0; a < k; ++a) {
      const StepContact& c = contacts[active_[a].contact];
      system_(a, u) = along(c, c.normal);
      if (tangent_row_[a] >= 0) system_(tangent_row_[a], u) = along(c, Tangent(c.normal));
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
