#pragma once
// Meshing a simple polygon (the object's outline) into a regular triangle mesh.

#include "calib/core/mesh.h"

#include <string>
#include <vector>

namespace calib {

struct MesherOptions {
  /// Target edge length: the spacing of the interior equilateral lattice and
  /// (about) of the nodes along the boundary. Pixels, finite, > 0.
  double edge_length_px = 20.0;

  /// When > 0, a polygon narrower than min_edges_across edges of
  /// edge_length_px is meshed finer: the edge length is at most its mean
  /// width (2 area / perimeter: a strip's width, a disc's radius) over
  /// min_edges_across (MeshEdgeLength), so that a narrow strip has enough
  /// elements across to bend. 0: edge_length_px, whatever the width. At
  /// most kMaxEdgesAcross.
  int min_edges_across = 0;
  static constexpr int kMaxEdgesAcross = 16;

  /// Rectangles (the recording's clamps) whose sides become lines of the
  /// mesh where they cross the object: each side's stretch inside the polygon
  /// is split into round(length / edge_length_px) (at least 1) pieces whose
  /// nodes lie exactly on it, and no triangle crosses it. The part a clamp
  /// holds then ends on a row of nodes on the clamp's edge, wherever the
  /// outline's own nodes fall, so the free part has the same length on every
  /// mesh of the object. Each must be finite with width and height >= 0.
  std::vector<RectPx> held_regions;

  /// False, with a message naming the field, its value and the rule, when an
  /// option is out of range; `error` may be null.
  bool IsValid(std::string* error) const;
};

/// The edge length MeshPolygon meshes `polygon` with: options.edge_length_px,
/// or less where options.min_edges_across asks for it. Throws
/// std::invalid_argument for invalid options or fewer than 3 vertices.
double MeshEdgeLength(const std::vector<Vec2>& polygon, const MesherOptions& options);

/// Meshes the simple polygon `polygon` (#P >= 3 vertices, pixels, either
/// orientation, not closed by repeating the first vertex).
///
/// Interior nodes lie on an equilateral lattice (spacing edge_length_px, rows
/// edge_length_px * sqrt(3) / 2 apart) centred on the polygon's bounding box,
/// so a polygon symmetric about the box's vertical or horizontal centre line
/// gives a node set with the same symmetry. Lattice points outside the polygon
/// or closer than kBoundaryClearance * edge_length_px to the boundary are
/// dropped. The boundary is conforming. Corners (vertices where the outline
/// turns by more than 40 degrees, at least half an edge apart) are nodes.
/// Between corners, a chain of sides that are all at least half an edge long
/// keeps its vertices and each side is split evenly into
/// round(length / edge_length_px) (at least 1) pieces, so the mesh's boundary
/// is exactly the polygon and the mesh area equals the polygon area; a chain
/// with shorter sides (an outline traced from pixels) is resampled at even arc
/// length, so its boundary nodes lie on the polygon and the sides between them
/// are chords of it. Where a side of a held region crosses the outline, a
/// boundary node is placed exactly at the crossing (the nearest boundary
/// node moves there when it is within kHeldLineSnap edges of it). Nodes come
/// in that order: boundary nodes along the polygon, then the held regions'
/// nodes inside the polygon (side by side), then lattice nodes row by row
/// (y, then x increasing); lattice nodes keep the same clearance from the
/// held regions' sides as from the boundary. The triangles are a constrained
/// Delaunay triangulation of those nodes, constrained by the boundary and
/// the held regions' sides. A side that would cross one already placed (two
/// held regions overlapping inside the object) is left out. The result is a
/// pure function of the input.
///
/// Throws std::invalid_argument when the options are invalid, the polygon has
/// fewer than 3 vertices, a non-finite coordinate, is not simple (crossing
/// sides, repeated vertices), or its area is below that of one equilateral
/// triangle of side edge_length_px.
Mesh MeshPolygon(const std::vector<Vec2>& polygon, const MesherOptions& options);

/// Lattice points closer than this many edge lengths to the polygon are
/// dropped. The strip between the boundary and the first kept lattice row is
/// then [c, c + sqrt(3)/2) edge lengths wide, and its flattest triangles have
/// angles near atan(c) (narrow strip) and atan(1 / (c + sqrt(3)/2)) (wide
/// strip): 35 and 33 degrees for c = 0.7. Boundary nodes out of step with the
/// lattice and polygon corners lower that; over sweeps of rectangles, L shapes
/// and circles (vertices about one edge length apart) the smallest angle seen
/// is 27.9 degrees and the worst radius ratio 1.8. Nothing refines further, so
/// there is no proven bound.
inline constexpr double kBoundaryClearance = 0.7;

/// A boundary node this many edge lengths or closer to where a held region's
/// side crosses the outline moves onto the crossing rather than leaving a
/// sliver beside a new node.
inline constexpr double kHeldLineSnap = 0.35;

}  // namespace calib
