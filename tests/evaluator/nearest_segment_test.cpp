// The nearest point of a set of segments (nearest_segment.h): the grid's
// answer is the plain scan's, bit for bit, for an outline and scattered
// segments, query points near, far, outside the grid and on ties; no
// segment, degenerate ones and non-finite ends.

#include "calib/evaluator/nearest_segment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <utility>
#include <vector>

namespace calib {
namespace {

void ExpectSame(const SegmentPoint& got, const SegmentPoint& want, const Vec2& p) {
  ASSERT_EQ(got.segment, want.segment) << "query (" << p.x() << ", " << p.y() << ")";
  // Bit for bit: the same expression on the same segment.
  EXPECT_EQ(got.distance2, want.distance2);
  EXPECT_EQ(got.share, want.share);
  EXPECT_EQ(got.point.x(), want.point.x());
  EXPECT_EQ(got.point.y(), want.point.y());
}

NearestSegment FromPolygon(const std::vector<Vec2>& corners) {
  NearestSegment index;
  index.Build(static_cast<int>(corners.size()), [&](int k) {
    return std::pair(corners[k], corners[(k + 1) % corners.size()]);
  });
  return index;
}

TEST(NearestSegment, AnOutlineGivesThePlainScansAnswerEverywhere) {
  // A wavy closed outline of 400 short segments, as a traced mask's.
  std::vector<Vec2> outline;
  for (int k = 0; k < 400; ++k) {
    const double t = 2.0 * std::numbers::pi * k / 400.0;
    const double r = 120.0 + 15.0 * std::sin(7.0 * t);
    outline.emplace_back(300.0 + r * std::cos(t), 200.0 + 0.6 * r * std::sin(t));
  }
  const NearestSegment index = FromPolygon(outline);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> near(-3.0, 3.0), anywhere(-200.0, 800.0);
  for (int q = 0; q < 4000; ++q) {
    // Near the outline (where the registration asks), and anywhere, far
    // outside the grid included.
    const Vec2 p = q % 2 == 0 ? outline[q % outline.size()] + Vec2(near(rng), near(rng))
                              : Vec2(anywhere(rng), anywhere(rng));
    ExpectSame(index.Nearest(p), index.NearestByScan(p), p);
  }
}

TEST(NearestSegment, TiesGoToTheLowestIndexAsInThePlainScan) {
  // A 10 px square, each side cut into eight segments (32: enough for a
  // grid), queried at its centre (the four sides' midpoints as near, each
  // the end of one segment and the start of the next), at its corners and
  // at the cuts along its sides.
  std::vector<Vec2> square;
  const std::vector<Vec2> corners{Vec2(0, 0), Vec2(10, 0), Vec2(10, 10), Vec2(0, 10)};
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < 8; ++k) {
      square.push_back(corners[side] + (corners[(side + 1) % 4] - corners[side]) * (k / 8.0));
    }
  }
  const NearestSegment index = FromPolygon(square);
  for (const Vec2& p : square) ExpectSame(index.Nearest(p), index.NearestByScan(p), p);
  for (const Vec2& p : {Vec2(5, 5), Vec2(5, 4), Vec2(6, 5), Vec2(-1, -1), Vec2(11, 5)}) {
    ExpectSame(index.Nearest(p), index.NearestByScan(p), p);
  }
  const SegmentPoint centre = index.Nearest(Vec2(5, 5));
  EXPECT_EQ(centre.segment, 3) << "the first side's middle, the end of its fourth segment";
  EXPECT_EQ(centre.share, 1.0);
  EXPECT_EQ(index.Nearest(Vec2(10, 10)).segment, 15) << "a corner: the end of the side before";
  // The same segment listed twenty times: the first.
  NearestSegment repeated;
  repeated.Build(20, [](int) { return std::pair(Vec2(0, 0), Vec2(4, 0)); });
  EXPECT_EQ(repeated.Nearest(Vec2(2, 1)).segment, 0);
}

