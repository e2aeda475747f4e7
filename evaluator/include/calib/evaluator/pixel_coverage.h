#pragma once
// Sub-pixel coverage of a shape, as the score sees the simulated mesh: the
// exact area of each pixel square covered by the shape, in [0, 1]. Pixels
// wholly inside (coverage 1) are bits of a BitMask, as a binary mask's are;
// the few pixels the outline crosses (0 < coverage < 1) are a sparse list of
// PixelCoverage beside it (Rasterizer::RasterizeMeshCoverage makes both,
// CompareCoverage in scoring.h scores them).
//
// Pixel (x, y) of a mask is the square [x, x + 1] x [y, y + 1] in mask
// coordinates, frame square [origin_x + x, origin_x + x + 1] x
// [origin_y + y, origin_y + y + 1].

#include "calib/evaluator/bit_mask.h"

#include <span>

namespace calib {

/// A pixel the shape covers in part.
struct PixelCoverage {
  int x = 0;              ///< mask column
  int y = 0;              ///< mask row
  double coverage = 0.0;  ///< covered area of the pixel square, px^2, in (0, 1)

  bool operator==(const PixelCoverage&) const = default;
};

/// A coverage within this of 0 counts as empty, within this of 1 as full:
/// rounding in the area sums leaves that much on pixels the outline only
/// touches.
inline constexpr double kCoverageTolerance = 1e-9;

/// Sets in `mask` the pixels of `boundary` covered at least half: with the
/// wholly covered pixels already in `mask`, the binary mask nearest to the
/// coverage (for overlays and residual analysis, which take bit masks).
inline void AddHalfCovered(std::span<const PixelCoverage> boundary, BitMask& mask) {
  for (const PixelCoverage& p : boundary) {
    if (p.coverage >= 0.5) mask.Set(p.x, p.y);
  }
}

}  // namespace calib
