#pragma once
// Which obstacle contacts the implicit first-order step (implicit_step.h)
// holds inside its solve, and the step they make.
//
// Obstacles: a stiff mesh's step is long where an obstacle holds it (the
// springs would undo a finger's dent in one step), so projecting the nodes
// out after the step makes them chatter by the dent's depth every substep
// and throws the contact's friction between sticking and sliding. Step
// therefore takes the contacts as constraints of the solve: each keeps a
// node, or a point of a boundary edge, on the obstacle's side of its
// tangent line (normal . dx >= gap, linearised at the step's start), and
// with friction mu it also moves along the tangent with the obstacle while
// the tangential force stays within mu times the normal one (Coulomb),
// else slides against a force of mu times it. The multipliers are found
// by an active-set iteration on the contacts' small dense system, whose
// columns come from cached solves with the factor (per coordinate, reused
// for the whole candidate): the step stays one solve plus a few vector
// sums. What the linearisation leaves the simulator's projections put
// right.

#include "calib/core/step_contact.h"
#include "calib/core/types.h"

#include <Eigen/Core>
#include <Eigen/LU>

#include <array>
#include <cstdint>
#include <span>
#include <vector>

namespace calib {

/// The coordinates of `contact`'s point along `direction`: visit(unknown,
/// weight x direction component) for each with an unknown
/// (unknown_of_coordinate >= 0: clamped nodes skipped) and a nonzero
/// factor.
template <class Visit>
void ForEachContactUnknown(const StepContact& contact, const Vec2& direction,
                           std::span<const int> unknown_of_coordinate, Visit&& visit) {
  for (int q = 0; q < 2; ++q) {
    const int node = contact.nodes[q];
    if (node < 0) continue;
    for (int d = 0; d < 2; ++d) {
      const int k = unknown_of_coordinate[2 * node + d];
      const double g = contact.weights[q] * direction[d];
      if (k >= 0 && g != 0.0) visit(k, g);
    }
  }
}

/// The step's response to a unit force at a contact's point, as the
/// combination of vectors the step keeps that it is:
///   sum_j weight[j] A^-1 e_unknown[j] + inverse_turn A^-1 t + turn t
/// (A the step's matrix, e_k the unit vector of unknown k, t the step's
/// free turn). At most four unknowns: a point of an edge moves two nodes'
/// two coordinates.
struct StepResponse {
  std::array<int, 4> unknown{};
  std::array<double, 4> weight{};
  int count = 0;
  double inverse_turn = 0.0;
  double turn = 0.0;
};

/// What the active set needs of the step: how a force at a contact point
/// changes the step. The active set reads a response only at the contacts'
/// unknowns, and forms the step from the responses once: a response is
/// kept as its combination, never as an m-long vector.
class ContactResponses {
 public:
  /// The change of the step (over the unknowns) made by a unit force along
  /// `direction` at `contact`'s point: linear in the force.
  virtual void ResponseOf(const StepContact& contact, const Vec2& direction,
                          StepResponse* out) = 0;
  /// out[i] = entry unknowns[i] of `response` (made by ResponseOf in this
  /// step).
  virtual void ResponseValues(const StepResponse& response, std::span<const int> unknowns,
                              double* out) const = 0;
  /// step += sum_j weights[j] A^-1 e_unknowns[j] + inverse_turn A^-1 t +
  /// turn t: a combination of this step's responses (each unknown once).
  virtual void AddCombination(std::span<const int> unknowns, std::span<const double> weights,
                              double inverse_turn, double turn, Eigen::VectorXd& step) const = 0;

 protected:
  ~ContactResponses() = default;
};

/// The active set of one step's contacts, with the buffers its solve
/// reuses.
class ContactActiveSet {
 public:
  /// Contacts held by one step at most; others are left to the projections.
  static constexpr int kMaxActiveContacts = 32;

  /// For a step over `num_unknowns` unknowns, coordinate c's being
  /// unknown_of_coordinate[c] (-1: none), which must outlive this.
  ContactActiveSet(std::span<const int> unknown_of_coordinate, int num_unknowns);

