#pragma once
// Polygons for the rasteriser tests (frame pixels), and the numbers to check
// them against.

#include "calib/core/mesh.h"

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

namespace calib::testing {

using Loop = std::vector<Vec2>;

/// Uniform in [lo, hi) from the raw engine output (std:: distributions differ
/// between standard libraries).
inline double Uniform(std::mt19937_64& rng, double lo, double hi) {
  return lo + (hi - lo) * static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

/// Signed area by the shoelace formula: positive for a loop that turns from
/// +x towards +y (clockwise on screen).
inline double SignedShoelaceArea(const Loop& loop) {
  double twice = 0.0;
  for (size_t i = 0; i < loop.size(); ++i) twice += Cross(loop[i], loop[(i + 1) % loop.size()]);
  return 0.5 * twice;
}

inline double ShoelaceArea(const Loop& loop) { return std::abs(SignedShoelaceArea(loop)); }

inline double Perimeter(const Loop& loop) {
  double sum = 0.0;
  for (size_t i = 0; i < loop.size(); ++i) sum += (loop[(i + 1) % loop.size()] - loop[i]).norm();
  return sum;
}

inline Loop Rectangle(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

inline Loop RegularPolygon(const Vec2& centre, double radius, int sides, double phase_rad) {
  Loop loop;
  for (int k = 0; k < sides; ++k) {
    const double a = phase_rad + 2.0 * std::numbers::pi * k / sides;
    loop.push_back(centre + radius * Vec2(std::cos(a), std::sin(a)));
  }
  return loop;
}

}  // namespace calib::testing
