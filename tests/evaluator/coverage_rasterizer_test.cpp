// The score's rasteriser, area coverage (rasterizer.h): every pixel's
// coverage against an independent reference (each loop clipped to the pixel
// square by Sutherland-Hodgman, its shoelace area), the total against the
// polygon's area, exactness on pixel-aligned shapes, clipping to the mask,
// continuity of the score under translation (where the centre rule jumps by
// whole pixels), bit-identical output for the same input, the score over the
// covered rows alone and no allocation in steady state.

#include "calib/core/mesher.h"
#include "calib/evaluator/rasterizer.h"
#include "calib/evaluator/scoring.h"

#include "polygon_support.h"
#include "support/allocation_counter.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace calib {
namespace {

using namespace testing;  // calib::testing: polygons, meshes, allocations

// A pixel's coverage may differ from the reference by the rasteriser's
// snapping tolerance and rounding.
constexpr double kPixelTolerance = kCoverageTolerance + 1e-11;

// A rasteriser and its output for masks of one shape.
struct Coverage {
  Coverage(int width, int height, int origin_x, int origin_y)
      : interior(width, height, origin_x, origin_y) {}
  void Fill(const std::vector<Loop>& loops) {
    rasterizer.FillPolygonsCoverage(loops, interior, boundary);
  }
  // The XOR area against `object` (same shape).
  double Score(const BitMask& object) const {
    return CompareCoverage(object, interior, boundary).xor_px;
  }

