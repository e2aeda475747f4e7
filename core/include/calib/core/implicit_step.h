#pragma once
// The first-order model's step made implicit in the springs and the edge
// damping, so that any stiffness is stable at the paper's 10 substeps.
//
// The explicit step x += (h / m) F is stable only while h / m times the
// stiffest mode of K stays below 2. That caps the calibrated stiffnesses
// well below the quasi-static regime of a sponge pushed across a table
// (measured: docs/loop.md, Known gaps), where the mesh stays in equilibrium
// with the finger and the pencil at every frame. The linearly implicit
// (backward) Euler step
//
//   (m / h I + K0 + k_d / h D0) dx = F(x, v = 0) + F_ext,   x += dx,
//
// treats the springs with their stiffness K0 and the edge damping with its
// matrix D0, both at the rest shape, and everything else (the push, the
// effects' forces) explicitly; effects that add springs about the rest
// shape (EffectHooks::rest_stiffness: a stiffness field) add their
// stiffness at the rest shape to K0, their forces staying in F. Its fixed
// points are the explicit step's (dx = 0 where the forces balance); for
// small h it agrees with it to first
// order; for large stiffness it is a modified Newton iteration towards the
// equilibrium (K0 for K(x)), which converges while the mesh's elements turn
// and stretch moderately from their rest shape, as a pushed sponge does.
//
// The matrix, its pattern and the numbering of the unknowns are
// implicit_assembly.h's. Configure factorises (allocating, once per
// candidate), Step solves with the factor and allocates nothing.
//
// Rigid motion: an unclamped mesh's K0 and D0 leave its rigid motions at the
// rest shape free, so the step moves the body along them by (h / m) times
// the forces' components, as the explicit step does. For the turn that has
// to be the turn about the current shape: the springs' forces have no net
// torque about the current positions, but once the mesh has deformed they
// have one about the rest positions, and in the stiff regime (K0 >> m / h)
// the solve would turn the body by it a little every substep. So the step
// splits off the forces' turn about the current centroid (with one clamped
// node: about that node), moves the body by (h / m) times it, solves for
// the rest and drops the solution's own turn. For small h that is still
// x += (h / m) F.
//
// Obstacles: Step takes the obstacles' contacts as constraints of the
// solve, held by an active-set iteration on their small dense system
// (contact_active_set.h) whose columns come from cached solves with the
// factor.
//
// Springs that stiffen with strain (EffectHooks::shape_stiffness) have no
// stiffness at the rest shape. Built with `edge_stiffness`, the step takes
// their axial stiffness at the current shape (BeginShapeStiffness, the
// effect's AddEdgeStiffness calls, FinishShapeStiffness: once a frame) on
// top of the configured matrix and refactorises it: numerically only, on
// the pattern analysed once, which holds every edge's node blocks, and only
// where the matrix moved by more than a tolerance (5 % of a row's diagonal,
// summed over the row) from the one factorised last. In between, the step
// keeps the older stiffness, as it already does between the frames' starts:
// the forces are exact, so the fixed points are the same, and a row that
// drifts further is refactorised before its stiffness runs ahead of the
// matrix by more than that share.

#include "calib/core/contact_active_set.h"
#include "calib/core/effects.h"
#include "calib/core/implicit_assembly.h"
#include "calib/core/ldlt_solve.h"
#include "calib/core/model.h"
#include "calib/core/parameters.h"
#include "calib/core/step_contact.h"
#include "calib/core/types.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace calib {

class ImplicitFirstOrderStep final : public EdgeStiffnessSink, private ContactResponses {
 public:
  /// Assembles the unit matrices of `model` (at its mesh's rest shape) for
  /// the nodes with `movable` != 0. With `edge_stiffness`, the matrix's
  /// pattern holds every mesh edge's node blocks, for AddEdgeStiffness.
  ImplicitFirstOrderStep(const Model& model, std::span<const double> movable,
                         bool edge_stiffness = false);

  // The contact active set reads the assembly's numbering in place.
  ImplicitFirstOrderStep(const ImplicitFirstOrderStep&) = delete;
  ImplicitFirstOrderStep& operator=(const ImplicitFirstOrderStep&) = delete;

  /// Forces added to the model's (ADDS them to f at the positions x, #N
  /// each, zero velocities) whose stiffness the step also takes implicitly.
  using ExtraForces = ImplicitStepAssembly::ExtraForces;

