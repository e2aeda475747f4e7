#include "calib/core/model.h"

#include <cassert>

#include "calib/core/enum_names.h"
#include "force_kernels.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <stdexcept>
#include <utility>

namespace calib {
namespace {

constexpr auto kForceKernelNames = std::to_array<EnumName<ForceKernel>>({
    {ForceKernel::kAuto, "auto"},
    {ForceKernel::kBaseline, "baseline"},
    {ForceKernel::kAvx2, "avx2"},
    {ForceKernel::kAvx512, "avx512"},
});

// Each triangle's edges (ab, bc, ca) as indices of mesh.edges.
std::vector<std::array<int, 3>> TriangleEdges(const Mesh& mesh) {
  std::map<std::pair<int, int>, int> edge_index;
  for (size_t e = 0; e < mesh.edges.size(); ++e) {
    edge_index[{mesh.edges[e][0], mesh.edges[e][1]}] = static_cast<int>(e);
  }
  std::vector<std::array<int, 3>> edges(mesh.triangles.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int from = mesh.triangles[t][k], to = mesh.triangles[t][(k + 1) % 3];
      const auto it = edge_index.find({std::min(from, to), std::max(from, to)});
      if (it == edge_index.end()) throw std::invalid_argument("Model: mesh edge list is incomplete");
      edges[t][k] = it->second;
    }
  }
  return edges;
}

}  // namespace

std::string ToString(ForceKernel kernel) { return EnumToString(kForceKernelNames, kernel); }

Model::Model(const Mesh& mesh) : mesh_(&mesh) {
  const size_t num_edges = mesh.edges.size(), num_triangles = mesh.triangles.size();
  edge_i_.resize(num_edges);
  edge_j_.resize(num_edges);
  for (std::vector<double>* column : {&rest_length_, &inv_rest_length_}) column->resize(num_edges);
  for (size_t e = 0; e < num_edges; ++e) {
    edge_i_[e] = mesh.edges[e][0];
    edge_j_[e] = mesh.edges[e][1];
  }
  for (std::vector<int>* column : {&triangle_a_, &triangle_b_, &triangle_c_, &triangle_edge_ab_,
                                   &triangle_edge_bc_, &triangle_edge_ca_}) {
    column->resize(num_triangles);
  }
  for (std::vector<double>* column :
       {&rest_area_, &inv_rest_area_, &rest_cos_a_, &rest_sin_a_, &rest_cos_b_, &rest_sin_b_}) {
    column->resize(num_triangles);
  }
  const std::vector<std::array<int, 3>> triangle_edges = TriangleEdges(mesh);
  for (size_t t = 0; t < num_triangles; ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    triangle_a_[t] = a;
    triangle_b_[t] = b;
    triangle_c_[t] = c;
    triangle_edge_ab_[t] = triangle_edges[t][0];
    triangle_edge_bc_[t] = triangle_edges[t][1];
    triangle_edge_ca_[t] = triangle_edges[t][2];
  }

  // The contributions to each node in the order the plain scatter adds them
  // (edges, then triangles, each in index order), as indices of (x, y) pairs
  // of ForceWorkspace::contribution.
  const int num_nodes = mesh.NumNodes();
  const int e_count = static_cast<int>(num_edges), t_count = static_cast<int>(num_triangles);
  std::vector<std::vector<int>> per_node(num_nodes);
  for (int e = 0; e < e_count; ++e) {
    per_node[edge_j_[e]].push_back(e);
    per_node[edge_i_[e]].push_back(e_count + e);
  }
  for (int t = 0; t < t_count; ++t) {
    per_node[triangle_a_[t]].push_back(2 * e_count + t);
    per_node[triangle_b_[t]].push_back(2 * e_count + t_count + t);
    per_node[triangle_c_[t]].push_back(2 * e_count + 2 * t_count + t);
  }
  // Groups of four nodes, by number of forces (most first, then by index),
  // each list padded with the zero pair (after the last triangle's) to its
  // group's longest: +0 added to a sum that started at +0 leaves it as it
  // is (such a sum is never -0), so the sums keep their bits.
  const int zero_pair = 2 * e_count + 3 * t_count;
  std::vector<int> order(num_nodes);
  for (int n = 0; n < num_nodes; ++n) order[n] = n;
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return per_node[a].size() > per_node[b].size();
  });
  const int lanes = force_kernels::kNodeGroup;
  const int num_groups = (num_nodes + lanes - 1) / lanes;
  node_group_start_.assign(num_groups + 1, 0);
  node_group_nodes_.assign(static_cast<size_t>(num_groups) * lanes, -1);
  node_group_pairs_.clear();
  for (int g = 0; g < num_groups; ++g) {
    size_t longest = 0;
    for (int j = 0; j < lanes && g * lanes + j < num_nodes; ++j) {
      const int n = order[g * lanes + j];
      node_group_nodes_[g * lanes + j] = n;
      longest = std::max(longest, per_node[n].size());
    }
    for (size_t slot = 0; slot < longest; ++slot) {
      for (int j = 0; j < lanes; ++j) {
        const int n = node_group_nodes_[g * lanes + j];
        node_group_pairs_.push_back(n >= 0 && slot < per_node[n].size() ? per_node[n][slot]
                                                                         : zero_pair);
      }
    }
    node_group_start_[g + 1] = static_cast<int>(node_group_pairs_.size());
  }
  ResetRestShape();
}

