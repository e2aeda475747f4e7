#pragma once
// Per-frame comparison of the segmented object with the rasterised mesh.
//
// The score of a frame is the area of the pixels where the object and the
// mesh disagree: the sum over pixels of |object(p) - coverage(p)|, object(p)
// in {0, 1} the segmented mask and coverage(p) in [0, 1] the area of the
// pixel square that the mesh covers (pixel_coverage.h). Inside and outside
// the mesh this is the XOR of two bit masks; only the pixels the mesh's
// outline crosses contribute fractions, which makes the score continuous in
// the node positions.

#include "calib/evaluator/bit_mask.h"
#include "calib/evaluator/pixel_coverage.h"

#include <cstdint>
#include <span>

namespace calib {

/// Areas of one frame's comparison, in px^2 (pixel areas: a pixel counts 1
/// in full, its covered fraction in part), over the masks' common extent.
/// For two bit masks they are pixel counts.
struct FrameScore {
  double xor_px = 0.0;     ///< area in exactly one: missed_px + extra_px (the score)
  double missed_px = 0.0;  ///< object, not mesh: sum of object(p) (1 - coverage(p))
  double extra_px = 0.0;   ///< mesh, not object: sum of (1 - object(p)) coverage(p)
  double object_px = 0.0;  ///< sum of object(p)
  double mesh_px = 0.0;    ///< sum of coverage(p)
  /// |object & mesh| / |object | mesh| (areas; the intersection is the sum of
  /// object(p) coverage(p)); 1 when both are empty.
  double iou = 0.0;

  bool operator==(const FrameScore&) const = default;
};

/// The score of a mesh given by its coverage: `interior` its wholly covered
/// pixels, `boundary` its partly covered ones (disjoint from `interior`,
/// inside the mask; Rasterizer::RasterizeMeshCoverage). Bit masks of
/// different shapes (size and origin) abort, a programmer error. Popcount
/// over 64-pixel words for the interior, then one look-up per boundary
/// pixel; the sums run in `boundary`'s order. No allocation.
FrameScore CompareCoverage(const BitMask& object, const BitMask& interior,
                           std::span<const PixelCoverage> boundary);

/// CompareCoverage, the same result, for an `interior` with no pixel outside
/// rows [row_begin, row_end) (mask rows, 0 <= row_begin <= row_end <=
/// height; Rasterizer::covered_rows()) and `object_px` the pixel count of
/// `object`: only those rows are counted, the object's pixels elsewhere are
/// missed. For a mesh a fraction of the mask's height.
FrameScore CompareCoverageInRows(const BitMask& object, int64_t object_px,
                                 const BitMask& interior, int row_begin, int row_end,
                                 std::span<const PixelCoverage> boundary);

/// Two bit masks (the mesh as a bit mask: CompareCoverage with no partly
/// covered pixel).
FrameScore CompareMasks(const BitMask& object, const BitMask& mesh);

}  // namespace calib
