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
#include <array>
#include <cstdint>
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

// Sets each face's info to its depth: the number of outline edges crossed
// from the infinite face (the held regions' lines are constrained too, but do
// not count). Purely combinatorial, so unlike a centroid test it cannot be
// fooled by slivers between nearly collinear boundary nodes.
template <class IsOutline>
void MarkDepth(Cdt& cdt, const IsOutline& is_outline) {
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
        if (is_outline(Cdt::Edge(f, k))) {
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

// A side of a held region inside the outline, from a to b. An end is where
// the side crosses the outline (on boundary edge `edge[e]` at parameter
// `t[e]`), or a corner of the region inside the object (edge[e] = -1).
struct HeldLine {
  std::array<Vec2, 2> end;
  std::array<long, 2> edge = {-1, -1};
  std::array<double, 2> t = {0.0, 0.0};
  int axis = 0;  // the coordinate that is constant along the line
};

// The stretches of the held regions' sides inside `boundary`, in order
// (region, then its top, bottom, left and right side, then along the side).
// A crossing is where the boundary edge's ends lie on either side of the
// side's line, "on the line" counting as below it, so a boundary vertex on
// the line is crossed once and a boundary edge along it not at all. The
// point's constant coordinate is the side's own, exactly, so its node is
// held by the region's closed rectangle.
std::vector<HeldLine> FindHeldLines(const std::vector<RectPx>& regions,
                                    const std::vector<Vec2>& boundary, double edge) {
  const std::vector<Point> points = ToPoints(boundary);
  const Kernel traits;
  const size_t nb = boundary.size();
  std::vector<HeldLine> lines;
  for (const RectPx& r : regions) {
    const double x0 = r.x, x1 = r.x + r.width, y0 = r.y, y1 = r.y + r.height;
    // Each side as (constant axis, its value, the range along the other axis).
    const std::array<std::array<double, 4>, 4> sides = {{
        {1, y0, x0, x1}, {1, y1, x0, x1}, {0, x0, y0, y1}, {0, x1, y0, y1}}};
    for (const auto& [axis_d, value, lo, hi] : sides) {
      if (!(hi > lo)) continue;
      const int axis = static_cast<int>(axis_d), along = 1 - axis;
      auto at = [&](double u) {
        Vec2 p;
        p[axis] = value;
        p[along] = u;
        return p;
      };
      struct Break {
        double u;
        long edge;
        double t;
      };
      std::vector<Break> breaks = {{lo, -1, 0.0}, {hi, -1, 0.0}};
      for (size_t k = 0; k < nb; ++k) {
        const Vec2& p = boundary[k];
        const Vec2& q = boundary[(k + 1) % nb];
        const double dp = p[axis] - value, dq = q[axis] - value;
        if ((dp > 0.0) == (dq > 0.0)) continue;
        const double t = dp / (dp - dq);
        const double u = t == 0.0 ? p[along] : t == 1.0 ? q[along] : p[along] + t * (q[along] - p[along]);
        if (u < lo || u > hi) continue;
        breaks.push_back({u, static_cast<long>(k), t});
      }
      // Crossings before the corners they coincide with.
      std::sort(breaks.begin(), breaks.end(), [](const Break& a, const Break& b) {
        return a.u != b.u ? a.u < b.u : a.edge > b.edge;
      });
      for (size_t i = 0; i + 1 < breaks.size(); ++i) {
        const Break& a = breaks[i];
        const Break& b = breaks[i + 1];
        if (!(b.u - a.u >= 0.5 * edge)) continue;  // a graze of a corner: no line
        const Vec2 mid = at(0.5 * (a.u + b.u));
        if (CGAL::bounded_side_2(points.begin(), points.end(), ToPoint(mid), traits) !=
            CGAL::ON_BOUNDED_SIDE) {
          continue;
        }
        HeldLine line;
        line.end = {at(a.u), at(b.u)};
        line.edge = {a.edge, b.edge};
        line.t = {a.t, b.t};
        line.axis = axis;
        lines.push_back(line);
      }
    }
  }
  // Lines that would cross a line already kept (overlapping regions) are
  // left out: the triangulation would add a node where they cross.
  std::vector<HeldLine> kept;
  for (const HeldLine& line : lines) {
    bool crosses = false;
    for (const HeldLine& other : kept) {
      const int a = line.axis, b = 1 - a;
      // Strictly between the ends: meeting at an end is a shared node.
      auto between = [](double v, double e0, double e1) {
        return v > std::min(e0, e1) && v < std::max(e0, e1);
      };
      if (other.axis == a) {
        // Parallel: they clash only on the same line, overlapping.
        crosses = line.end[0][a] == other.end[0][a] &&
                  std::max(std::min(line.end[0][b], line.end[1][b]),
                           std::min(other.end[0][b], other.end[1][b])) <
                      std::min(std::max(line.end[0][b], line.end[1][b]),
                               std::max(other.end[0][b], other.end[1][b]));
      } else {
        // Perpendicular: where they meet must not be inside both.
        const double along_line = other.end[0][b];   // other's constant coordinate
        const double along_other = line.end[0][a];   // line's constant coordinate
        crosses = between(along_line, line.end[0][b], line.end[1][b]) &&
                  between(along_other, other.end[0][a], other.end[1][a]);
      }
      if (crosses) break;
    }
    if (!crosses) kept.push_back(line);
  }
  return kept;
}

// Puts the held lines' crossings into the boundary loop: a boundary node
// within kHeldLineSnap edges of a crossing moves onto it, otherwise a node is
// inserted there. Afterwards each crossing end of a line is a boundary node
// at exactly its position.
std::vector<Vec2> InsertCrossings(const std::vector<Vec2>& boundary,
                                  const std::vector<HeldLine>& lines, double edge) {
  const size_t nb = boundary.size();
  std::vector<Vec2> moved = boundary;
  std::vector<uint8_t> taken(nb, 0);
  std::vector<std::vector<std::pair<double, Vec2>>> inserted(nb);
  for (const HeldLine& line : lines) {
    for (int e = 0; e < 2; ++e) {
      if (line.edge[e] < 0) continue;
      const size_t k = static_cast<size_t>(line.edge[e]);
      const Vec2& point = line.end[e];
      const size_t next = (k + 1) % nb;
      if (moved[k] == point || moved[next] == point) continue;
      bool already = false;
      for (const auto& [t, p] : inserted[k]) already = already || p == point;
      if (already) continue;
      const double to_start = (point - boundary[k]).norm();
      const double to_end = (point - boundary[next]).norm();
      const size_t nearest = to_start <= to_end ? k : next;
      if (std::min(to_start, to_end) <= kHeldLineSnap * edge && taken[nearest] == 0) {
        moved[nearest] = point;
        taken[nearest] = 1;
      } else {
        inserted[k].emplace_back(line.t[e], point);
      }
    }
  }
  std::vector<Vec2> out;
  out.reserve(nb + lines.size() * 2);
  for (size_t k = 0; k < nb; ++k) {
    out.push_back(moved[k]);
    std::sort(inserted[k].begin(), inserted[k].end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& [t, p] : inserted[k]) out.push_back(p);
  }
  return out;
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
  if (min_edges_across < 0 || min_edges_across > kMaxEdgesAcross) {
    if (error != nullptr) {
      *error = fmt::format("MesherOptions::min_edges_across = {}. Violated: 0 <= min_edges_across <= {}.",
                           min_edges_across, kMaxEdgesAcross);
    }
    return false;
  }
  for (size_t i = 0; i < held_regions.size(); ++i) {
    const RectPx& r = held_regions[i];
    const bool finite = std::isfinite(r.x) && std::isfinite(r.y) && std::isfinite(r.width) &&
                        std::isfinite(r.height);
    if (!finite || !(r.width >= 0.0) || !(r.height >= 0.0)) {
      if (error != nullptr) {
        *error = fmt::format(
            "MesherOptions::held_regions[{}] = (x {}, y {}, width {}, height {}). Violated: "
            "finite, width and height >= 0.",
            i, r.x, r.y, r.width, r.height);
      }
      return false;
    }
  }
  return true;
}

double MeshEdgeLength(const std::vector<Vec2>& polygon, const MesherOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("MeshEdgeLength: " + error);
  if (polygon.size() < 3) {
    throw std::invalid_argument(
        fmt::format("MeshEdgeLength: polygon of {} vertices (at least 3)", polygon.size()));
  }
  if (options.min_edges_across == 0) return options.edge_length_px;
  double perimeter = 0.0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    perimeter += (polygon[(i + 1) % polygon.size()] - polygon[i]).norm();
  }
  const double width = perimeter > 0.0 ? 2.0 * std::abs(PolygonArea(polygon)) / perimeter : 0.0;
  const double across = width / options.min_edges_across;
  return across > 0.0 ? std::min(options.edge_length_px, across) : options.edge_length_px;
}

Mesh MeshPolygon(const std::vector<Vec2>& polygon, const MesherOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument("MeshPolygon: " + error);
  CheckPolygon(polygon, options);
  if (options.min_edges_across > 0) {
    MesherOptions fine = options;
    fine.edge_length_px = MeshEdgeLength(polygon, options);
    fine.min_edges_across = 0;
    return MeshPolygon(polygon, fine);
  }
  const double edge = options.edge_length_px;

  // The mesh's boundary is the resampled outline, with a node wherever a held
  // region's side crosses it; lattice nodes are placed inside it, clear of it
  // and of those sides.
  std::vector<Vec2> boundary = ResampleBoundary(polygon, edge);
  const std::vector<HeldLine> held_lines = FindHeldLines(options.held_regions, boundary, edge);
  if (!held_lines.empty()) boundary = InsertCrossings(boundary, held_lines, edge);
  const int num_boundary = static_cast<int>(boundary.size());
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

  // The held lines' nodes: their ends (a boundary node, or a region's corner
  // inside the object, shared by its two sides) and each line split evenly,
  // its constant coordinate kept exactly.
  std::vector<Vec2> nodes = boundary;
  auto node_at = [&](const Vec2& p) {
    const auto found = std::find(nodes.begin(), nodes.end(), p);
    if (found != nodes.end()) return static_cast<int>(found - nodes.begin());
    nodes.push_back(p);
    return static_cast<int>(nodes.size()) - 1;
  };
  std::vector<std::pair<int, int>> held_segments;
  for (const HeldLine& line : held_lines) {
    const int axis = line.axis, along = 1 - axis;
    const Vec2& a = line.end[0];
    const Vec2& b = line.end[1];
    const long m = std::max(1L, std::lround(std::abs(b[along] - a[along]) / edge));
    int previous = node_at(a);
    for (long t = 1; t <= m; ++t) {
      Vec2 p = b;
      if (t < m) {
        p[along] = (static_cast<double>(m - t) * a[along] + static_cast<double>(t) * b[along]) /
                   static_cast<double>(m);
      }
      const int current = node_at(p);
      held_segments.emplace_back(previous, current);
      previous = current;
    }
  }
  std::vector<std::pair<Vec2, Vec2>> keep_clear;
  for (int b = 0; b < num_boundary; ++b) {
    keep_clear.emplace_back(boundary[b], boundary[(b + 1) % num_boundary]);
  }
  for (const auto& [i, j] : held_segments) keep_clear.emplace_back(nodes[i], nodes[j]);

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
      for (size_t k = 0; k < keep_clear.size() && clear; ++k) {
        clear = SegmentDistance(p, keep_clear[k].first, keep_clear[k].second) >= clearance;
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
  for (const auto& [i, j] : held_segments) cdt.insert_constraint(handles[i], handles[j]);
  if (cdt.number_of_vertices() != nodes.size()) {
    throw std::logic_error(fmt::format(
        "MeshPolygon: the triangulation has {} vertices for {} nodes: a held region's side "
        "crosses another constraint",
        cdt.number_of_vertices(), nodes.size()));
  }

  auto is_outline = [&](const Cdt::Edge& e) {
    if (!cdt.is_constrained(e)) return false;
    const int i = e.first->vertex(Cdt::cw(e.second))->info();
    const int j = e.first->vertex(Cdt::ccw(e.second))->info();
    if (i >= num_boundary || j >= num_boundary) return false;
    const int d = std::abs(i - j);
    return d == 1 || d == num_boundary - 1;
  };
  MarkDepth(cdt, is_outline);
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
