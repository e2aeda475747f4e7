#include "calib/core/model.h"

#include "calib/core/energy_terms.h"

#include <cmath>
#include <map>
#include <stdexcept>

namespace calib {

Model::Model(const Mesh& mesh)
    : mesh_(&mesh),
      inv_rest_length_(mesh.edges.size()),
      inv_rest_area_(mesh.triangles.size()),
      rest_cos_sin_(mesh.triangles.size()),
      triangle_edges_(mesh.triangles.size()) {
  std::map<std::pair<int, int>, int> edge_index;
  for (size_t e = 0; e < mesh.edges.size(); ++e) {
    inv_rest_length_[e] = 1.0 / mesh.rest_length_px[e];
    edge_index[{mesh.edges[e][0], mesh.edges[e][1]}] = static_cast<int>(e);
  }
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    inv_rest_area_[t] = 1.0 / mesh.rest_area_px2[t];
    for (int k = 0; k < 3; ++k) {
      rest_cos_sin_[t][2 * k] = std::cos(mesh.rest_angle_rad[t][k]);
      rest_cos_sin_[t][2 * k + 1] = std::sin(mesh.rest_angle_rad[t][k]);
      const int from = mesh.triangles[t][k], to = mesh.triangles[t][(k + 1) % 3];
      const auto it = edge_index.find({std::min(from, to), std::max(from, to)});
      if (it == edge_index.end()) throw std::invalid_argument("Model: mesh edge list is incomplete");
      triangle_edges_[t].edge[k] = it->second;
      triangle_edges_[t].sign[k] = from < to ? 1.0 : -1.0;
    }
  }
}

ForceWorkspace Model::MakeWorkspace() const {
  ForceWorkspace ws;
  ws.edge_vector.resize(mesh_->edges.size());
  ws.edge_inv_length_sq.resize(mesh_->edges.size());
  return ws;
}

double Model::ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                            std::span<const Vec2> v, std::span<Vec2> forces,
                            ForceWorkspace& ws) const {
  const Mesh& mesh = *mesh_;
  for (Vec2& f : forces) f.setZero();
  double energy = 0.0;

  // Edges: distance springs E = 1/2 k_D ((L - D0) / D0)^2 and Teschner damping
  // -k_d / D0^2 ((v_i - v_j).u) u (see energy_terms.h).
  const double k_d = params.k_distance, c_d = params.k_damping;
  for (size_t e = 0; e < mesh.edges.size(); ++e) {
    const int i = mesh.edges[e][0], j = mesh.edges[e][1];
    const Vec2 d = x[j] - x[i];
    const double length_sq = d.squaredNorm();
    ws.edge_vector[e] = d;
    if (!(length_sq > 0.0)) {
      ws.edge_inv_length_sq[e] = 0.0;
      energy += 0.5 * k_d;
      continue;
    }
    const double length = std::sqrt(length_sq);
    const double inv_length = 1.0 / length;
    const double inv_rest = inv_rest_length_[e];
    ws.edge_inv_length_sq[e] = inv_length * inv_length;
    const double strain = (length - mesh.rest_length_px[e]) * inv_rest;
    energy += 0.5 * k_d * strain * strain;
    // Force on j along d: -k_D strain / D0 / L; damping adds
    // -k_d / D0^2 ((v_j - v_i).d) / L^2.
    const double along = -k_d * strain * inv_rest * inv_length -
                         c_d * inv_rest * inv_rest * (v[j] - v[i]).dot(d) * ws.edge_inv_length_sq[e];
    const Vec2 f = along * d;
    forces[j] += f;
    forces[i] -= f;
  }

  // Triangles: signed-area springs and the three angle springs.
  using energy_terms_detail::Atan2;
  using energy_terms_detail::Wrap;
  const double k_a = params.k_area, k_phi = params.k_angle;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const int a = mesh.triangles[t][0], b = mesh.triangles[t][1], c = mesh.triangles[t][2];
    const TriangleEdges& te = triangle_edges_[t];
    const Vec2 ab = te.sign[0] * ws.edge_vector[te.edge[0]];
    const Vec2 bc = te.sign[1] * ws.edge_vector[te.edge[1]];
    const Vec2 ca = te.sign[2] * ws.edge_vector[te.edge[2]];

    // Area: A = 1/2 cross(ab, -ca); dA/dp_k = 1/2 perp_ccw(opposite edge),
    // perp_ccw(x, y) = (-y, x).
    const double area = -0.5 * Cross(ab, ca);
    const double inv_rest_area = inv_rest_area_[t];
    const double rel = (area - mesh.rest_area_px2[t]) * inv_rest_area;
    energy += 0.5 * k_a * rel * rel;
    const double s = -0.5 * k_a * rel * inv_rest_area;
    Vec2 f_a = s * Vec2(-bc.y(), bc.x());
    Vec2 f_b = s * Vec2(-ca.y(), ca.x());
    Vec2 f_c = s * Vec2(-ab.y(), ab.x());

    const double i_ab = ws.edge_inv_length_sq[te.edge[0]];
    const double i_bc = ws.edge_inv_length_sq[te.edge[1]];
    const double i_ca = ws.edge_inv_length_sq[te.edge[2]];
    if (k_phi != 0.0 && i_ab > 0.0 && i_bc > 0.0 && i_ca > 0.0) {
      // As TriangleAngleEnergy: deviations at a and b from one atan2 each,
      // the third from the angle sum.
      const auto& cs = rest_cos_sin_[t];
      const Vec2 ra(cs[0] * ab.x() - cs[1] * ab.y(), cs[1] * ab.x() + cs[0] * ab.y());
      const Vec2 rb(cs[2] * bc.x() - cs[3] * bc.y(), cs[3] * bc.x() + cs[2] * bc.y());
      const double d_a = Atan2(-Cross(ra, ca), -ra.dot(ca));
      const double d_b = Atan2(-Cross(rb, ab), -rb.dot(ab));
      const double d_c = Wrap(-(d_a + d_b));
      energy += 0.5 * k_phi * (d_a * d_a + d_b * d_b + d_c * d_c);
      const Vec2 p_ab = i_ab * Vec2(ab.y(), -ab.x());
      const Vec2 p_bc = i_bc * Vec2(bc.y(), -bc.x());
      const Vec2 p_ca = i_ca * Vec2(ca.y(), -ca.x());
      const double w_a = -k_phi * (d_a - d_c);
      const double w_b = -k_phi * (d_b - d_c);
      f_a += (w_b - w_a) * p_ab - w_a * p_ca;
      f_b += (w_a - w_b) * p_ab - w_b * p_bc;
      f_c += w_a * p_ca + w_b * p_bc;
    }
    forces[a] += f_a;
    forces[b] += f_b;
    forces[c] += f_c;
  }
  return energy;
}

double Model::ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                            std::span<const Vec2> v, std::span<Vec2> forces) const {
  ForceWorkspace ws = MakeWorkspace();
  return ComputeForces(params, x, v, forces, ws);
}

double Model::Energy(const ModelParameters& params, std::span<const Vec2> x) const {
  std::vector<Vec2> v(x.size(), Vec2::Zero()), f(x.size());
  return ComputeForces(params, x, v, f);
}

}  // namespace calib