  Rasterizer rasterizer;
  BitMask interior;
  std::vector<PixelCoverage> boundary;
};

// The part of `loop` with p[axis] <= bound (below) or >= bound (!below), by
// Sutherland-Hodgman; the result may have zero-width spikes along the
// bound, which add no area.
Loop ClipToHalfPlane(const Loop& loop, int axis, double bound, bool below) {
  Loop out;
  const auto inside = [&](const Vec2& p) { return below ? p[axis] <= bound : p[axis] >= bound; };
  for (size_t i = 0; i < loop.size(); ++i) {
    const Vec2& a = loop[i];
    const Vec2& b = loop[(i + 1) % loop.size()];
    if (inside(a)) out.push_back(a);
    if (inside(a) != inside(b)) {
      Vec2 p = a + (bound - a[axis]) / (b[axis] - a[axis]) * (b - a);
      p[axis] = bound;
      out.push_back(p);
    }
  }
  return out;
}

// The signed area of `loop` inside the square [x, x + 1] x [y, y + 1].
double SignedAreaInSquare(Loop loop, double x, double y) {
  loop = ClipToHalfPlane(loop, 0, x, false);
  loop = ClipToHalfPlane(loop, 0, x + 1.0, true);
  loop = ClipToHalfPlane(loop, 1, y, false);
  loop = ClipToHalfPlane(loop, 1, y + 1.0, true);
  return loop.size() < 3 ? 0.0 : SignedShoelaceArea(loop);
}

// Per mask pixel (row-major), min(1, |sum over the loops of their signed
// areas in the pixel|): the coverage of loops whose winding number is 0 or
// +-1 everywhere (simple polygons, a mesh's outline with its holes).
std::vector<double> ReferenceCoverage(const std::vector<Loop>& loops, const BitMask& shape) {
  std::vector<double> out(static_cast<size_t>(shape.width()) * shape.height(), 0.0);
  double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
  for (const Loop& loop : loops) {
    for (const Vec2& p : loop) {
      x0 = std::min(x0, p.x());
      x1 = std::max(x1, p.x());
      y0 = std::min(y0, p.y());
      y1 = std::max(y1, p.y());
    }
  }
  const auto first = [](double v, int origin, int size) {
    return static_cast<int>(std::clamp(std::floor(v) - origin, 0.0, double(size)));
  };
  const auto end = [](double v, int origin, int size) {
    return static_cast<int>(std::clamp(std::ceil(v) - origin, 0.0, double(size)));
  };
  for (int y = first(y0, shape.origin_y(), shape.height());
       y < end(y1, shape.origin_y(), shape.height()); ++y) {
    for (int x = first(x0, shape.origin_x(), shape.width());
         x < end(x1, shape.origin_x(), shape.width()); ++x) {
      double sum = 0.0;
      for (const Loop& loop : loops) {
        sum += SignedAreaInSquare(loop, shape.origin_x() + x, shape.origin_y() + y);
      }
      out[static_cast<size_t>(y) * shape.width() + x] = std::min(1.0, std::abs(sum));
    }
  }
  return out;
}

// The rasteriser's output as one coverage per mask pixel (row-major), after
// checking the contract of `boundary`: inside the mask, row by row with
// columns ascending, strictly between empty and full, never in `interior`.
std::vector<double> DenseCoverage(const Coverage& c, const std::string& what) {
  const BitMask& interior = c.interior;
  const std::vector<PixelCoverage>& boundary = c.boundary;
  std::vector<double> out(static_cast<size_t>(interior.width()) * interior.height(), 0.0);
  for (int y = 0; y < interior.height(); ++y) {
    for (int x = 0; x < interior.width(); ++x) {
      if (interior.Get(x, y)) out[static_cast<size_t>(y) * interior.width() + x] = 1.0;
    }
  }
  for (size_t i = 0; i < boundary.size(); ++i) {
    const PixelCoverage& p = boundary[i];
    EXPECT_TRUE(p.x >= 0 && p.x < interior.width() && p.y >= 0 && p.y < interior.height())
        << what << ": boundary pixel (" << p.x << ", " << p.y << ") outside the mask";
    if (i > 0) {
      const PixelCoverage& q = boundary[i - 1];
      EXPECT_TRUE(q.y < p.y || (q.y == p.y && q.x < p.x))
          << what << ": boundary pixels out of order at " << i;
    }
    EXPECT_GT(p.coverage, kCoverageTolerance) << what;
    EXPECT_LT(p.coverage, 1.0 - kCoverageTolerance) << what;
    EXPECT_FALSE(interior.Get(p.x, p.y)) << what << ": (" << p.x << ", " << p.y << ") twice";
    out[static_cast<size_t>(p.y) * interior.width() + p.x] = p.coverage;
  }
  return out;
}

// Expects every pixel's coverage to match the reference.
void ExpectMatchesReference(const std::vector<Loop>& loops, const Coverage& c,
                            const std::string& what) {
  const std::vector<double> expected = ReferenceCoverage(loops, c.interior);
  const std::vector<double> actual = DenseCoverage(c, what);
  size_t worst = 0;
  for (size_t i = 0; i < actual.size(); ++i) {
    if (std::abs(actual[i] - expected[i]) > std::abs(actual[worst] - expected[worst])) worst = i;
  }
  EXPECT_LE(std::abs(actual[worst] - expected[worst]), kPixelTolerance)
      << what << ": worst at mask pixel (" << worst % c.interior.width() << ", "
      << worst / c.interior.width() << "): coverage " << actual[worst] << ", reference "
      << expected[worst];
}

double Sum(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s += x;
  return s;
}

// A simple polygon, star-shaped about `centre`: `n` vertices at increasing
// angles, each at a random radius in [r_min, r_max] (convex when equal).
Loop StarPolygon(std::mt19937_64& rng, const Vec2& centre, int n, double r_min, double r_max) {
  Loop loop;
  const double step = 2.0 * std::numbers::pi / n;
  for (int k = 0; k < n; ++k) {
    const double a = step * (k + Uniform(rng, 0.0, 0.9));
    loop.push_back(centre + Uniform(rng, r_min, r_max) * Vec2(std::cos(a), std::sin(a)));
  }
  return loop;
}

std::vector<Loop> BoundaryLoops(const Mesh& mesh, const std::vector<Vec2>& x) {
  std::vector<Loop> loops;
  for (const std::vector<int>& ids : mesh.boundary_loops) {
    Loop loop;
    for (int i : ids) loop.push_back(x[i]);
    loops.push_back(std::move(loop));
  }
  return loops;
}

// A grid patch without one interior cell: an outline and a hole.
Mesh GridMeshWithHole(int nx, int ny, double spacing, const Vec2& origin, int hole_i, int hole_j) {
  const Mesh grid = MakeGridMesh(nx, ny, spacing, origin);
  const Vec2 lo = origin + spacing * Vec2(hole_i, hole_j);
  std::vector<std::array<int, 3>> kept;
  for (const auto& t : grid.triangles) {
    const Vec2 c = (grid.rest_positions[t[0]] + grid.rest_positions[t[1]] +
                    grid.rest_positions[t[2]]) / 3.0;
    const bool in_hole = c.x() > lo.x() && c.x() < lo.x() + spacing && c.y() > lo.y() &&
                         c.y() < lo.y() + spacing;
    if (!in_hole) kept.push_back(t);
  }
  return BuildMesh(grid.rest_positions, std::move(kept));
}

TEST(CoverageRasterizer, MatchesClippedAreasOnRandomTriangles) {
  std::mt19937_64 rng(101);
  Coverage c(70, 50, -3, 4);
  for (int trial = 0; trial < 300; ++trial) {
    // Either orientation, some reaching past the mask's sides.
    Loop tri;
    for (int k = 0; k < 3; ++k) {
      tri.push_back({Uniform(rng, -15.0, 75.0), Uniform(rng, -5.0, 62.0)});
    }
    c.Fill({tri});
    ExpectMatchesReference({tri}, c, "triangle " + std::to_string(trial));
  }
}

TEST(CoverageRasterizer, MatchesClippedAreasOnRandomSimplePolygons) {
  std::mt19937_64 rng(202);
  Coverage c(130, 70, 5, -8);  // more than one word per row
  for (int trial = 0; trial < 80; ++trial) {
    const bool convex = trial % 2 == 0;
    const double radius = Uniform(rng, 2.0, 45.0);
    const Vec2 centre(Uniform(rng, -10.0, 145.0), Uniform(rng, -20.0, 70.0));
    Loop loop = StarPolygon(rng, centre, 3 + static_cast<int>(rng() % 38),
                            convex ? radius : 0.3 * radius, radius);
    if (trial % 3 == 0) std::reverse(loop.begin(), loop.end());
    c.Fill({loop});
    ExpectMatchesReference({loop}, c,
                           std::string(convex ? "convex" : "concave") + " polygon " +
                               std::to_string(trial));
  }
  // Nearly horizontal and nearly vertical edges, long rows and slivers.
  const std::vector<Loop> special = {
      RegularPolygon({70.3, 25.1}, 60.0, 4, 1e-3),
      RegularPolygon({70.3, 25.1}, 60.0, 4, std::numbers::pi / 4 + 1e-9),
      {{8.2, 10.1}, {120.7, 10.35}, {121.0, 10.9}},
      {{40.5, -8.0}, {40.75, 61.0}, {40.6, 61.0}},
      Rectangle(10.25, -30.5, 200.0, 12.5),
  };
  for (size_t k = 0; k < special.size(); ++k) {
    c.Fill({special[k]});
    ExpectMatchesReference({special[k]}, c, "special shape " + std::to_string(k));
  }
}

TEST(CoverageRasterizer, MatchesClippedAreasOnMeshesAtSubPixelOffsets) {
  std::mt19937_64 rng(303);
  MesherOptions mesher;
  mesher.edge_length_px = 7.0;
  const Loop notched = {{10.0, 10.0}, {60.0, 10.0}, {60.0, 45.0}, {40.0, 45.0},
                        {35.0, 25.0}, {30.0, 45.0}, {10.0, 45.0}};
  const std::vector<std::pair<std::string, Mesh>> meshes = {
      {"mesher, notched outline", MeshPolygon(notched, mesher)},
      {"mesher, circle", MeshPolygon(RegularPolygon({35.0, 30.0}, 22.0, 40, 0.2), mesher)},
      {"grid with a hole", GridMeshWithHole(8, 6, 6.0, Vec2(8.0, 9.0), 3, 2)},
  };
  Coverage c(64, 56, 2, 1);  // the shapes reach past its right side
  for (const auto& [name, mesh] : meshes) {
    ASSERT_FALSE(mesh.boundary_loops.empty()) << name;
    for (int trial = 0; trial < 12; ++trial) {
      const Vec2 offset(Uniform(rng, 0.0, 1.0), Uniform(rng, 0.0, 1.0));
      std::vector<Vec2> x = mesh.rest_positions;
      for (Vec2& p : x) {
        p += offset + Vec2(0.8 * std::sin(0.11 * p.y() + trial), 0.6 * std::cos(0.13 * p.x()));
      }
      c.rasterizer.RasterizeMeshCoverage(mesh, x, c.interior, c.boundary);
      const std::string what = name + ", trial " + std::to_string(trial);
      ExpectMatchesReference(BoundaryLoops(mesh, x), c, what);
      // The pointer overload is the same computation.
      Coverage via_pointer(64, 56, 2, 1);
      c.rasterizer.RasterizeMeshCoverage(mesh, x.data(), via_pointer.interior,
                                         via_pointer.boundary);
      EXPECT_TRUE(via_pointer.interior == c.interior && via_pointer.boundary == c.boundary) << what;
    }
  }
}

TEST(CoverageRasterizer, TotalCoverageIsTheShoelaceArea) {
  std::mt19937_64 rng(404);
  Coverage c(200, 120, -20, 10);
  for (int trial = 0; trial < 40; ++trial) {
    const double radius = Uniform(rng, 3.0, 50.0);
    const Vec2 centre(Uniform(rng, 40.0, 120.0), Uniform(rng, 70.0, 75.0));
    const Loop loop = StarPolygon(rng, centre, 3 + static_cast<int>(rng() % 60),
                                  Uniform(rng, 0.2, 1.0) * radius, radius);
    c.Fill({loop});
    const double total = Sum(DenseCoverage(c, "polygon"));
    EXPECT_NEAR(total, ShoelaceArea(loop), 1e-9 * (1.0 + static_cast<double>(c.boundary.size())))
        << "polygon " << trial << ": " << c.boundary.size() << " boundary pixels";
  }
}

TEST(CoverageRasterizer, PixelAlignedShapesGiveExactlyTheBinaryMask) {
  Coverage c(100, 40, -7, 3);
  BitMask centres(100, 40, -7, 3);
  // A unit square covers exactly its pixel.
  c.Fill({Rectangle(5, 8, 6, 9)});
  EXPECT_EQ(c.interior.Count(), 1);
  EXPECT_TRUE(c.interior.Get(5 + 7, 8 - 3));
  EXPECT_TRUE(c.boundary.empty());
  // Integer rectangles (partly outside too) and a grid mesh with integer
  // nodes: whole pixels, the same as the centre rule's.
  for (const Loop& loop : {Rectangle(-3, 5, 40, 30), Rectangle(-20, -5, 200, 12),
                           Rectangle(90, 40, 95, 43)}) {
    c.Fill({loop});
    c.rasterizer.FillPolygons({loop}, centres);
    EXPECT_TRUE(c.boundary.empty()) << c.boundary.size() << " partly covered pixels";
    EXPECT_TRUE(c.interior == centres) << c.interior.Count() << " vs " << centres.Count();
  }
  const Mesh grid = MakeGridMesh(12, 5, 4.0, Vec2(3, 6));
  c.rasterizer.RasterizeMeshCoverage(grid, grid.rest_positions, c.interior, c.boundary);
  c.rasterizer.RasterizeMesh(grid, grid.rest_positions, centres);
  EXPECT_TRUE(c.boundary.empty());
  EXPECT_TRUE(c.interior == centres);
  EXPECT_EQ(c.interior.Count(), 48 * 20);
}

TEST(CoverageRasterizer, ClipsToTheMaskAndRespectsTheOrigin) {
  const std::vector<Loop> loops = {RegularPolygon({30.3, 20.7}, 45.1, 37, 0.1),
                                   {{-40.2, 70.3}, {200.5, 55.1}, {10.9, 130.4}}};
  // The scene in a big mask, then windows onto it reaching past every side.
  Coverage big(400, 300, -150, -100);
  big.Fill(loops);
  const std::vector<double> whole = DenseCoverage(big, "big");
  const BitMask& b = big.interior;
  for (const auto& [ox, oy, w, h] : {std::array{-30, -20, 70, 50}, std::array{0, 0, 64, 64},
                                     std::array{50, 40, 130, 33}, std::array{-5, 60, 65, 80},
                                     std::array{500, 500, 10, 10}}) {
    Coverage window(w, h, ox, oy);
    window.interior.SetSpan(0, 0, w);  // stale content must be cleared
    window.boundary = {{1, 1, 0.5}};
    window.Fill(loops);
    const std::vector<double> part = DenseCoverage(window, "window");
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int bx = ox + x - b.origin_x(), by = oy + y - b.origin_y();
        const bool inside_big = bx >= 0 && bx < b.width() && by >= 0 && by < b.height();
        const double expected = inside_big ? whole[static_cast<size_t>(by) * b.width() + bx] : 0.0;
        ASSERT_NEAR(part[static_cast<size_t>(y) * w + x], expected, kPixelTolerance)
            << "window origin (" << ox << ", " << oy << "), mask pixel (" << x << ", " << y << ")";
      }
    }
  }
  // A shape over the whole mask covers every pixel in full.
  Coverage small(70, 9, 3, 3);
  small.Fill({RegularPolygon({40.0, 7.0}, 1000.0, 7, 0.3)});
  EXPECT_EQ(small.interior.Count(), 70 * 9);
  EXPECT_TRUE(small.boundary.empty());
}

