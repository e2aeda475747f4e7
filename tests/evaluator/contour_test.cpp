#include "calib/evaluator/contour.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <limits>
#include <stdexcept>
#include <string>

namespace calib {
namespace {

double SignedPolygonArea(const std::vector<Vec2>& polygon) {
  double twice = 0.0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    twice += Cross(polygon[i], polygon[(i + 1) % polygon.size()]);
  }
  return 0.5 * twice;
}

// Pixels whose centre (frame coordinates) lies inside the disc.
BitMask DiscMask(int width, int height, int origin_x, int origin_y, const Vec2& centre,
                 double radius) {
  BitMask mask(width, height, origin_x, origin_y);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const Vec2 c(origin_x + x + 0.5, origin_y + y + 0.5);
      if ((c - centre).norm() < radius) mask.Set(x, y);
    }
  }
  return mask;
}

TEST(ObjectOutline, RectangleOfPixelsGivesItsExactSquares) {
  BitMask mask(50, 40);
  for (int y = 10; y < 30; ++y) mask.SetSpan(y, 5, 45);  // pixels [5, 45) x [10, 30)
  const auto outline = ObjectOutline(mask, 0.5);
  ASSERT_EQ(outline.size(), 4u);
  EXPECT_NEAR(SignedPolygonArea(outline), static_cast<double>(mask.Count()), 1e-9);
  for (const Vec2& p : outline) {
    EXPECT_TRUE((p.x() == 5.0 || p.x() == 45.0) && (p.y() == 10.0 || p.y() == 30.0))
        << "(" << p.x() << ", " << p.y() << ") is not a corner of the pixel block";
  }
}

TEST(ObjectOutline, DiscAreaMatchesPixelCountAndHugsTheCircle) {
  const Vec2 centre(60.3, 48.7);
  for (double radius : {12.0, 40.0}) {
    for (double tolerance : {0.0, 0.5, 1.0}) {
      const BitMask mask = DiscMask(128, 100, 0, 0, centre, radius);
      const auto outline = ObjectOutline(mask, tolerance);
      const double count = static_cast<double>(mask.Count());
      const double area = SignedPolygonArea(outline);
      EXPECT_GT(area, 0.0) << "orientation: positive shoelace area";
      // Staircase: under 1% of a pixel per unit of perimeter (0.5 px^2 seen for
      // both radii at tolerance 0). Douglas-Peucker
      // chords cut inside a convex outline by up to `tolerance`, about 2/3 of it
      // on average over an arc.
      const double perimeter = 2.0 * std::numbers::pi * radius;
      EXPECT_NEAR(area, count, (0.01 + 0.7 * tolerance) * perimeter)
          << "radius " << radius << " tolerance " << tolerance;
      // Vertices and side midpoints lie within 1 px (plus the tolerance) of the circle.
      for (size_t i = 0; i < outline.size(); ++i) {
        const Vec2 midpoint = 0.5 * (outline[i] + outline[(i + 1) % outline.size()]);
        for (const Vec2& p : {outline[i], midpoint}) {
          EXPECT_NEAR((p - centre).norm(), radius, 1.0 + tolerance)
              << "radius " << radius << " tolerance " << tolerance << " vertex " << i;
        }
      }
    }
  }
}

TEST(ObjectOutline, RespectsMaskOrigin) {
  // The same disc in frame coordinates, seen through masks at different origins.
  const Vec2 centre(530.2, 310.9);
  const BitMask near = DiscMask(100, 80, 480, 270, centre, 25.0);
  const BitMask far = DiscMask(90, 90, 470, 260, centre, 25.0);
  ASSERT_EQ(near.Count(), far.Count());
  const auto a = ObjectOutline(near, 0.7);
  const auto b = ObjectOutline(far, 0.7);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_LT((a[i] - b[i]).norm(), 1e-9) << "vertex " << i;
    EXPECT_NEAR((a[i] - centre).norm(), 25.0, 1.7) << "vertex " << i;
  }
}

TEST(ObjectOutline, KeepsTheLargestRegionOnly) {
  BitMask mask(100, 60, 7, 3);
  for (int y = 5; y < 15; ++y) mask.SetSpan(y, 5, 15);   // 100 px
  for (int y = 20; y < 50; ++y) mask.SetSpan(y, 40, 90);  // 1500 px
  const auto outline = ObjectOutline(mask, 0.5);
  EXPECT_NEAR(SignedPolygonArea(outline), 1500.0, 1e-9);
  for (const Vec2& p : outline) {
    EXPECT_GE(p.x(), 7 + 40 - 1e-9);
    EXPECT_GE(p.y(), 3 + 20 - 1e-9);
  }
}

TEST(ObjectOutline, SinglePixelGivesItsSquare) {
  BitMask mask(10, 10, 100, 200);
  mask.Set(3, 4);
  const auto outline = ObjectOutline(mask, 0.5);
  ASSERT_EQ(outline.size(), 4u);
  EXPECT_NEAR(SignedPolygonArea(outline), 1.0, 1e-12);
  EXPECT_EQ(outline[0], Vec2(103, 204));
}

TEST(ObjectOutline, BadInputThrows) {
  try {
    ObjectOutline(BitMask(20, 20), 1.0);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no pixel set"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ObjectOutline(BitMask(), 1.0), std::invalid_argument);
  BitMask mask(20, 20);
  mask.Set(5, 5);
  try {
    ObjectOutline(mask, -1.0);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tolerance_px"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ObjectOutline(mask, std::numeric_limits<double>::quiet_NaN()),
               std::invalid_argument);
}

}  // namespace
}  // namespace calib
