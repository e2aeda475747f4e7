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
// effects' forces) explicitly. Its fixed points are the explicit step's
// (dx = 0 where the forces balance); for small h it agrees with it to first
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

#include "calib/core/mesh.h"
#include "calib/core/model.h"
#include "calib/core/parameters.h"
#include "calib/core/types.h"

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <span>
#include <string>
#include <vector>

namespace calib {

class ImplicitFirstOrderStep {
 public:
  /// Assembles the unit matrices of `model` (at its mesh's rest shape) for
  /// the nodes with `movable` != 0. `movable` must outlive this.
  ImplicitFirstOrderStep(const Model& model, std::span<const double> movable);

  /// Factorises m / h I + K0 + (k_d / h) D0 for `params` and step `h`.
  /// Returns false with *error set when the matrix is not positive definite
  /// (it is for every valid parameter set: K0 and D0 are positive
  /// semi-definite at the rest shape).
  bool Configure(const ModelParameters& params, double h, std::string* error);

  /// x += dx for the forces `f` (#N, the springs without damping plus every
  /// explicit force) at the positions `x`; clamped nodes stay. After a
  /// successful Configure. Allocates nothing.
  void Step(std::span<const Vec2> f, std::span<Vec2> x);

  /// The stiffness K0 of `params` over all 2N coordinates (node i: rows 2i,
  /// 2i+1; zero rows and columns for clamped nodes), for tests.
  Eigen::SparseMatrix<double> Stiffness(const ModelParameters& params) const;

  int num_unknowns() const { return static_cast<int>(coordinate_of_unknown_.size()); }

 private:
  using SparseMatrix = Eigen::SparseMatrix<double>;

  int num_coordinates_ = 0;           // 2 N
  std::vector<int> coordinate_of_unknown_;  // unknown k: coordinate coordinate_of_unknown_[k] (2 i + d)
  // The unit matrices' values on A's pattern (A_ below), in its storage order.
  std::vector<double> distance_, area_, angle_, damping_;
  std::vector<int> diagonal_;  // index of each unknown's diagonal entry in A_'s values
  SparseMatrix A_;             // lower triangle of the step's matrix, permuted
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower, Eigen::NaturalOrdering<int>> factor_;
  Eigen::VectorXd rhs_, solution_;
  double h_over_m_ = 0.0;

  // The rotation K0 leaves free (kFree: about the centroid, kPivot: about
  // the one clamped node, kNone: two or more clamped nodes hold the mesh).
  enum class FreeTurn { kNone, kFree, kPivot };
  FreeTurn free_turn_ = FreeTurn::kNone;
  int pivot_ = -1;                    // the clamped node (kPivot)
  std::span<const double> movable_;
};

}  // namespace calib
