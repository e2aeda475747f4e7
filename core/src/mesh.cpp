#include "calib/core/mesh.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace calib {
namespace {

// A triangle whose doubled area is below this fraction of its longest edge
// squared is degenerate (its smallest height is below ~1e-10 of its size).
constexpr double kDegenerateRelativeArea = 1e-10;

// Corner k of triangle (p0, p1, p2): angle from (p[k+1] - p[k]) to
// (p[k+2] - p[k]), as mesh.h defines it.
double CornerAngle(const Vec2& at, const Vec2& next, const Vec2& prev) {
  const Vec2 a = next - at;
  const Vec2 b = prev - at;
  return std::atan2(Cross(a, b), a.dot(b));
}

// Shoelace area of a closed node loop, signed like SignedArea.
double LoopArea(const std::vector<Vec2>& positions, const std::vector<int>& loop) {
  double twice = 0.0;
  for (size_t i = 0; i < loop.size(); ++i) {
    twice += Cross(positions[loop[i]], positions[loop[(i + 1) % loop.size()]]);
  }
  return 0.5 * twice;
}

// Chains the boundary edges (each directed as it runs in its positive
// triangle) into closed loops. Each loop starts at its smallest node; loops
// are ordered by decreasing enclosed area, so the outer boundary of a simple
// object comes first and holes (negative area) last.
std::vector<std::vector<int>> ChainBoundaryLoops(const std::vector<Vec2>& positions,
                                                 std::vector<std::array<int, 2>> directed) {
  std::sort(directed.begin(), directed.end());
  std::vector<bool> used(directed.size(), false);
  auto next_unused_from = [&](int node) -> int {
    auto it = std::lower_bound(directed.begin(), directed.end(), std::array<int, 2>{node, -1});
    for (; it != directed.end() && (*it)[0] == node; ++it) {
      const auto k = static_cast<size_t>(it - directed.begin());
      if (!used[k]) return static_cast<int>(k);
    }
    return -1;
  };

  std::vector<std::vector<int>> loops;
  for (size_t first = 0; first < directed.size(); ++first) {
    if (used[first]) continue;
    const int start = directed[first][0];
    std::vector<int> loop;
    int k = static_cast<int>(first);
    while (true) {
      used[k] = true;
      loop.push_back(directed[k][0]);
      const int to = directed[k][1];
      if (to == start) break;
      k = next_unused_from(to);
      if (k < 0) {
        throw std::invalid_argument(fmt::format(
            "BuildMesh: the boundary edges do not form closed loops (stuck at node {}); the "
            "mesh is not an oriented manifold",
            to));
      }
    }
    loops.push_back(std::move(loop));
  }

  std::vector<double> area(loops.size());
  for (size_t i = 0; i < loops.size(); ++i) area[i] = LoopArea(positions, loops[i]);
  std::vector<size_t> order(loops.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return area[a] > area[b]; });
  std::vector<std::vector<int>> sorted;
  sorted.reserve(loops.size());
  for (size_t i : order) sorted.push_back(std::move(loops[i]));
  return sorted;
}

}  // namespace

