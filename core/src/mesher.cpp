#include "calib/core/mesher.h"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Constrained_triangulation_face_base_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2_algorithms.h>
#include <CGAL/Triangulation_data_structure_2.h>
#include <CGAL/Triangulation_face_base_with_info_2.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <cmath>
#include <stdexcept>

namespace calib {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = Kernel::Point_2;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<int, Kernel>;  // node index
// Face info: number of polygon sides crossed to reach the face from outside
// (-1 until visited); the polygon's interior is the faces at depth 1.
using FaceBase = CGAL::Triangulation_face_base_with_info_2<
    int, Kernel, CGAL::Constrained_triangulation_face_base_2<Kernel>>;
using Tds = CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>;
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::Exact_predicates_tag>;

// Meshes of more nodes than this are refused as a sign of a wrong unit.
constexpr double kMaxNodes = 5e6;

Point ToPoint(const Vec2& p) { return Point(p.x(), p.y()); }

std::vector<Point> ToPoints(const std::vector<Vec2>& polygon) {
  std::vector<Point> points;
  points.reserve(polygon.size());
  for (const Vec2& p : polygon) points.push_back(ToPoint(p));
  return points;
}

double SegmentDistance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

double PolygonArea(const std::vector<Vec2>& polygon) {
  double twice = 0.0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    twice += Cross(polygon[i], polygon[(i + 1) % polygon.size()]);
  }
  return 0.5 * twice;
}

// The outline resampled at about `edge` spacing: vertices where it turns by
// more than kCornerTurnRad are kept as nodes (corners, no closer than half an
// edge to each other). A chain between corners whose sides are all at least
// half an edge long keeps its vertices and has each side split evenly, so
// the boundary is exactly the polygon; other chains are split into pieces of
// equal arc length. An outline traced from a mask has many vertices a pixel
// or two apart, which a mesh of `edge` cannot follow; they are passed over.
// A point on a chain is the weighted mean of its segment's ends, so mirrored
// chains give mirrored points.
std::vector<Vec2> ResampleBoundary(const std::vector<Vec2>& polygon, double edge) {
  constexpr double kCornerTurnRad = 0.7;  // 40 degrees
  const size_t n = polygon.size();
  std::vector<size_t> corners;
  for (size_t k = 0; k < n; ++k) {
    const Vec2 in = polygon[k] - polygon[(k + n - 1) % n];
    const Vec2 out = polygon[(k + 1) % n] - polygon[k];
    if (std::abs(std::atan2(Cross(in, out), in.dot(out))) <= kCornerTurnRad) continue;
    if (!corners.empty() && (polygon[k] - polygon[corners.back()]).norm() < 0.5 * edge) continue;
    corners.push_back(k);
  }
  while (corners.size() > 1 &&
         (polygon[corners.back()] - polygon[corners.front()]).norm() < 0.5 * edge) {
    corners.pop_back();
  }
  if (corners.empty()) corners.push_back(0);  // a smooth outline: start anywhere

  std::vector<Vec2> out;
  for (size_t c = 0; c < corners.size(); ++c) {
    const size_t first = corners[c];
    const size_t last = corners[(c + 1) % corners.size()];
    // The chain's vertices first, ..., last (cyclically; the whole loop when
    // there is only one corner).
    std::vector<size_t> chain = {first};
    for (size_t k = (first + 1) % n; k != last; k = (k + 1) % n) chain.push_back(k);
    chain.push_back(last);
    double length = 0.0, shortest = std::numeric_limits<double>::infinity();
    for (size_t k = 0; k + 1 < chain.size(); ++k) {
      const double side = (polygon[chain[k + 1]] - polygon[chain[k]]).norm();
      length += side;
      shortest = std::min(shortest, side);
    }
    if (shortest >= 0.5 * edge) {
      // Sides long enough to keep: the boundary is exactly the polygon, each
      // side split evenly.
      for (size_t k = 0; k + 1 < chain.size(); ++k) {
        const Vec2& a = polygon[chain[k]];
        const Vec2& b = polygon[chain[k + 1]];
        const long m = std::max(1L, std::lround((b - a).norm() / edge));
        for (long t = 0; t < m; ++t) {
          out.push_back((static_cast<double>(m - t) * a + static_cast<double>(t) * b) /
                        static_cast<double>(m));
        }
      }
      continue;
    }
    const long pieces = std::max(1L, std::lround(length / edge));
    const double step = length / static_cast<double>(pieces);
    out.push_back(polygon[first]);
    size_t seg = 0;
    double seg_start = 0.0;
    for (long t = 1; t < pieces; ++t) {
      const double s = step * static_cast<double>(t);
      double seg_len = (polygon[chain[seg + 1]] - polygon[chain[seg]]).norm();
      while (seg + 2 < chain.size() && seg_start + seg_len < s) {
        seg_start += seg_len;
        ++seg;
        seg_len = (polygon[chain[seg + 1]] - polygon[chain[seg]]).norm();
      }
      const double u = seg_len > 0.0 ? std::clamp((s - seg_start) / seg_len, 0.0, 1.0) : 0.0;
      out.push_back((1.0 - u) * polygon[chain[seg]] + u * polygon[chain[seg + 1]]);
    }
  }
  return out;
}

