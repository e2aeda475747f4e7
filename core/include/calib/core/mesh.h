#pragma once
// The triangle mesh of the object and its rest quantities.
//
// Conventions: triangles are stored with positive signed area
//   A = 1/2 cross(p1 - p0, p2 - p0) > 0
// in image coordinates (x right, y down), so "positive" is clockwise on the
// screen. Corner k of a triangle is the angle at vertex k from the edge to the
// next vertex (k+1) to the edge to the previous vertex (k+2), signed as
// atan2(cross, dot); at rest every corner lies in (0, pi).

#include "calib/core/types.h"

#include <span>
#include <string>

namespace calib {

struct Mesh {
  std::vector<Vec2> rest_positions;            ///< #N, pixels; also the frame-0 state.
  std::vector<std::array<int, 2>> edges;        ///< #E unique node pairs (i < j).
  std::vector<std::array<int, 3>> triangles;    ///< #T, positive orientation.
  std::vector<double> rest_length_px;           ///< #E
  std::vector<double> rest_area_px2;            ///< #T, > 0
  std::vector<std::array<double, 3>> rest_angle_rad;  ///< #T x 3, in (0, pi)
  /// Closed boundary loops (node indices), oriented so the interior lies on
  /// the same side as for a positive triangle; a simple object has one.
  std::vector<std::vector<int>> boundary_loops;

  int NumNodes() const { return static_cast<int>(rest_positions.size()); }
  int NumEdges() const { return static_cast<int>(edges.size()); }
  int NumTriangles() const { return static_cast<int>(triangles.size()); }
};

/// Signed area of triangle (a, b, c): 1/2 cross(b - a, c - a).
inline double SignedArea(const Vec2& a, const Vec2& b, const Vec2& c) {
  return 0.5 * Cross(b - a, c - a);
}

/// Builds a Mesh from node positions and triangles: orients every triangle
/// positively, derives the unique edges, the boundary loops and all rest
/// quantities. Throws std::invalid_argument, naming the triangle, when a
/// triangle is degenerate or an index is out of range.
Mesh BuildMesh(std::vector<Vec2> positions, std::vector<std::array<int, 3>> triangles);

/// Triangle quality figures of a mesh.
struct MeshQuality {
  int num_nodes = 0;
  int num_triangles = 0;
  double min_angle_deg = 0.0;
  double max_angle_deg = 0.0;
  double mean_edge_px = 0.0;
  double min_edge_px = 0.0;
  double max_edge_px = 0.0;
  /// Worst ratio of circumradius to twice the inradius (1 for equilateral).
  double worst_radius_ratio = 0.0;
  double area_px2 = 0.0;
  std::string BriefReport() const;
};

MeshQuality MeasureQuality(const Mesh& mesh);

/// The area centroid of the mesh's triangles at `positions` (one per node),
/// signed areas weighting each triangle's centroid; NaN when the total area
/// is zero.
Vec2 AreaCentroid(const Mesh& mesh, std::span<const Vec2> positions);

}  // namespace calib
