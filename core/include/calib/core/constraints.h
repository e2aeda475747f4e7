#pragma once
// Position constraints applied after each substep: obstacles are impenetrable
// discs, triangles may not invert, clamped nodes stay put. Each function moves
// only nodes with a nonzero inverse weight (clamped nodes have weight 0).

#include "calib/core/mesh.h"

#include <algorithm>
#include <cstdint>
#include <span>

namespace calib {

/// Where a substep started: the nodes' positions and the discs before the
/// step (the same discs in the same order). A step longer than a disc's
/// radius can carry a node past the disc's centre, or an edge over it; the
/// projections then need to know which side it came from. Empty spans: not
/// known (only the current positions count).
struct SubstepStart {
  std::span<const Vec2> x;
  std::span<const Disc> discs;
  /// Coulomb friction between the discs and the object, position-based:
  /// where a node or an edge point is pushed out of a disc by d, its motion
  /// along the disc's surface relative to the disc over the substep is
  /// undone up to `friction` x d (all of it: it sticks). 0: frictionless,
  /// the paper's contact. Needs the start.
  double friction = 0.0;
};

/// Moves every movable node that lies inside a disc radially onto its
/// boundary. A node exactly at a centre is moved along +x. With the
/// substep's start known, a node that went past the centre (or onto it)
/// from where it was against the disc at the start is moved back out on
/// that side instead, along the direction it came from, onto the circle's
/// tangent there: a long step does not push it out of the far side.
/// Returns the number of nodes moved.
int ProjectOutOfDiscs(std::span<const Disc> discs, std::span<const double> inverse_weight,
                      std::span<Vec2> x, const SubstepStart& start = {});

/// Where boundary edge a -> b (interior to its left) is nearest a point
/// `centre`: at (1 - t) a + t b; `inward` is the edge's unit normal into
/// the interior and `s` = inward . (a - centre), positive when the centre
/// lies in front of the edge (outside). False, and *edge_point unset, for a
/// degenerate edge or when the nearest point is an end node (t outside
/// (0, 1)): that node is nearest.
struct EdgePoint {
  double t = 0.0;
  Vec2 inward = Vec2::Zero();
  double s = 0.0;
};
bool NearestInteriorEdgePoint(const Vec2& a, const Vec2& b, const Vec2& centre, EdgePoint* edge_point);

/// Whether the bounding box of segment a-b comes within `distance` of `p`
/// along both axes: false means every point of the segment is farther than
/// `distance` from p (a test without division or square root, to skip the
/// edges far from an obstacle before NearestInteriorEdgePoint).
inline bool BoxWithin(const Vec2& a, const Vec2& b, const Vec2& p, double distance) {
  return !(p.x() + distance < std::min(a.x(), b.x()) || p.x() - distance > std::max(a.x(), b.x()) ||
           p.y() + distance < std::min(a.y(), b.y()) || p.y() - distance > std::max(a.y(), b.y()));
}

/// Edges inside a disc by less than this are left alone by
/// ProjectBoundaryOutOfDiscs: invisible to the rasteriser.
inline constexpr double kEdgeContactTolerancePx = 0.01;

/// Keeps the discs out of the mesh's boundary edges, not only its nodes: a
/// disc narrower than the mesh's edges would otherwise slip between two
/// boundary nodes and poke through the outline. For every boundary edge
/// whose interior point nearest a disc's centre lies inside the disc (the
/// centre in front of the edge, outside the object), moves the edge's two
/// nodes along its inward normal so that point lands on the circle, shared by
/// their inverse weights and barycentric weights (the position-based
/// edge-point contact). Only edges inside by more than
/// kEdgeContactTolerancePx are moved. An edge moved more at one end tilts,
/// so its nearest point may still lie a little inside: repeated rounds, as
/// the simulator runs them, converge. A centre that got inside the outline
/// (a disc that went through an edge, or an edge that swept over it) is put
/// back out: then the edges it overlaps from behind are moved past it too,
/// by up to the radius; with the substep's start known, an edge that had
/// the centre in front of it at the start is moved back past the centre
/// from any depth (an edge that swept over the whole disc in one step).
/// An edge whose nearest point is an end node is left to ProjectOutOfDiscs.
/// Returns the number of edges moved.
int ProjectBoundaryOutOfDiscs(const Mesh& mesh, std::span<const Disc> discs,
                              std::span<const double> inverse_weight, std::span<Vec2> x,
                              const SubstepStart& start = {});

/// For every triangle whose signed area is below min_area_fraction * A0
/// (inverted or nearly so), pushes the node and the opposite edge apart: a
/// step towards A = 2 min_area_fraction A0 along the area gradient, shared
/// between the three nodes by their inverse weights (the paper's repair,
/// written so that clamped nodes do not move). Returns the number of
/// triangles repaired.
int RepairInvertedTriangles(const Mesh& mesh, double min_area_fraction,
                            std::span<const double> inverse_weight, std::span<Vec2> x);

/// Index of a triangle with signed area <= 0, or -1.
int FindInvertedTriangle(const Mesh& mesh, std::span<const Vec2> x);

/// Index of a node inside a disc by more than tolerance_px, or -1.
int FindNodeInsideDisc(std::span<const Disc> discs, std::span<const Vec2> x, double tolerance_px);

}  // namespace calib
