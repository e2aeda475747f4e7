#pragma once
// Position constraints applied after each substep: obstacles are impenetrable
// discs, triangles may not invert, clamped nodes stay put. Each function moves
// only nodes with a nonzero inverse weight (clamped nodes have weight 0).

#include "calib/core/mesh.h"

#include <cstdint>
#include <span>

namespace calib {

/// Moves every movable node that lies inside a disc radially onto its
/// boundary. A node exactly at a centre is moved along +x. Returns the number
/// of nodes moved.
int ProjectOutOfDiscs(std::span<const Disc> discs, std::span<const double> inverse_weight,
                      std::span<Vec2> x);

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