TEST(NearestSegment, ScatteredLongAndPointSegmentsGiveThePlainScansAnswer) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> coordinate(0.0, 500.0), length(0.0, 60.0), angle(0.0, 6.3);
  std::vector<std::pair<Vec2, Vec2>> segments;
  for (int k = 0; k < 300; ++k) {
    const Vec2 a(coordinate(rng), coordinate(rng));
    const double l = k % 10 == 0 ? 0.0 : (k % 10 == 1 ? 400.0 : length(rng));  // points, long ones
    const double t = angle(rng);
    segments.emplace_back(a, a + l * Vec2(std::cos(t), std::sin(t)));
  }
  NearestSegment index;
  index.Build(static_cast<int>(segments.size()), [&](int k) { return segments[k]; });
  for (int q = 0; q < 3000; ++q) {
    const Vec2 p(coordinate(rng) * 1.4 - 100.0, coordinate(rng) * 1.4 - 100.0);
    ExpectSame(index.Nearest(p), index.NearestByScan(p), p);
  }
  // Rebuilt smaller (the buffers reused): the new set only.
  index.Build(3, [&](int k) { return segments[k]; });
  for (int q = 0; q < 200; ++q) {
    const Vec2 p(coordinate(rng), coordinate(rng));
    const SegmentPoint got = index.Nearest(p);
    ExpectSame(got, index.NearestByScan(p), p);
    EXPECT_LT(got.segment, 3);
  }
}

TEST(NearestSegment, NoSegmentsNonFiniteEndsAndQueriesAreTheScansAnswer) {
  NearestSegment empty;
  empty.Build(0, [](int) { return std::pair(Vec2::Zero().eval(), Vec2::Zero().eval()); });
  EXPECT_EQ(empty.Nearest(Vec2(1, 2)).segment, -1);
  EXPECT_TRUE(std::isinf(empty.Nearest(Vec2(1, 2)).distance2));

  const double nan = std::numeric_limits<double>::quiet_NaN();
  NearestSegment with_nan;  // enough segments for a grid, one of them not finite
  with_nan.Build(40, [&](int k) {
    return k == 1 ? std::pair(Vec2(nan, 0), Vec2(1, 1)) : std::pair(Vec2(k, 0), Vec2(k, 5));
  });
  for (const Vec2& p : {Vec2(0.2, 2), Vec2(1.9, 4), Vec2(-50, 3)}) {
    ExpectSame(with_nan.Nearest(p), with_nan.NearestByScan(p), p);
  }
  NearestSegment far_flung;  // coordinates beyond any image
  far_flung.Build(40, [](int k) { return std::pair(Vec2(k * 1e200, 0), Vec2(k * 1e200, 1)); });
  for (const Vec2& p : {Vec2(3e200, 0.5), Vec2(-1, 0)}) {
    ExpectSame(far_flung.Nearest(p), far_flung.NearestByScan(p), p);
  }
  // A query that is not finite, against a set large enough for a grid (a
  // 40-gon) and against one that is scanned (a triangle).
  std::vector<Vec2> polygon;
  for (int k = 0; k < 40; ++k) {
    const double t = 2.0 * std::numbers::pi * k / 40.0;
    polygon.emplace_back(50.0 * std::cos(t), 50.0 * std::sin(t));
  }
  const NearestSegment gridded = FromPolygon(polygon);
  const NearestSegment triangle = FromPolygon({Vec2(0, 0), Vec2(10, 0), Vec2(10, 10)});
  for (const Vec2& query : {Vec2(nan, 1.0), Vec2(1.0, std::numeric_limits<double>::infinity())}) {
    for (const NearestSegment* index : {&gridded, &triangle}) {
      EXPECT_EQ(index->Nearest(query).segment, index->NearestByScan(query).segment);
    }
  }
}

}  // namespace
}  // namespace calib