  /// Factorises m / h I + K0 + (k_d / h) D0 for `params` and step `h`.
  /// Returns false with *error set when the matrix is not positive definite
  /// (it is for every valid parameter set: K0 and D0 are positive
  /// semi-definite at the rest shape).
  bool Configure(const ModelParameters& params, double h, std::string* error) {
    return Configure(params, h, nullptr, error);
  }

  /// As above, with K0 also holding the stiffness of `extra` (when not
  /// null) at the rest shape: each node's forces must depend only on the
  /// nodes sharing a model element with it (EffectHooks::rest_stiffness).
  /// Its columns are probed by central differences, the unknowns whose
  /// neighbourhoods do not overlap together (a few dozen evaluations of
  /// `extra` a candidate). Allocates nothing.
  bool Configure(const ModelParameters& params, double h, const ExtraForces* extra,
                 std::string* error);

  /// x += dx for the forces `f` (#N, the springs without damping plus every
  /// explicit force) at the positions `x`; clamped nodes stay. After a
  /// successful Configure. Allocates nothing.
  void Step(std::span<const Vec2> f, std::span<Vec2> x) { Step(f, x, {}, 0.0); }

  /// As above, keeping the `contacts` (the candidates: those the step
  /// would break become active, at most kMaxActiveContacts) with Coulomb
  /// friction coefficient `friction` (>= 0). Allocates nothing once each
  /// contact's coordinates have been seen since Configure.
  void Step(std::span<const Vec2> f, std::span<Vec2> x, std::span<const StepContact> contacts,
            double friction);

  /// Re-linearisation at a shape, after a successful Configure (built with
  /// `edge_stiffness`): BeginShapeStiffness goes back to the configured
  /// matrix, AddEdgeStiffness adds an edge spring's axial stiffness k u u^T
  /// (k >= 0), FinishShapeStiffness refactorises (false with *error set
  /// when the matrix is not positive definite) unless the matrix moved
  /// little from the one factorised last: by at most `shape_tolerance()` in
  /// every row, max_i sum_j |A_ij - F_ij| / F_ii (F the factorised matrix;
  /// the configured one after Configure). A step with the kept factor is
  /// the same linearly implicit step with its stiffness a frame or more
  /// old (the forces stay exact, so its fixed points do not move).
  /// Allocates nothing.
  void BeginShapeStiffness() { assembly_.BeginShapeStiffness(); }
  void AddEdgeStiffness(int edge, double k, const Vec2& u) override {
    assembly_.AddEdgeStiffness(edge, k, u);
  }
  bool FinishShapeStiffness(std::string* error);

  /// The relative change of the re-linearised matrix below which its factor
  /// is kept (FinishShapeStiffness); 0 refactorises at every change.
  static constexpr double kDefaultShapeTolerance = 0.05;
  double shape_tolerance() const { return shape_tolerance_; }
  void set_shape_tolerance(double tolerance) { shape_tolerance_ = tolerance; }
  /// Refactorisations of the re-linearised matrix since Configure.
  int shape_factorizations() const { return shape_factorizations_; }

  /// Contacts held by one step at most; others are left to the projections.
  static constexpr int kMaxActiveContacts = ContactActiveSet::kMaxActiveContacts;

  /// The stiffness K0 of `params` over all 2N coordinates (node i: rows 2i,
  /// 2i+1; zero rows and columns for clamped nodes), for tests.
  Eigen::SparseMatrix<double> Stiffness(const ModelParameters& params) const {
    return assembly_.Stiffness(params);
  }

  /// The stiffness of the last Configure's `extra` forces, as Stiffness
  /// (zero without them), for tests.
  Eigen::SparseMatrix<double> ExtraStiffness() const { return assembly_.ExtraStiffness(); }

  int num_unknowns() const { return assembly_.num_unknowns(); }

 private:
  using SparseMatrix = Eigen::SparseMatrix<double>;