Mesh BuildMesh(std::vector<Vec2> positions, std::vector<std::array<int, 3>> triangles) {
  const int num_nodes = static_cast<int>(positions.size());
  for (size_t t = 0; t < triangles.size(); ++t) {
    auto& tri = triangles[t];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] < 0 || tri[k] >= num_nodes) {
        throw std::invalid_argument(
            fmt::format("BuildMesh: triangle {} has node index {} out of range [0, {})", t,
                        tri[k], num_nodes));
      }
    }
    const Vec2& a = positions[tri[0]];
    const Vec2& b = positions[tri[1]];
    const Vec2& c = positions[tri[2]];
    const double area = SignedArea(a, b, c);
    const double longest2 =
        std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    if (!std::isfinite(area) || !(std::abs(2.0 * area) > kDegenerateRelativeArea * longest2)) {
      throw std::invalid_argument(fmt::format(
          "BuildMesh: triangle {} (nodes {}, {}, {}) is degenerate: signed area {} px^2", t,
          tri[0], tri[1], tri[2], area));
    }
    if (area < 0.0) std::swap(tri[1], tri[2]);
  }

  Mesh mesh;
  mesh.rest_positions = std::move(positions);
  mesh.triangles = std::move(triangles);

  // Every triangle side once per triangle, as (min, max), plus its direction in
  // the triangle; a side met exactly once is a boundary edge.
  struct Side {
    std::array<int, 2> key;
    std::array<int, 2> directed;
  };
  std::vector<Side> sides;
  sides.reserve(3 * mesh.triangles.size());
  for (const auto& tri : mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      const int i = tri[k], j = tri[(k + 1) % 3];
      sides.push_back({{std::min(i, j), std::max(i, j)}, {i, j}});
    }
  }
  std::sort(sides.begin(), sides.end(), [](const Side& a, const Side& b) {
    return a.key != b.key ? a.key < b.key : a.directed < b.directed;
  });
  std::vector<std::array<int, 2>> boundary;
  for (size_t s = 0; s < sides.size();) {
    size_t e = s;
    while (e < sides.size() && sides[e].key == sides[s].key) ++e;
    mesh.edges.push_back(sides[s].key);
    if (e - s == 1) boundary.push_back(sides[s].directed);
    s = e;
  }
  mesh.boundary_loops = ChainBoundaryLoops(mesh.rest_positions, std::move(boundary));

  const auto& p = mesh.rest_positions;
  mesh.rest_length_px.reserve(mesh.edges.size());
  for (const auto& [i, j] : mesh.edges) mesh.rest_length_px.push_back((p[j] - p[i]).norm());
  mesh.rest_area_px2.reserve(mesh.triangles.size());
  mesh.rest_angle_rad.reserve(mesh.triangles.size());
  for (const auto& tri : mesh.triangles) {
    mesh.rest_area_px2.push_back(SignedArea(p[tri[0]], p[tri[1]], p[tri[2]]));
    std::array<double, 3> angles;
    for (int k = 0; k < 3; ++k) {
      angles[k] = CornerAngle(p[tri[k]], p[tri[(k + 1) % 3]], p[tri[(k + 2) % 3]]);
    }
    mesh.rest_angle_rad.push_back(angles);
  }
  return mesh;
}

MeshQuality MeasureQuality(const Mesh& mesh) {
  MeshQuality q;
  q.num_nodes = mesh.NumNodes();
  q.num_triangles = mesh.NumTriangles();
  if (mesh.triangles.empty()) return q;

  constexpr double kDeg = 180.0 / std::numbers::pi;
  q.min_angle_deg = std::numeric_limits<double>::infinity();
  q.max_angle_deg = -std::numeric_limits<double>::infinity();
  for (const auto& angles : mesh.rest_angle_rad) {
    for (double a : angles) {
      q.min_angle_deg = std::min(q.min_angle_deg, a * kDeg);
      q.max_angle_deg = std::max(q.max_angle_deg, a * kDeg);
    }
  }

  q.min_edge_px = std::numeric_limits<double>::infinity();
  double sum = 0.0;
  for (double l : mesh.rest_length_px) {
    sum += l;
    q.min_edge_px = std::min(q.min_edge_px, l);
    q.max_edge_px = std::max(q.max_edge_px, l);
  }
  q.mean_edge_px = mesh.rest_length_px.empty() ? 0.0 : sum / mesh.rest_length_px.size();

  // R / (2 r) with R = abc / (4 A) and r = A / s (s the half perimeter).
  const auto& p = mesh.rest_positions;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const double a = (p[tri[1]] - p[tri[2]]).norm();
    const double b = (p[tri[2]] - p[tri[0]]).norm();
    const double c = (p[tri[0]] - p[tri[1]]).norm();
    const double area = mesh.rest_area_px2[t];
    const double s = 0.5 * (a + b + c);
    q.worst_radius_ratio = std::max(q.worst_radius_ratio, a * b * c * s / (8.0 * area * area));
    q.area_px2 += area;
  }
  return q;
}

std::string MeshQuality::BriefReport() const {
  return fmt::format(
      "Mesh: {} nodes, {} triangles, area {:.6g} px^2, angles [{:.2f}, {:.2f}] deg, edges "
      "{:.3g} px mean [{:.3g}, {:.3g}], worst radius ratio {:.3f}",
      num_nodes, num_triangles, area_px2, min_angle_deg, max_angle_deg, mean_edge_px,
      min_edge_px, max_edge_px, worst_radius_ratio);
}

Vec2 AreaCentroid(const Mesh& mesh, std::span<const Vec2> positions) {
  double area = 0.0;
  Vec2 moment = Vec2::Zero();
  for (const auto& tri : mesh.triangles) {
    const Vec2& a = positions[tri[0]];
    const Vec2& b = positions[tri[1]];
    const Vec2& c = positions[tri[2]];
    const double t = SignedArea(a, b, c);
    area += t;
    moment += t * (a + b + c) / 3.0;
  }
  if (area == 0.0) return Vec2(NAN, NAN);
  return moment / area;
}

}  // namespace calib
