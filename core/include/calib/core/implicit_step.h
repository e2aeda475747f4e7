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
// K0 = k_D K_D + k_A K_A + k_phi K_phi, where the unit matrices are the
// model's force Jacobians at the rest shape with one stiffness set to 1,
// assembled once by central differences of Model::ComputeForces (exact
// zeros away from a node's neighbours). Clamped nodes have no unknowns. The
// unknowns are numbered once by an approximate minimum degree ordering, so
// the factor stays sparse; Configure factorises (allocating, once per
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
//
// Springs that stiffen with strain (EffectHooks::shape_stiffness) have no
// stiffness at the rest shape. Built with `edge_stiffness`, the step takes
// their axial stiffness at the current shape (BeginShapeStiffness, the
// effect's AddEdgeStiffness calls, FinishShapeStiffness: once a frame) on
// top of the configured matrix and refactorises it: numerically only, on
// the pattern analysed once, which holds every edge's node blocks.

#include "calib/core/effects.h"
#include "calib/core/mesh.h"
#include "calib/core/model.h"
#include "calib/core/parameters.h"
#include "calib/core/types.h"

#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <array>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace calib {

/// A contact the implicit step keeps: the point sum_k weights[k] x[nodes[k]]
/// (a node, or a point of a boundary edge) moves along `normal` by at least
/// `gap`. `normal` is unit and points the way the obstacle pushes;
/// `obstacle_step` is the obstacle's motion over the step (the tangential
/// motion a sticking contact follows).
struct StepContact {
  std::array<int, 2> nodes{-1, -1};  ///< nodes[1] = -1: a node contact
  std::array<double, 2> weights{1.0, 0.0};
  Vec2 normal = Vec2::UnitX();
  double gap = 0.0;  ///< px
  Vec2 obstacle_step = Vec2::Zero();
};

class ImplicitFirstOrderStep final : public EdgeStiffnessSink {
 public:
  /// Assembles the unit matrices of `model` (at its mesh's rest shape) for
  /// the nodes with `movable` != 0. `movable` must outlive this. With
  /// `edge_stiffness`, the matrix's pattern holds every mesh edge's node
  /// blocks, for AddEdgeStiffness.
  ImplicitFirstOrderStep(const Model& model, std::span<const double> movable,
                         bool edge_stiffness = false);

  /// Forces added to the model's (ADDS them to f at the positions x, #N
  /// each, zero velocities) whose stiffness the step also takes implicitly.
  using ExtraForces = std::function<void(std::span<const Vec2> x, std::span<Vec2> f)>;

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
  /// when the matrix is not positive definite). Allocates nothing but the
  /// factorisation's scratch.
  void BeginShapeStiffness();
  void AddEdgeStiffness(int edge, double k, const Vec2& u) override;
  bool FinishShapeStiffness(std::string* error);

  /// Contacts held by one step at most; others are left to the projections.
  static constexpr int kMaxActiveContacts = 32;

  /// The stiffness K0 of `params` over all 2N coordinates (node i: rows 2i,
  /// 2i+1; zero rows and columns for clamped nodes), for tests.
  Eigen::SparseMatrix<double> Stiffness(const ModelParameters& params) const;

  /// The stiffness of the last Configure's `extra` forces, as Stiffness
  /// (zero without them), for tests.
  Eigen::SparseMatrix<double> ExtraStiffness() const;

  int num_unknowns() const { return static_cast<int>(coordinate_of_unknown_.size()); }

 private:
  using SparseMatrix = Eigen::SparseMatrix<double>;