TEST(CoverageRasterizer, EmptyAndNonFiniteInputsAddNothing) {
  Coverage c(70, 10, 0, 0), alone(70, 10, 0, 0);
  c.interior.SetSpan(3, 0, 70);
  c.Fill({});
  EXPECT_EQ(c.interior.Count(), 0);
  EXPECT_TRUE(c.boundary.empty());
  c.Fill({{{1.0, 1.0}, {5.0, 5.0}}, Rectangle(1.0, 2.0, 9.0, 2.0)});
  EXPECT_EQ(c.interior.Count(), 0) << "a two-point loop and a zero-height rectangle";
  EXPECT_TRUE(c.boundary.empty());
  // A loop whose points are not finite (a blown-up state) is ignored.
  const Loop good = Rectangle(2.5, 1.25, 30.75, 8.5);
  const Loop bad = {{NAN, 2.0}, {INFINITY, 3.0}, {5.0, -INFINITY}};
  alone.Fill({good});
  c.Fill({good, bad});
  EXPECT_TRUE(c.interior == alone.interior && c.boundary == alone.boundary);
}

TEST(CoverageRasterizer, OverlappingLoopsClampToFullCoverage) {
  // A folded mesh winds twice where it overlaps itself: coverage stays <= 1,
  // and what either loop covers in full stays covered in full.
  Coverage both(60, 40, 0, 0), one(60, 40, 0, 0);
  const Loop a = Rectangle(5.3, 4.6, 40.2, 30.7);
  const Loop b = Rectangle(20.5, 10.25, 55.9, 35.1);
  both.Fill({a, b});
  const std::vector<double> dense = DenseCoverage(both, "two loops");
  EXPECT_LE(*std::max_element(dense.begin(), dense.end()), 1.0);
  for (const Loop& loop : {a, b}) {
    one.Fill({loop});
    for (size_t k = 0; k < one.interior.words().size(); ++k) {
      ASSERT_EQ(one.interior.words()[k] & ~both.interior.words()[k], 0u);
    }
  }
}