void Model::ResetRestShape() {
  const Mesh& mesh = *mesh_;
  for (size_t e = 0; e < rest_length_.size(); ++e) {
    rest_length_[e] = mesh.rest_length_px[e];
    inv_rest_length_[e] = 1.0 / mesh.rest_length_px[e];
  }
  for (size_t t = 0; t < rest_area_.size(); ++t) {
    rest_area_[t] = mesh.rest_area_px2[t];
    inv_rest_area_[t] = 1.0 / mesh.rest_area_px2[t];
    rest_cos_a_[t] = std::cos(mesh.rest_angle_rad[t][0]);
    rest_sin_a_[t] = std::sin(mesh.rest_angle_rad[t][0]);
    rest_cos_b_[t] = std::cos(mesh.rest_angle_rad[t][1]);
    rest_sin_b_[t] = std::sin(mesh.rest_angle_rad[t][1]);
  }
}

int Model::SetRestShape(std::span<const Vec2> rest) {
  const int num_triangles = static_cast<int>(rest_area_.size());
  for (int t = 0; t < num_triangles; ++t) {
    const Vec2 &a = rest[triangle_a_[t]], &b = rest[triangle_b_[t]], &c = rest[triangle_c_[t]];
    if (!(SignedArea(a, b, c) > 0.0)) return t;
  }
  for (size_t e = 0; e < rest_length_.size(); ++e) {
    rest_length_[e] = (rest[edge_j_[e]] - rest[edge_i_[e]]).norm();
    inv_rest_length_[e] = 1.0 / rest_length_[e];
  }
  // Corner k at p[k] from (p[k+1] - p[k]) to (p[k+2] - p[k]), as mesh.h defines it.
  const auto corner = [](const Vec2& at, const Vec2& next, const Vec2& prev, double& cos_out,
                         double& sin_out) {
    const Vec2 u = next - at, w = prev - at;
    const double inv = 1.0 / (u.norm() * w.norm());
    cos_out = u.dot(w) * inv;
    sin_out = Cross(u, w) * inv;
  };
  for (int t = 0; t < num_triangles; ++t) {
    const Vec2 &a = rest[triangle_a_[t]], &b = rest[triangle_b_[t]], &c = rest[triangle_c_[t]];
    rest_area_[t] = SignedArea(a, b, c);
    inv_rest_area_[t] = 1.0 / rest_area_[t];
    corner(a, b, c, rest_cos_a_[t], rest_sin_a_[t]);
    corner(b, c, a, rest_cos_b_[t], rest_sin_b_[t]);
  }
  return -1;
}

