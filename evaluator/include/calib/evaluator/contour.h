#pragma once
// The object's outline polygon from a segmented mask.

#include "calib/core/types.h"
#include "calib/evaluator/bit_mask.h"

#include <vector>

namespace calib {

/// The outer contour of the largest 8-connected region of `mask` (holes
/// ignored), simplified with Douglas-Peucker (cv::approxPolyDP) at
/// `tolerance_px` (>= 0, pixels) and returned in FRAME pixel coordinates.
///
/// The contour first runs through the centres of the region's border pixels
/// (mask pixel (x, y) has centre (origin_x + x + 0.5, origin_y + y + 0.5)),
/// which under-covers the pixels' squares. Every side is then moved outward by
/// half a pixel along the axis nearest its normal, i.e. by 0.5 * max(|n.x|,
/// |n.y|) px for unit normal n (0.5 px for axis-aligned sides, 0.35 px for
/// 45-degree staircases, which is how far a border-centre chain lies inside
/// the pixel squares), with mitred corners, bevelled where the outline turns
/// by more than 90 degrees. The polygon's area then matches the region's
/// pixel count: exactly for a rectangle of pixels, to within a few percent of
/// a pixel per unit perimeter for curved shapes.
///
/// Returns #P >= 3 vertices, the first not repeated at the end, with positive
/// shoelace area 1/2 sum cross(p_i, p_{i+1}) > 0 -- the orientation of the
/// mesh's positive triangles and boundary loops (clockwise on screen, y down).
/// A region without area at pixel-centre level (one pixel, a one-pixel-wide
/// line) gives its bounding box of pixel squares.
///
/// Throws std::invalid_argument when the mask has no pixel set or
/// tolerance_px is negative or not finite.
std::vector<Vec2> ObjectOutline(const BitMask& mask, double tolerance_px);

}  // namespace calib