  int num_coordinates_ = 0;           // 2 N
  std::vector<int> coordinate_of_unknown_;  // unknown k: coordinate coordinate_of_unknown_[k] (2 i + d)
  std::vector<int> unknown_of_coordinate_;  // its inverse; -1 for clamped nodes
  // The unit matrices' values on A's pattern (A_ below), in its storage order.
  std::vector<double> distance_, area_, angle_, damping_;
  // The extra forces' stiffness on A's pattern, and how it is probed: the
  // unknowns in colour groups whose columns share no row, each column's
  // rows (rows_ from row_begin_[k]) with the positions of their entries in
  // A's values (the lower triangle's).
  std::vector<double> extra_;
  std::vector<int> colour_begin_, coloured_unknowns_;
  std::vector<int> row_begin_, rows_, row_position_;
  std::vector<Vec2> rest_, probe_x_, probe_plus_, probe_minus_;
  bool has_extra_ = false;
  void ProbeExtraStiffness(const ExtraForces& extra);
  // The symmetric matrix over all 2N coordinates whose lower triangle on
  // A's pattern has the values value(position).
  template <class Value>
  Eigen::SparseMatrix<double> OverCoordinates(Value value) const;
  // The values of A_ after Configure (the shape's stiffness goes on top).
  // The re-linearised matrix is kept as its upper triangle (upper_, A_
  // transposed: where upper_of_lower_ says), which Eigen's factorisation
  // reads in place where a lower one is copied every time; per mesh edge
  // the positions in upper_ of its node blocks' entries (-1 for a clamped
  // node's): ii xx, ii yy, ii xy, jj xx, jj yy, jj xy, ij xx, ij xy, ij yx,
  // ij yy. shape_active_: the last factorisation was FinishShapeStiffness's.
  std::vector<double> configured_;
  SparseMatrix upper_;
  std::vector<int> upper_of_lower_;
  std::vector<std::array<int, 10>> edge_positions_;
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Upper, Eigen::NaturalOrdering<int>> shape_factor_;
  bool shape_active_ = false;
  // dest = A^-1 rhs with the current factor.
  template <class Rhs, class Dest>
  void Solve(const Rhs& rhs, Dest&& dest) const {
    if (shape_active_) {
      dest = shape_factor_.solve(rhs);
    } else {
      dest = factor_.solve(rhs);
    }
  }
  void ForgetSolves();  // the cached columns of A^-1 belong to the old matrix
  template <class Factor>
  bool Factorized(const Factor& factor, const ModelParameters& params, double h,
                  std::string* error) const;
  ModelParameters configured_params_;
  double configured_h_ = 0.0;
  std::vector<int> diagonal_;  // index of each unknown's diagonal entry in A_'s values
  SparseMatrix A_;             // lower triangle of the step's matrix, permuted
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> factor_;
  Eigen::VectorXd rhs_, solution_;
  double h_over_m_ = 0.0;

  // The free turn of this step's start over the unknowns (zero without one),
  // its squared norm and A^-1 turn_.
  Eigen::VectorXd turn_, inverse_turn_;
  double turn_norm_sq_ = 0.0;
  void SetTurn(std::span<const Vec2> x);
  // The step's response to the force g over the unknowns (the turn split
  // off, solved, kept as described above), given y = A^-1 (g) and
  // g . turn_: linear in g.
  void FinishResponse(double g_dot_turn, Eigen::Ref<Eigen::VectorXd> y) const;

  // A^-1 e_k for the unknowns k the contacts touched since Configure.
  std::vector<int> inverse_column_of_unknown_;  // slot, or -1
  std::vector<double> inverse_columns_;         // slot s: [s m, (s + 1) m)
  const double* InverseColumn(int unknown);

  // The contacts' active set (ContactSolve in implicit_step.cpp).
  struct ActiveContact {
    int contact = 0;
    bool stick = false;
    double slip_sign = 0.0;  // sliding: the friction force's sign along the tangent
    double normal_force = 0.0, tangent_force = 0.0;
  };
  std::vector<ActiveContact> active_;
  std::vector<int> active_of_contact_;  // index into active_, or -1
  std::vector<uint8_t> excluded_;       // contacts dropped for a singular system
  // The step's response to a unit force along each active contact's normal
  // and tangent (m rows, kMaxActiveContacts columns).
  Eigen::MatrixXd normal_response_, tangent_response_;
  Eigen::VectorXd step_, column_;  // the constrained step; a scratch column
  bool inverse_turn_valid_ = false;
  // The active contacts' system (fixed capacity: no allocation).
  static constexpr int kMaxRows = 2 * kMaxActiveContacts;
  using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxRows, kMaxRows>;
  using SmallVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxRows, 1>;
  SmallMatrix system_;
  SmallVector system_rhs_, forces_;
  Eigen::FullPivLU<SmallMatrix> lu_;
  std::array<int, kMaxActiveContacts> tangent_row_{};
  // Solves for the active contacts' forces and sets step_; false when the
  // system is singular.
  bool SolveActive(std::span<const StepContact> contacts, double friction);
  template <class Visit>
  void ForEachUnknown(const StepContact& contact, const Vec2& direction, Visit&& visit) const;
  void ResponseOf(const StepContact& contact, const Vec2& direction, Eigen::Ref<Eigen::VectorXd> out);
  double Along(const StepContact& contact, const Vec2& direction, const Eigen::VectorXd& dx) const;
  void ContactSolve(std::span<const StepContact> contacts, double friction);

  // The rotation K0 leaves free (kFree: about the centroid, kPivot: about
  // the one clamped node, kNone: two or more clamped nodes hold the mesh).
  enum class FreeTurn { kNone, kFree, kPivot };
  FreeTurn free_turn_ = FreeTurn::kNone;
  int pivot_ = -1;                    // the clamped node (kPivot)
  std::span<const double> movable_;
};

}  // namespace calib