  /// The step that keeps the `contacts` (the candidates: those the free
  /// step `free_step` would break become active, at most
  /// kMaxActiveContacts) with Coulomb friction coefficient `friction`
  /// (>= 0), the active contacts' forces acting through `responses`. Valid
  /// until the next call.
  const Eigen::VectorXd& Solve(std::span<const StepContact> contacts, double friction,
                               const Eigen::VectorXd& free_step, ContactResponses& responses);

 private:
  struct ActiveContact {
    int contact = 0;
    bool stick = false;
    double slip_sign = 0.0;  // sliding: the friction force's sign along the tangent
    double normal_force = 0.0, tangent_force = 0.0;
  };
  std::span<const int> unknown_of_coordinate_;
  std::vector<ActiveContact> active_;
  std::vector<int> active_of_contact_;  // index into active_, or -1
  std::vector<uint8_t> excluded_;       // contacts dropped for a singular system
  // The step's response to a unit force along each active contact's normal
  // and tangent, as combinations (StepResponse).
  std::array<StepResponse, kMaxActiveContacts> normal_response_{}, tangent_response_{};
  // The unknowns of this Solve's contacts (local_of_unknown_: each one's
  // place among them, or -1), and each active contact's responses there:
  // active contact a's at [a L, (a + 1) L), L = local_unknowns_.size():
  // all the active set reads of them.
  std::vector<int> local_unknowns_, local_of_unknown_;
  std::vector<double> normal_values_, tangent_values_;
  Eigen::VectorXd step_;  // the constrained step
  // The step's combination of the rows' responses: each unknown's weight
  // (slot_of_unknown_: its place, or -1), A^-1 t's and t's.
  std::vector<int> combination_unknowns_, slot_of_unknown_;
  std::vector<double> combination_weights_;
  double combination_inverse_turn_ = 0.0, combination_turn_ = 0.0;
  void AddToCombination(const StepResponse& response, double weight);
  // The active contacts' system (fixed capacity: no allocation).
  static constexpr int kMaxRows = 2 * kMaxActiveContacts;
  using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxRows, kMaxRows>;
  using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxRows, 1>;
  SmallMatrix system_;
  SmallVector system_rhs_, forces_;
  Eigen::FullPivLU<SmallMatrix> lu_;
  std::array<int, kMaxActiveContacts> tangent_row_{};
  // The system's unknowns (rows of forces_): each one's column of the step
  // is active contact `response`'s normal response (plus `slip` times its
  // tangent response when it `slides`), or its tangent response.
  struct Row {
    int response = 0;
    bool tangent = false;
    bool slides = false;
    double slip = 0.0;
  };
  std::array<Row, kMaxRows> rows_{};
  int num_rows_ = 0;  // of the last successful SolveActive; 0: the free step
  // Solves for the active contacts' forces (forces_, rows_); false when the
  // system is singular. The step is free_step plus each row's force times
  // its column; the active set reads it only at the contacts' unknowns
  // (StepAlong), and Solve forms it whole once, at its end.
  bool SolveActive(std::span<const StepContact> contacts, double friction,
                   const Eigen::VectorXd& free_step);
  // A contact's point along a direction: its unknowns (ForEachContactUnknown's,
  // in its order), their places among local_unknowns_ and their weights.
  struct ContactTerms {
    int count = 0;
    std::array<int, 4> unknown{}, local{};
    std::array<double, 4> g{};
  };
  std::vector<ContactTerms> terms_;  // contact j's: [2 j] its normal, [2 j + 1] its tangent
  // Row `row`'s column at the local unknown `local`.
  double ColumnAt(int row, int local) const;
  // Along, of the step of the last successful SolveActive.
  double StepAlong(const ContactTerms& terms, const Eigen::VectorXd& free_step) const;
  // The motion of a contact's point along a direction (its terms) under
  // the step dx.
  double Along(const ContactTerms& terms, const Eigen::VectorXd& dx) const;
};

}  // namespace calib
