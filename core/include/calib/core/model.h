#pragma once
// The mass-spring-like model: sums the energy terms over the mesh.
//
// The sums are written for speed: rest quantities are inverted once here,
// and one pass over the edges computes each edge's vector and inverse squared
// length, which the distance and damping springs use and the triangle pass
// reuses for the angle springs (an edge is shared by two triangles). The
// kernels of energy_terms.h are the reference the tests hold these sums to.

#include "calib/core/mesh.h"
#include "calib/core/parameters.h"

#include <span>

namespace calib {

/// Per-thread scratch of Model::ComputeForces, sized by the model.
struct ForceWorkspace {
  std::vector<Vec2> edge_vector;          ///< p_j - p_i per edge
  std::vector<double> edge_inv_length_sq;  ///< 1 / |p_j - p_i|^2 per edge (0 if degenerate)
};

class Model {
 public:
  /// Keeps a reference to `mesh`, which must outlive the model.
  explicit Model(const Mesh& mesh);

  const Mesh& mesh() const { return *mesh_; }

  ForceWorkspace MakeWorkspace() const;

  /// Overwrites `forces` (#N) with the internal forces at positions `x` and
  /// velocities `v` (#N each): distance, area and angle springs plus edge
  /// damping. Returns the elastic energy (damping has none). Allocates
  /// nothing.
  double ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                       std::span<const Vec2> v, std::span<Vec2> forces,
                       ForceWorkspace& workspace) const;

  /// As above with a temporary workspace (tests, one-off calls).
  double ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                       std::span<const Vec2> v, std::span<Vec2> forces) const;

  /// Elastic energy at positions `x`.
  double Energy(const ModelParameters& params, std::span<const Vec2> x) const;

 private:
  /// A triangle's three edges (ab, bc, ca) as edge indices, and +1 where the
  /// stored edge (i < j) runs the triangle's way round, -1 otherwise.
  struct TriangleEdges {
    std::array<int, 3> edge;
    std::array<double, 3> sign;
  };

  const Mesh* mesh_;
  std::vector<double> inv_rest_length_;     ///< 1 / D0 per edge
  std::vector<double> inv_rest_area_;       ///< 1 / A0 per triangle
  std::vector<std::array<double, 6>> rest_cos_sin_;  ///< cos, sin of rest corner angles
  std::vector<TriangleEdges> triangle_edges_;
};

}  // namespace calib