void CheckPolygon(const std::vector<Vec2>& polygon, const MesherOptions& options) {
  if (polygon.size() < 3) {
    throw std::invalid_argument(
        fmt::format("MeshPolygon: polygon has {} vertices; need at least 3", polygon.size()));
  }
  for (size_t i = 0; i < polygon.size(); ++i) {
    if (!polygon[i].allFinite()) {
      throw std::invalid_argument(fmt::format(
          "MeshPolygon: polygon vertex {} = ({}, {}) is not finite", i, polygon[i].x(),
          polygon[i].y()));
    }
  }
  const std::vector<Point> points = ToPoints(polygon);
  const Kernel traits;
  if (!CGAL::is_simple_2(points.begin(), points.end(), traits)) {
    throw std::invalid_argument(fmt::format(
        "MeshPolygon: polygon of {} vertices is not simple (its sides cross or touch, or a "
        "vertex repeats)",
        polygon.size()));
  }
  const double area = std::abs(PolygonArea(polygon));
  const double edge = options.edge_length_px;
  const double triangle_area = std::sqrt(3.0) / 4.0 * edge * edge;
  if (area < triangle_area) {
    throw std::invalid_argument(fmt::format(
        "MeshPolygon: polygon area {} px^2 is too small for edge_length_px = {} (less than one "
        "equilateral triangle, {} px^2)",
        area, edge, triangle_area));
  }
  if (area / (2.0 * triangle_area) > kMaxNodes) {
    throw std::invalid_argument(fmt::format(
        "MeshPolygon: polygon area {} px^2 with edge_length_px = {} would give more than {} "
        "nodes",
        area, edge, kMaxNodes));
  }
}

// Sets each face's info to its depth: the number of constrained edges crossed
// from the infinite face. Purely combinatorial, so unlike a centroid test it
// cannot be fooled by slivers between nearly collinear boundary nodes.
void MarkDepth(Cdt& cdt) {
  for (auto f = cdt.all_faces_begin(); f != cdt.all_faces_end(); ++f) f->info() = -1;
  std::vector<Cdt::Face_handle> frontier = {cdt.infinite_face()};
  cdt.infinite_face()->info() = 0;
  std::vector<Cdt::Face_handle> next_depth;
  for (int depth = 0; !frontier.empty(); ++depth) {
    while (!frontier.empty()) {
      const Cdt::Face_handle f = frontier.back();
      frontier.pop_back();
      for (int k = 0; k < 3; ++k) {
        const Cdt::Face_handle n = f->neighbor(k);
        if (n->info() != -1) continue;
        if (cdt.is_constrained(Cdt::Edge(f, k))) {
          next_depth.push_back(n);
        } else {
          n->info() = depth;
          frontier.push_back(n);
        }
      }
    }
    for (const Cdt::Face_handle& f : next_depth) {
      if (f->info() == -1) {
        f->info() = depth + 1;
        frontier.push_back(f);
      }
    }
    next_depth.clear();
  }
}

}  // namespace

