#pragma once
// Per-frame comparison of the segmented object with the rasterised mesh.

#include "calib/evaluator/bit_mask.h"

#include <cstdint>

namespace calib {

/// Pixel counts of one frame's comparison (over the masks' common extent).
struct FrameScore {
  int64_t xor_px = 0;     ///< pixels in exactly one mask: missed_px + extra_px (the score)
  int64_t missed_px = 0;  ///< object, not mesh
  int64_t extra_px = 0;   ///< mesh, not object
  int64_t object_px = 0;
  int64_t mesh_px = 0;
  double iou = 0.0;  ///< |object & mesh| / |object | mesh|; 1 when both are empty
};

/// Compares two masks of the same shape (size and origin; aborts otherwise,
/// a programmer error) by popcount over 64-pixel words. No allocation.
FrameScore CompareMasks(const BitMask& object, const BitMask& mesh);

}  // namespace calib