ForceWorkspace Model::MakeWorkspace() const {
  const size_t num_edges = mesh_->edges.size(), num_triangles = mesh_->triangles.size();
  ForceWorkspace ws;
  ws.contribution.assign(2 * (2 * num_edges + 3 * num_triangles + 1), 0.0);
  ws.edge_inv_length_sq.resize(num_edges);
  ws.edge_energy.resize(num_edges);
  ws.triangle_energy.resize(num_triangles);
  ws.triangle_needs_atan2.resize(num_triangles);
  return ws;
}

bool Model::IsAvailable(ForceKernel kernel) {
  switch (kernel) {
    case ForceKernel::kAvx2: return force_kernels::CpuHasAvx2();
    case ForceKernel::kAvx512: return force_kernels::CpuHasAvx512();
    default: return true;
  }
}

double Model::ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                            std::span<const Vec2> v, std::span<Vec2> forces,
                            ForceWorkspace& ws, ForceKernel kernel) const {
  force_kernels::Stiffness k;
  k.distance = params.k_distance;
  k.damping = params.k_damping;
  k.area = params.k_area;
  k.angle = params.k_angle;
  if (!edge_weight_.empty()) {
    return RunKernel(k, edge_weight_.data(), triangle_weight_.data(), angle_weight_.data(), x, v,
                     forces, ws, kernel);
  }
  return RunKernel(k, nullptr, nullptr, nullptr, x, v, forces, ws, kernel);
}

void Model::SetElementWeights(std::span<const double> edge_weight,
                              std::span<const double> triangle_weight,
                              std::span<const double> angle_weight) {
  if (edge_weight.empty() && triangle_weight.empty() && angle_weight.empty()) {
    edge_weight_.clear();
    triangle_weight_.clear();
    angle_weight_.clear();
    return;
  }
  auto check = [](std::span<const double> w, size_t expected, const char* what,
                  const char* element) {
    if (w.size() != expected) {
      throw std::invalid_argument(fmt::format("Model::SetElementWeights: {} {} weights for {} {}s",
                                              w.size(), what, expected, element));
    }
    for (size_t i = 0; i < w.size(); ++i) {
      if (!std::isfinite(w[i]) || !(w[i] > 0.0)) {
        throw std::invalid_argument(fmt::format(
            "Model::SetElementWeights: {} {}'s {} weight is {}; must be finite and > 0", element,
            i, what, w[i]));
      }
    }
  };
  check(edge_weight, edge_i_.size(), "edge", "edge");
  check(triangle_weight, triangle_a_.size(), "triangle", "triangle");
  check(angle_weight, triangle_a_.size(), "angle", "triangle");
  edge_weight_.assign(edge_weight.begin(), edge_weight.end());
  triangle_weight_.assign(triangle_weight.begin(), triangle_weight.end());
  angle_weight_.assign(angle_weight.begin(), angle_weight.end());
}

AreaWeights ComputeAreaWeights(const Mesh& mesh, std::span<const double> triangle_areas) {
  if (!triangle_areas.empty() && triangle_areas.size() != mesh.rest_area_px2.size()) {
    throw std::invalid_argument(fmt::format("area weights: {} triangle areas for a mesh of {} triangles",
                                            triangle_areas.size(), mesh.rest_area_px2.size()));
  }
  const std::span<const double> areas =
      triangle_areas.empty() ? std::span<const double>(mesh.rest_area_px2) : triangle_areas;
  const double lattice_triangle =
      std::sqrt(3.0) / 4.0 * kAreaWeightReferenceEdgePx * kAreaWeightReferenceEdgePx;
  AreaWeights w;
  w.node.assign(mesh.NumNodes(), 0.0);
  w.edge.assign(mesh.NumEdges(), 0.0);
  w.triangle.assign(mesh.NumTriangles(), 0.0);
  w.angle.assign(mesh.NumTriangles(), 1.0);
  const std::vector<std::array<int, 3>> triangle_edges = TriangleEdges(mesh);
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto& tri = mesh.triangles[t];
    const double area = areas[t];
    w.triangle[t] = area / lattice_triangle;
    // A third of the area to each corner and each side: over two lattice
    // triangles (a node's share of the lattice) and over two thirds of one
    // (an edge's).
    for (int k = 0; k < 3; ++k) {
      w.node[tri[k]] += area / (6.0 * lattice_triangle);
      w.edge[triangle_edges[t][k]] += area / (2.0 * lattice_triangle);
    }
  }
  return w;
}