// The score moves by at most the area the outline sweeps: perimeter x the
// shift. The centre rule jumps by a whole column of pixels when an edge
// crosses a row of pixel centres.
TEST(CoverageRasterizer, ScoreIsContinuousUnderTranslation) {
  std::mt19937_64 rng(505);
  Coverage c(120, 90, -4, 6);
  BitMask object(120, 90, -4, 6);
  c.rasterizer.FillPolygons({RegularPolygon({55.0, 50.0}, 30.0, 9, 0.4)}, object);
  for (int trial = 0; trial < 200; ++trial) {
    const Loop loop = StarPolygon(rng, Vec2(Uniform(rng, 30.0, 80.0), Uniform(rng, 30.0, 70.0)),
                                  3 + static_cast<int>(rng() % 20), 10.0, 35.0);
    const double step = std::pow(10.0, -Uniform(rng, 1.0, 8.0));
    const double angle = Uniform(rng, 0.0, 2.0 * std::numbers::pi);
    const Vec2 shift = step * Vec2(std::cos(angle), std::sin(angle));
    Loop moved = loop;
    for (Vec2& p : moved) p += shift;
    c.Fill({loop});
    const double before = c.Score(object);
    c.Fill({moved});
    ASSERT_LE(std::abs(c.Score(object) - before), Perimeter(loop) * step + 1e-9)
        << "trial " << trial << ": shift " << step << " px";
  }
  // An edge on a column of pixel centres, moved by 1e-7 px.
  const Loop block = Rectangle(20.5, 12.25, 60.0, 52.75);
  Loop nudged = block;
  for (Vec2& p : nudged) p.x() += 1e-7;
  BitMask centres(120, 90, -4, 6);
  c.rasterizer.FillPolygons({block}, centres);
  const double centre_before = CompareMasks(object, centres).xor_px;
  c.rasterizer.FillPolygons({nudged}, centres);
  const double centre_after = CompareMasks(object, centres).xor_px;
  EXPECT_GE(std::abs(centre_after - centre_before), 40.0) << "the centre rule jumps a column";
  c.Fill({block});
  const double before = c.Score(object);
  c.Fill({nudged});
  EXPECT_LE(std::abs(c.Score(object) - before), Perimeter(block) * 1e-7 + 1e-9);
}

