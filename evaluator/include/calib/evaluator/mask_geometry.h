#pragma once
// Mask geometry: area, centroid and principal axis of a mask; the XOR of two
// masks with one shifted; axis angles. Used by the scoring side (the
// observed motion of a recording) and by the residual analysis.

#include "calib/core/types.h"
#include "calib/evaluator/bit_mask.h"

#include <cmath>
#include <cstdint>

namespace calib {

/// Area, centroid and principal-axis orientation of a mask's pixels.
struct MaskMoments {
  int64_t area_px = 0;
  Vec2 centroid_px{NAN, NAN};  ///< frame pixels (pixel centres)
  /// Orientation of the major axis, in (-pi/2, pi/2]; NaN when empty.
  double angle_rad = NAN;
  /// 1 - minor / major eigenvalue of the covariance (0: isotropic, the angle
  /// meaningless; -> 1: elongated).
  double anisotropy = 0.0;
};
MaskMoments ComputeMoments(const BitMask& mask);

/// The centre of the mask's pixel farthest from `point` (frame pixels; the
/// first in row order on ties): a hanging object's tip, for `point` its
/// clamp. (NaN, NaN) for an empty mask.
Vec2 FarthestPixelFrom(const BitMask& mask, const Vec2& point);

/// |a XOR (b shifted by (dx, dy))|: the XOR after moving b's content dx
/// pixels right and dy down, over a's extent (b's pixels shifted outside it
/// are not counted). a and b must have the same shape.
int64_t CountXorShifted(const BitMask& a, const BitMask& b, int dx, int dy);

/// a - b wrapped into (-pi/2, pi/2] (axis angles are defined modulo pi).
double AxisAngleDifference(double a_rad, double b_rad);

}  // namespace calib
