#include "calib/core/model.h"

#include "calib/core/energy_terms.h"

#include <cmath>

namespace calib {

Model::Model(const Mesh& mesh) : mesh_(&mesh), rest_cos_sin_(mesh.triangles.size()) {
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      rest_cos_sin_[t][2 * k] = std::cos(mesh.rest_angle_rad[t][k]);
      rest_cos_sin_[t][2 * k + 1] = std::sin(mesh.rest_angle_rad[t][k]);
    }
  }
}

double Model::ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                            std::span<const Vec2> v, std::span<Vec2> forces) const {
  const Mesh& mesh = *mesh_;
  for (Vec2& f : forces) f.setZero();
  double energy = 0.0;
  const bool damped = params.k_damping != 0.0;
  for (size_t e = 0; e < mesh.edges.size(); ++e) {
    const auto [i, j] = mesh.edges[e];
    const double rest = mesh.rest_length_px[e];
    energy += DistanceEnergy(x[i], x[j], rest, params.k_distance, forces[i], forces[j]);
    if (damped) DistanceDamping(x[i], x[j], v[i], v[j], rest, params.k_damping, forces[i], forces[j]);
  }
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    energy += AreaEnergy(x[a], x[b], x[c], mesh.rest_area_px2[t], params.k_area, forces[a],
                         forces[b], forces[c]);
    if (params.k_angle == 0.0) continue;
    energy += TriangleAngleEnergy(x[a], x[b], x[c], rest_cos_sin_[t], params.k_angle, forces[a],
                                  forces[b], forces[c]);
  }
  return energy;
}

double Model::Energy(const ModelParameters& params, std::span<const Vec2> x) const {
  std::vector<Vec2> v(x.size(), Vec2::Zero()), f(x.size());
  return ComputeForces(params, x, v, f);
}

}  // namespace calib