TEST(CoverageRasterizer, SameInputGivesBitIdenticalOutput) {
  std::mt19937_64 rng(606);
  Coverage used(90, 70, 3, -2), other(40, 30, -9, 7);
  for (int trial = 0; trial < 30; ++trial) {
    const std::vector<Loop> loops = {
        StarPolygon(rng, Vec2(Uniform(rng, 20, 70), Uniform(rng, 10, 50)), 12, 8.0, 30.0),
        StarPolygon(rng, Vec2(Uniform(rng, 20, 70), Uniform(rng, 10, 50)), 5, 3.0, 9.0)};
    // A fresh rasteriser, and one that has just filled a mask of another shape.
    Coverage fresh(90, 70, 3, -2);
    fresh.Fill(loops);
    used.rasterizer.FillPolygonsCoverage({RegularPolygon({0.0, 20.0}, 25.3, 11, 0.2)},
                                         other.interior, other.boundary);
    used.Fill(loops);
    EXPECT_TRUE(fresh.interior == used.interior && fresh.boundary == used.boundary)
        << "trial " << trial;
  }
}

TEST(CoverageRasterizer, ScoreOverTheCoveredRowsIsTheWholeMasksScore) {
  // CompareCoverageInRows counts only the rows the last fill touched: the
  // same score, field for field, as counting every word, for shapes inside
  // the mask, clipped at its top or bottom, beside it and with none at all.
  std::mt19937_64 rng(707);
  Coverage c(150, 110, -7, 4);
  BitMask object(150, 110, -7, 4);
  c.rasterizer.FillPolygons({StarPolygon(rng, Vec2(60.0, 55.0), 11, 15.0, 40.0)}, object);
  const int64_t object_px = object.Count();
  const auto expect_same = [&](const std::string& what) {
    const auto [row_begin, row_end] = c.rasterizer.covered_rows();
    ASSERT_LE(0, row_begin);
    ASSERT_LE(row_begin, row_end);
    ASSERT_LE(row_end, c.interior.height());
    for (int y = 0; y < c.interior.height(); ++y) {
      if (y >= row_begin && y < row_end) continue;
      for (int w = 0; w < c.interior.words_per_row(); ++w) {
        ASSERT_EQ(c.interior.Row(y)[w], 0u) << what << ": a pixel in row " << y;
      }
    }
    const FrameScore whole = CompareCoverage(object, c.interior, c.boundary);
    const FrameScore rows =
        CompareCoverageInRows(object, object_px, c.interior, row_begin, row_end, c.boundary);
    EXPECT_EQ(rows, whole) << what;
  };
  for (int trial = 0; trial < 40; ++trial) {
    const Vec2 centre(Uniform(rng, -30.0, 170.0), Uniform(rng, -20.0, 140.0));
    c.Fill({StarPolygon(rng, centre, 3 + static_cast<int>(rng() % 15), 4.0, 45.0)});
    expect_same("trial " + std::to_string(trial));
  }
  c.Fill({});
  EXPECT_EQ(c.rasterizer.covered_rows(), std::make_pair(0, 0));
  expect_same("no loop");
  c.Fill({Rectangle(-50.0, -40.0, 300.0, 200.0)});  // the whole mask
  expect_same("the whole mask");
}

