#pragma once
// The sparse matrix of the implicit first-order step (implicit_step.h):
// its pattern and numbering, the unit matrices it is assembled from, the
// effects' stiffness at the rest shape and the springs' stiffness at the
// current shape.
//
// K0 = k_D K_D + k_A K_A + k_phi K_phi, where the unit matrices are the
// model's force Jacobians at the rest shape with one stiffness set to 1,
// assembled once by central differences of Model::ComputeForces (exact
// zeros away from a node's neighbours). Clamped nodes have no unknowns. The
// unknowns are numbered once by an approximate minimum degree ordering, so
// the factor stays sparse; Assemble writes the values of
// m / h I + K0 + k_d / h D0 on the pattern and allocates nothing.
//
// Effects that add springs about the rest shape (EffectHooks::
// rest_stiffness: a stiffness field) add their stiffness at the rest shape
// to K0, probed by central differences of their forces, the unknowns whose
// neighbourhoods do not overlap together.
//
// Springs that stiffen with strain (EffectHooks::shape_stiffness) have no
// stiffness at the rest shape. Built with `edge_stiffness`, the pattern
// holds every edge's node blocks, and the matrix is also kept as its upper
// triangle, on which BeginShapeStiffness and AddEdgeStiffness put their
// axial stiffness at the current shape on top of the assembled matrix.

#include "calib/core/mesh.h"
#include "calib/core/model.h"
#include "calib/core/parameters.h"
#include "calib/core/types.h"

#include <Eigen/SparseCore>

#include <array>
#include <functional>
#include <span>
#include <vector>

namespace calib {

/// The implicit step's matrix: its pattern built once per simulator, its
/// values assembled once per candidate.
class ImplicitStepAssembly {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double>;

  /// Assembles the unit matrices of `model` (at its mesh's rest shape) for
  /// the nodes with `movable` != 0 and numbers their unknowns. With
  /// `edge_stiffness`, the matrix's pattern holds every mesh edge's node
  /// blocks, for AddEdgeStiffness.
  ImplicitStepAssembly(const Model& model, std::span<const double> movable, bool edge_stiffness);

  /// Forces added to the model's (ADDS them to f at the positions x, #N
  /// each, zero velocities) whose stiffness the step also takes implicitly.
  using ExtraForces = std::function<void(std::span<const Vec2> x, std::span<Vec2> f)>;

  /// Writes the values of m / h I + K0 + (k_d / h) D0 for `params` and step
  /// `h` into lower(), K0 also holding the stiffness of `extra` (when not
  /// null) at the rest shape: each node's forces must depend only on the
  /// nodes sharing a model element with it (EffectHooks::rest_stiffness).
  /// Its columns are probed by central differences, the unknowns whose
  /// neighbourhoods do not overlap together (a few dozen evaluations of
  /// `extra` a candidate). Allocates nothing.
  void Assemble(const ModelParameters& params, double h, const ExtraForces* extra);

  /// Re-linearisation at a shape, after Assemble (built with
  /// `edge_stiffness`): BeginShapeStiffness sets upper() to the assembled
  /// matrix, AddEdgeStiffness adds an edge spring's axial stiffness k u u^T
  /// (k >= 0) to it. Allocate nothing.
  void BeginShapeStiffness();
  void AddEdgeStiffness(int edge, double k, const Vec2& u);

  /// The step's matrix over the unknowns: its lower triangle as Assemble
  /// left it, and (built with `edge_stiffness`) its upper triangle as the
  /// shape's stiffness left it (empty without).
  const SparseMatrix& lower() const { return A_; }
  const SparseMatrix& upper() const { return upper_; }
  /// Whether the last Assemble had extra forces.
  bool has_extra() const { return has_extra_; }

  int num_unknowns() const { return static_cast<int>(coordinate_of_unknown_.size()); }
  /// Unknown k is coordinate coordinate_of_unknown()[k] (node i: 2 i, 2 i + 1).
  std::span<const int> coordinate_of_unknown() const { return coordinate_of_unknown_; }
  /// Its inverse over the 2N coordinates; -1 for clamped nodes.
  std::span<const int> unknown_of_coordinate() const { return unknown_of_coordinate_; }

  /// The stiffness K0 of `params` over all 2N coordinates (node i: rows 2i,
  /// 2i+1; zero rows and columns for clamped nodes), for tests.
  SparseMatrix Stiffness(const ModelParameters& params) const;

  /// The stiffness of the last Assemble's `extra` forces, as Stiffness
  /// (zero without them), for tests.
  SparseMatrix ExtraStiffness() const;

 private:
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
  SparseMatrix OverCoordinates(Value value) const;
  // The values of A_ after Assemble (the shape's stiffness goes on top).
  // The re-linearised matrix is kept as its upper triangle (upper_, A_
  // transposed: where upper_of_lower_ says), which Eigen's factorisation
  // reads in place where a lower one is copied every time; per mesh edge
  // the positions in upper_ of its node blocks' entries (-1 for a clamped
  // node's): ii xx, ii yy, ii xy, jj xx, jj yy, jj xy, ij xx, ij xy, ij yx,
  // ij yy.
  std::vector<double> configured_;
  SparseMatrix upper_;
  std::vector<int> upper_of_lower_;
  std::vector<std::array<int, 10>> edge_positions_;
  std::vector<int> diagonal_;  // index of each unknown's diagonal entry in A_'s values
  SparseMatrix A_;             // lower triangle of the step's matrix, permuted
};

}  // namespace calib