  ImplicitStepAssembly assembly_;
  // The factors of the step's matrix A as configured (assembly_.lower(),
  // once per candidate) and as re-linearised at a shape (assembly_.upper(),
  // where a frame's shape moved it: its symbolic work done once), their
  // patterns analysed once.
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> factor_;
  ldlt::Factorization shape_factor_;
  // The re-linearised matrix's factorised values (upper(), storage order),
  // each row's sum of changes against them, its diagonal's positions.
  std::vector<double> factorised_upper_, row_change_;
  std::vector<int> upper_diagonal_;
  double shape_tolerance_ = kDefaultShapeTolerance;
  int shape_factorizations_ = 0;
  // max_i sum_j |upper_ij - factorised_ij| / factorised_ii.
  double ShapeChange();
  // The last successful factorisation's arrays (ldlt_solve.h: the factor's
  // own solve, bit for bit), and for factor_ its 1 / D and backward order.
  ldlt::FactorView factor_view_;
  ldlt::FactorExtras factor_extras_;
  std::vector<double> solve_scratch_;  // 2 m: SolveInPlace2's
  // dest = A^-1 rhs with the current factor.
  template <class Rhs, class Dest>
  void Solve(const Rhs& rhs, Dest&& dest) const {
    dest = rhs;
    ldlt::SolveInPlace(factor_view_, dest.data());
  }
  void ForgetSolves();  // the cached columns of A^-1 belong to the old matrix
  // Views the factor (or says why it failed, with the parameters).
  bool Factorized(bool ok, const ldlt::FactorView& view, const ModelParameters& params, double h,
                  std::string* error);
  ModelParameters configured_params_;
  double configured_h_ = 0.0;
  Eigen::VectorXd rhs_, solution_;
  double h_over_m_ = 0.0;

  // The free turn of this step's start over the unknowns (zero without one),
  // its squared norm and A^-1 turn_.
  Eigen::VectorXd turn_, inverse_turn_;
  double turn_norm_sq_ = 0.0;
  bool inverse_turn_valid_ = false;
  void SetTurn(std::span<const Vec2> x);
  // The step's response to the force g over the unknowns (the turn split
  // off, solved, kept as described above), given y = A^-1 (g) and
  // g . turn_: linear in g.
  void FinishResponse(double g_dot_turn, Eigen::Ref<Eigen::VectorXd> y) const;

  // A^-1 e_k for the unknowns k the contacts touched since Configure.
  std::vector<int> inverse_column_of_unknown_;  // slot, or -1
  std::vector<double> inverse_columns_;         // slot s: [s m, (s + 1) m)
  const double* InverseColumn(int unknown);
  // Solves the columns `contact` needs along `direction` that are not
  // cached yet, two in one pass (SolveInPlace2: each its own solve's bits).
  void SolveMissingColumns(const StepContact& contact, const Vec2& direction);

  // Column k's (A^-1 e_k, cached) dot product with this step's turn, for
  // the unknowns whose stamp is this step's (step_stamp_, advanced by
  // SetTurn); A^-1 turn_ . turn_ likewise.
  std::vector<double> column_dot_turn_;
  std::vector<uint64_t> column_dot_turn_stamp_;
  uint64_t step_stamp_ = 0, inverse_turn_dot_turn_stamp_ = 0;
  double inverse_turn_dot_turn_ = 0.0;
  const double* CachedColumn(int unknown) const {
    return inverse_columns_.data() +
           static_cast<size_t>(inverse_column_of_unknown_[unknown]) * num_unknowns();
  }
  double ColumnDotTurn(int unknown);
  double InverseTurnDotTurn();

  // The contacts' active set, and the step's response to a unit force at a
  // contact's point for it: A^-1 of the force (cached columns) less A^-1 of
  // its turn, then as any force (FinishResponse), kept as that combination.
  ContactActiveSet contacts_;
  void ResponseOf(const StepContact& contact, const Vec2& direction, StepResponse* out) override;
  void ResponseValues(const StepResponse& response, std::span<const int> unknowns,
                      double* out) const override;
  void AddCombination(std::span<const int> unknowns, std::span<const double> weights,
                      double inverse_turn, double turn, Eigen::VectorXd& step) const override;

  // The rotation K0 leaves free (kFree: about the centroid, kPivot: about
  // the one clamped node, kNone: two or more clamped nodes hold the mesh).
  enum class FreeTurn { kNone, kFree, kPivot };
  FreeTurn free_turn_ = FreeTurn::kNone;
  int pivot_ = -1;  // the clamped node (kPivot)
};

}  // namespace calib