bool MesherOptions::IsValid(std::string* error) const {
  if (!std::isfinite(edge_length_px) || !(edge_length_px > 0.0)) {
    if (error != nullptr) {
      *error = fmt::format("MesherOptions::edge_length_px = {}. Violated: finite and > 0.",
                           edge_length_px);
    }
    return false;
  }
  return true;
}

Mesh MeshPolygon(const std::vector<Vec2>& polygon, const MesherOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("MeshPolygon: " + error);
  CheckPolygon(polygon, options);
  const double edge = options.edge_length_px;

  // The mesh's boundary is the resampled outline; lattice nodes are placed
  // inside it, clear of it.
  std::vector<Vec2> nodes = ResampleBoundary(polygon, edge);
  const int num_boundary = static_cast<int>(nodes.size());
  const std::vector<Vec2> boundary(nodes.begin(), nodes.end());
  const std::vector<Point> points = ToPoints(boundary);
  const Kernel traits;
  if (!CGAL::is_simple_2(points.begin(), points.end(), traits)) {
    throw std::invalid_argument(fmt::format(
        "MeshPolygon: the outline resampled at edge_length_px = {} crosses itself; use a "
        "smaller edge length",
        edge));
  }
  auto inside = [&](const Vec2& p) {
    return CGAL::bounded_side_2(points.begin(), points.end(), ToPoint(p), traits) ==
           CGAL::ON_BOUNDED_SIDE;
  };

  // Equilateral lattice through the bounding box centre; odd rows are shifted
  // by half a spacing, which keeps the lattice symmetric about both centre
  // lines of the box.
  double x_min = polygon[0].x(), x_max = x_min, y_min = polygon[0].y(), y_max = y_min;
  for (const Vec2& p : polygon) {
    x_min = std::min(x_min, p.x());
    x_max = std::max(x_max, p.x());
    y_min = std::min(y_min, p.y());
    y_max = std::max(y_max, p.y());
  }
  const Vec2 centre(0.5 * (x_min + x_max), 0.5 * (y_min + y_max));
  const double row_step = edge * std::sqrt(3.0) / 2.0;
  const long rows = static_cast<long>(std::ceil(0.5 * (y_max - y_min) / row_step)) + 1;
  const long cols = static_cast<long>(std::ceil(0.5 * (x_max - x_min) / edge)) + 1;
  const double clearance = kBoundaryClearance * edge;
  for (long j = -rows; j <= rows; ++j) {
    const double shift = (j % 2 != 0) ? 0.5 : 0.0;
    for (long i = -cols; i <= cols; ++i) {
      const Vec2 p(centre.x() + (static_cast<double>(i) + shift) * edge,
                   centre.y() + static_cast<double>(j) * row_step);
      if (!inside(p)) continue;
      bool clear = true;
      for (size_t k = 0; k < boundary.size() && clear; ++k) {
        clear = SegmentDistance(p, boundary[k], boundary[(k + 1) % boundary.size()]) >= clearance;
      }
      if (clear) nodes.push_back(p);
    }
  }

  Cdt cdt;
  std::vector<Cdt::Vertex_handle> handles;
  handles.reserve(nodes.size());
  for (size_t n = 0; n < nodes.size(); ++n) {
    handles.push_back(cdt.insert(ToPoint(nodes[n])));
    handles.back()->info() = static_cast<int>(n);
  }
  for (int b = 0; b < num_boundary; ++b) {
    cdt.insert_constraint(handles[b], handles[(b + 1) % num_boundary]);
  }

  MarkDepth(cdt);
  std::vector<std::array<int, 3>> triangles;
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (f->info() != 1) continue;
    std::array<int, 3> tri = {f->vertex(0)->info(), f->vertex(1)->info(), f->vertex(2)->info()};
    // Canonical form (smallest index first, cyclic order kept) and sorted
    // below, so the result does not depend on CGAL's face storage order.
    std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end());
    triangles.push_back(tri);
  }
  std::sort(triangles.begin(), triangles.end());
  return BuildMesh(std::move(nodes), std::move(triangles));
}

}  // namespace calib
