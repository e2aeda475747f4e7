// Mask geometry (mask_geometry.h): moments, shifted XOR, axis angles.

#include "calib/evaluator/mask_geometry.h"

#include "popcount_clones.h"

#include <bit>
#include <cmath>
#include <numbers>

namespace calib {
namespace {

// Bits [bit, bit + 64) of a packed row of `words` words (bit may be negative
// or run past the end: those bits are 0).
uint64_t BitsAt(const uint64_t* row, int words, int bit) {
  const int w = bit >> 6;  // floor division
  const int s = bit & 63;
  const uint64_t lo = (w >= 0 && w < words) ? row[w] : 0;
  if (s == 0) return lo;
  const uint64_t hi = (w + 1 >= 0 && w + 1 < words) ? row[w + 1] : 0;
  return (lo >> s) | (hi << (64 - s));
}

}  // namespace

Vec2 FarthestPixelFrom(const BitMask& mask, const Vec2& point) {
  Vec2 best(NAN, NAN);
  double farthest = -1.0;
  for (int y = 0; y < mask.height(); ++y) {
    const uint64_t* row = mask.Row(y);
    const double py = mask.origin_y() + y + 0.5;
    for (int w = 0; w < mask.words_per_row(); ++w) {
      uint64_t bits = row[w];
      while (bits != 0) {
        const int b = std::countr_zero(bits);
        bits &= bits - 1;
        const Vec2 p(mask.origin_x() + w * 64 + b + 0.5, py);
        const double d = (p - point).squaredNorm();
        if (d > farthest) {
          farthest = d;
          best = p;
        }
      }
    }
  }
  return best;
}

MaskMoments ComputeMoments(const BitMask& mask) {
  MaskMoments m;
  // Sums relative to the mask's centre keep the second moments accurate.
  const double cx = 0.5 * mask.width(), cy = 0.5 * mask.height();
  double n = 0, sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
  for (int y = 0; y < mask.height(); ++y) {
    const uint64_t* row = mask.Row(y);
    const double py = y + 0.5 - cy;
    double rn = 0, rsx = 0, rsxx = 0;
    for (int w = 0; w < mask.words_per_row(); ++w) {
      uint64_t bits = row[w];
      while (bits != 0) {
        const int b = std::countr_zero(bits);
        bits &= bits - 1;
        const double px = (w * 64 + b) + 0.5 - cx;
        rn += 1;
        rsx += px;
        rsxx += px * px;
      }
    }
    n += rn;
    sx += rsx;
    sxx += rsxx;
    sy += rn * py;
    syy += rn * py * py;
    sxy += rsx * py;
  }
  m.area_px = static_cast<int64_t>(n);
  if (n == 0) return m;
  const double mx = sx / n, my = sy / n;
  m.centroid_px = Vec2(mask.origin_x() + cx + mx, mask.origin_y() + cy + my);
  const double mu20 = sxx / n - mx * mx, mu02 = syy / n - my * my, mu11 = sxy / n - mx * my;
  double angle = 0.5 * std::atan2(2.0 * mu11, mu20 - mu02);
  if (angle <= -0.5 * std::numbers::pi) angle += std::numbers::pi;
  m.angle_rad = angle;
  const double tr = mu20 + mu02;
  const double disc = std::sqrt(std::max(0.0, 0.25 * (mu20 - mu02) * (mu20 - mu02) + mu11 * mu11));
  const double major = 0.5 * tr + disc, minor = 0.5 * tr - disc;
  m.anisotropy = major > 0.0 ? 1.0 - std::max(0.0, minor) / major : 0.0;
  return m;
}

CALIB_POPCOUNT_CLONES
int64_t CountXorShifted(const BitMask& a, const BitMask& b, int dx, int dy) {
  int64_t count = 0;
  const int words = a.words_per_row();
  // Bits beyond a's width in a row's last word must not count.
  const int tail = a.width() & 63;
  const uint64_t last_mask = tail == 0 ? ~uint64_t{0} : (uint64_t{1} << tail) - 1;
  for (int y = 0; y < a.height(); ++y) {
    const uint64_t* ra = a.Row(y);
    const int yb = y - dy;
    if (yb < 0 || yb >= b.height()) {
      for (int w = 0; w < words; ++w) count += std::popcount(ra[w]);
      continue;
    }
    const uint64_t* rb = b.Row(yb);
    for (int w = 0; w < words; ++w) {
      uint64_t shifted = BitsAt(rb, b.words_per_row(), w * 64 - dx);
      if (w == words - 1) shifted &= last_mask;
      count += std::popcount(ra[w] ^ shifted);
    }
  }
  return count;
}

double AxisAngleDifference(double a_rad, double b_rad) {
  double d = std::remainder(a_rad - b_rad, std::numbers::pi);  // [-pi/2, pi/2]
  if (d <= -0.5 * std::numbers::pi) d += std::numbers::pi;
  return d;
}

}  // namespace calib
