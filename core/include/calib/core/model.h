#pragma once
// The mass-spring-like model: sums the energy-term kernels over the mesh.

#include "calib/core/mesh.h"
#include "calib/core/parameters.h"

#include <span>

namespace calib {

class Model {
 public:
  /// Keeps a reference to `mesh`, which must outlive the model.
  explicit Model(const Mesh& mesh);

  const Mesh& mesh() const { return *mesh_; }

  /// Overwrites `forces` (#N) with the internal forces at positions `x` and
  /// velocities `v` (#N each): distance, area and angle springs plus edge
  /// damping. Returns the elastic energy (damping has none).
  double ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                       std::span<const Vec2> v, std::span<Vec2> forces) const;

  /// Elastic energy at positions `x`.
  double Energy(const ModelParameters& params, std::span<const Vec2> x) const;

 private:
  const Mesh* mesh_;
  /// cos and sin of each triangle's three rest corner angles.
  std::vector<std::array<double, 6>> rest_cos_sin_;
};

}  // namespace calib