double Model::ComputeScaledForces(const ModelParameters& params, std::span<const double> edge_scale,
                                  std::span<const double> triangle_scale, std::span<const Vec2> x,
                                  std::span<Vec2> forces, ForceWorkspace& ws,
                                  ForceKernel kernel) const {
  assert(edge_scale.size() == edge_i_.size() && triangle_scale.size() == triangle_a_.size());
  force_kernels::Stiffness k;
  k.distance = params.k_distance;
  k.damping = 0.0;
  k.area = params.k_area;
  k.angle = params.k_angle;
  // No damping: the velocities are never read into a result (0 times a
  // finite value), so the positions stand in for them.
  return RunKernel(k, edge_scale.data(), triangle_scale.data(), triangle_scale.data(), x, x,
                   forces, ws, kernel);
}

double Model::RunKernel(const force_kernels::Stiffness& k, const double* edge_scale,
                        const double* triangle_scale, const double* angle_scale,
                        std::span<const Vec2> x,
                        std::span<const Vec2> v, std::span<Vec2> forces, ForceWorkspace& ws,
                        ForceKernel kernel) const {
  force_kernels::Arrays arrays;
  arrays.num_edges = static_cast<int>(edge_i_.size());
  arrays.edge_i = edge_i_.data();
  arrays.edge_j = edge_j_.data();
  arrays.rest_length = rest_length_.data();
  arrays.inv_rest_length = inv_rest_length_.data();
  arrays.num_triangles = static_cast<int>(triangle_a_.size());
  arrays.triangle_a = triangle_a_.data();
  arrays.triangle_b = triangle_b_.data();
  arrays.triangle_c = triangle_c_.data();
  arrays.triangle_edge_ab = triangle_edge_ab_.data();
  arrays.triangle_edge_bc = triangle_edge_bc_.data();
  arrays.triangle_edge_ca = triangle_edge_ca_.data();
  arrays.rest_area = rest_area_.data();
  arrays.inv_rest_area = inv_rest_area_.data();
  arrays.rest_cos_a = rest_cos_a_.data();
  arrays.rest_sin_a = rest_sin_a_.data();
  arrays.rest_cos_b = rest_cos_b_.data();
  arrays.rest_sin_b = rest_sin_b_.data();
  arrays.edge_scale = edge_scale;
  arrays.triangle_scale = triangle_scale;
  arrays.angle_scale = angle_scale;
  arrays.num_node_groups = static_cast<int>(node_group_start_.size()) - 1;
  arrays.node_group_start = node_group_start_.data();
  arrays.node_group_nodes = node_group_nodes_.data();
  arrays.node_group_pairs = node_group_pairs_.data();
  arrays.workspace = &ws;

  // Vec2 is two contiguous doubles, so the spans are interleaved (x, y) arrays.
  // Every node's force is written by the kernel's node pass.
  static_assert(sizeof(Vec2) == 2 * sizeof(double));
  const double* xd = x.data()->data();
  const double* vd = v.data()->data();
  double* fd = forces.data()->data();
  if (kernel == ForceKernel::kAuto) {
    kernel = force_kernels::CpuHasAvx512() ? ForceKernel::kAvx512
             : force_kernels::CpuHasAvx2() ? ForceKernel::kAvx2
                                            : ForceKernel::kBaseline;
  }
  if (kernel == ForceKernel::kAvx512 && force_kernels::CpuHasAvx512()) {
    return force_kernels::ComputeForcesAvx512(arrays, k, xd, vd, fd);
  }
  if (kernel == ForceKernel::kAvx2 && force_kernels::CpuHasAvx2()) {
    return force_kernels::ComputeForcesAvx2(arrays, k, xd, vd, fd);
  }
  return force_kernels::ComputeForcesBaseline(arrays, k, xd, vd, fd);
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
