#pragma once
// Small shared types of the model. Coordinates are image pixels: x to the
// right, y down, origin at the top-left pixel's corner.

#include <Eigen/Core>

#include <array>
#include <vector>

namespace calib {

using Vec2 = Eigen::Vector2d;

/// A rigid disc obstacle at one instant (pixels).
struct Disc {
  Vec2 centre = Vec2::Zero();
  double radius_px = 0.0;
};

/// An axis-aligned rectangle in pixels: [x, x + width) x [y, y + height).
struct RectPx {
  double x = 0.0;
  double y = 0.0;
  double width = 0.0;
  double height = 0.0;
  bool Contains(const Vec2& p) const {
    return p.x() >= x && p.x() <= x + width && p.y() >= y && p.y() <= y + height;
  }
};

/// Cross product of two plane vectors (z component).
inline double Cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

}  // namespace calib