TEST(CoverageRasterizer, SteadyStateDoesNotAllocate) {
  const Mesh mesh = MakeGridMesh(20, 14, 6.0, Vec2(30.5, 20.25));
  Rasterizer r;
  BitMask object(200, 150, 10, 5), interior(200, 150, 10, 5);
  r.RasterizeMesh(mesh, mesh.rest_positions, object);
  std::vector<PixelCoverage> boundary;
  std::vector<Vec2> x(mesh.rest_positions.size());
  const auto run = [&] {
    std::copy(mesh.rest_positions.begin(), mesh.rest_positions.end(), x.begin());
    double score = 0.0;
    for (int frame = 0; frame < 20; ++frame) {
      for (size_t i = 0; i < x.size(); ++i) {
        x[i] += Vec2(0.37 + 0.01 * std::sin(0.3 * i + frame), -0.21);  // stays inside the mask
      }
      r.RasterizeMeshCoverage(mesh, x, interior, boundary);
      score += CompareCoverage(object, interior, boundary).xor_px;
    }
    return score;
  };
  const double warm_up = run();  // buffers grow here
  const int64_t before = Allocations();
  const double score = run();
  EXPECT_EQ(Allocations() - before, 0);
  EXPECT_EQ(score, warm_up);
  EXPECT_GT(score, 0.0);
}

}  // namespace
}  // namespace calib
