#include "calib/evaluator/rasterizer.h"

#include "polygon_support.h"
#include "support/allocation_counter.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <string>
#include <vector>

namespace calib {
namespace {

using testing::Loop;
using testing::Perimeter;
using testing::Rectangle;
using testing::RegularPolygon;
using testing::ShoelaceArea;
using testing::Uniform;

// Winding number of `loops` at p by the rasteriser's rule, evaluated
// independently per pixel: an edge counts when p.y lies in [min y, max y) of
// the edge and the crossing is at or left of p.x.
int WindingAt(const std::vector<Loop>& loops, const Vec2& p) {
  int winding = 0;
  for (const Loop& loop : loops) {
    for (size_t i = 0; i < loop.size(); ++i) {
      const Vec2& u = loop[i];
      const Vec2& v = loop[(i + 1) % loop.size()];
      if (u.y() == v.y()) continue;
      const Vec2& a = u.y() < v.y() ? u : v;
      const Vec2& b = u.y() < v.y() ? v : u;
      if (!(a.y() <= p.y() && p.y() < b.y())) continue;
      const double x = a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (x <= p.x()) winding += u.y() < v.y() ? 1 : -1;
    }
  }
  return winding;
}

// Distance from p to the nearest edge of `loops`.
double DistanceToEdges(const std::vector<Loop>& loops, const Vec2& p) {
  double best = INFINITY;
  for (const Loop& loop : loops) {
    for (size_t i = 0; i < loop.size(); ++i) {
      const Vec2& a = loop[i];
      const Vec2 d = loop[(i + 1) % loop.size()] - a;
      const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
      best = std::min(best, (a + t * d - p).norm());
    }
  }
  return best;
}

std::string Describe(const BitMask& m) {
  std::string s;
  for (int y = 0; y < m.height(); ++y) {
    for (int x = 0; x < m.width(); ++x) s += m.Get(x, y) ? '#' : '.';
    s += '\n';
  }
  return s;
}

// The first pixel where two same-shaped masks differ, for messages.
std::string FirstDifference(const BitMask& a, const BitMask& b) {
  if (!a.SameShape(b)) return "masks differ in shape";
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      if (a.Get(x, y) != b.Get(x, y)) {
        return "first difference at mask pixel (" + std::to_string(x) + ", " +
               std::to_string(y) + ")";
      }
    }
  }
  return "identical";
}

// A lattice mesh (nx x ny cells of `spacing` px from `origin`) with random
// diagonals, optionally jittered nodes and without the cells for which
// `hole(i, j)` is true.
template <class Hole>
Mesh LatticeMesh(int nx, int ny, double spacing, const Vec2& origin, double jitter_px,
                 std::mt19937_64& rng, Hole hole) {
  std::vector<Vec2> positions;
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) {
      positions.push_back(origin + spacing * Vec2(i, j) +
                          Vec2(Uniform(rng, -jitter_px, jitter_px),
                               Uniform(rng, -jitter_px, jitter_px)));
    }
  }
  const auto id = [nx](int i, int j) { return j * (nx + 1) + i; };
  std::vector<std::array<int, 3>> triangles;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if (hole(i, j)) continue;
      if (rng() & 1) {
        triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
        triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
      } else {
        triangles.push_back({id(i, j), id(i + 1, j), id(i, j + 1)});
        triangles.push_back({id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)});
      }
    }
  }
  // Nodes left only in removed cells stay in the mesh, unused; harmless here.
  return BuildMesh(std::move(positions), std::move(triangles));
}

bool AllTrianglesPositive(const Mesh& mesh, const std::vector<Vec2>& x) {
  for (const auto& t : mesh.triangles) {
    if (!(SignedArea(x[t[0]], x[t[1]], x[t[2]]) > 0.0)) return false;
  }
  return true;
}

// A smooth deformation: a bend, a shear wave and a squeeze, small enough for
// the lattices below to keep every triangle positive.
std::vector<Vec2> Deform(const std::vector<Vec2>& rest, const Vec2& centre, double amplitude_px) {
  std::vector<Vec2> x = rest;
  for (Vec2& p : x) {
    const Vec2 d = p - centre;
    p += amplitude_px * Vec2(std::sin(0.05 * d.y()) + 0.3 * std::cos(0.07 * d.x()),
                             0.5 * std::sin(0.04 * d.x() + 0.3) - 0.002 * d.y());
  }
  return x;
}

TEST(Rasterizer, UnitSquareSetsExactlyItsPixel) {
  Rasterizer r;
  for (const auto& [ox, oy] : {std::pair{0, 0}, std::pair{-3, 5}, std::pair{7, -2}}) {
    BitMask mask(20, 12, ox, oy);
    for (const auto& [fx, fy] : {std::pair{ox, oy}, std::pair{ox + 5, oy + 3},
                                 std::pair{ox + 19, oy + 11}, std::pair{ox + 13, oy + 0}}) {
      r.FillPolygons({Rectangle(fx, fy, fx + 1, fy + 1)}, mask);
      EXPECT_EQ(mask.Count(), 1) << "square at frame (" << fx << ", " << fy << "), origin (" << ox
                                 << ", " << oy << ")\n"
                                 << Describe(mask);
      EXPECT_TRUE(mask.Get(fx - ox, fy - oy))
          << "square at frame (" << fx << ", " << fy << "), origin (" << ox << ", " << oy << ")";
    }
  }
}

TEST(Rasterizer, CentresOnEdgesFollowTheHalfOpenRule) {
  Rasterizer r;
  BitMask mask(10, 10);
  // Edges through pixel centres: x from 1.5 to 4.5 covers centres 1.5, 2.5,
  // 3.5 (not 4.5); likewise in y.
  r.FillPolygons({Rectangle(1.5, 2.5, 4.5, 5.5)}, mask);
  EXPECT_EQ(mask.Count(), 9) << Describe(mask);
  EXPECT_TRUE(mask.Get(1, 2) && mask.Get(3, 4)) << Describe(mask);
  EXPECT_FALSE(mask.Get(4, 2) || mask.Get(1, 5)) << Describe(mask);

  // Two rectangles sharing an edge through centres claim each centre once.
  BitMask left(10, 10), right(10, 10), both(10, 10);
  r.FillPolygons({Rectangle(0.0, 0.0, 3.5, 10.0)}, left);
  r.FillPolygons({Rectangle(3.5, 0.0, 10.0, 10.0)}, right);
  r.FillPolygons({Rectangle(0.0, 0.0, 3.5, 10.0), Rectangle(3.5, 0.0, 10.0, 10.0)}, both);
  EXPECT_EQ(left.Count() + right.Count(), 100);
  EXPECT_EQ(both.Count(), 100) << Describe(both);
}

TEST(Rasterizer, AxisAlignedRectangleCountIsExact) {
  Rasterizer r;
  BitMask mask(64 + 37, 50, -4, 3);
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 200; ++trial) {
    const double x0 = Uniform(rng, -10.0, 60.0), x1 = x0 + Uniform(rng, 0.0, 70.0);
    const double y0 = Uniform(rng, -5.0, 40.0), y1 = y0 + Uniform(rng, 0.0, 30.0);
    r.FillPolygons({Rectangle(x0, y0, x1, y1)}, mask);
    // Columns with centre c = ox + x + 0.5 in [x0, x1), clipped to the mask.
    const auto count = [](double lo, double hi, int origin, int size) {
      const double first = std::clamp(std::ceil(lo - origin - 0.5), 0.0, double(size));
      const double end = std::clamp(std::ceil(hi - origin - 0.5), 0.0, double(size));
      return static_cast<int64_t>(end - first);
    };
    const int64_t expected = count(x0, x1, mask.origin_x(), mask.width()) *
                             count(y0, y1, mask.origin_y(), mask.height());
    EXPECT_EQ(mask.Count(), expected)
        << "rectangle [" << x0 << ", " << x1 << "] x [" << y0 << ", " << y1 << "]";
  }
}

// Bounds on |count - area| for the orthogonally convex shapes below (every
// row and every column meets the shape in at most one interval), with w x h
// the bounding box:
//  - rigorous: summing by rows, a span's pixel count differs from its chord
//    length l(y) at the row centre by less than 1 (at most h + 1 rows), and
//    the midpoint rule sum of l over rows differs from the integral of l by at
//    most the total variation of l, 2 w (l rises from 0 to at most w and falls
//    back); so |error| <= h + 2 w + 1, and by columns w + 2 h + 1;
//  - the specified perimeter + 4, looser than the above for these shapes
//    unless their edges run near 45 degrees; it holds comfortably because
//    the per-pixel errors along the boundary largely cancel.
double RigorousAreaBound(const Loop& loop) {
  double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
  for (const Vec2& p : loop) {
    x0 = std::min(x0, p.x());
    x1 = std::max(x1, p.x());
    y0 = std::min(y0, p.y());
    y1 = std::max(y1, p.y());
  }
  const double w = x1 - x0, h = y1 - y0;
  return std::min(h + 2.0 * w, w + 2.0 * h) + 1.0;
}

TEST(Rasterizer, AreaMatchesAnalyticArea) {
  struct Case {
    std::string name;
    Loop loop;
  };
  std::vector<Case> cases = {
      {"rectangle at fractional offset", Rectangle(10.3, 7.71, 83.9, 51.25)},
      {"rectangle with edges through centres", Rectangle(5.5, 5.5, 66.49, 40.01)},
      {"rotated square", RegularPolygon({60.2, 45.7}, 30.0, 4, 0.3)},
      {"triangle", {{12.2, 80.1}, {100.7, 10.4}, {70.3, 85.9}}},
      {"circle polygon", RegularPolygon({64.4, 48.3}, 35.7, 128, 0.0)},
      {"concave L",
       {{10.25, 10.5}, {40.75, 10.5}, {40.75, 60.2}, {90.1, 60.2}, {90.1, 85.6}, {10.25, 85.6}}},
  };
  Rasterizer r;
  BitMask mask(128, 96);
  for (const Case& c : cases) {
    for (bool reversed : {false, true}) {
      Loop loop = c.loop;
      if (reversed) std::reverse(loop.begin(), loop.end());
      r.FillPolygons({loop}, mask);
      const double area = ShoelaceArea(loop);
      const double error = std::abs(static_cast<double>(mask.Count()) - area);
      const std::string what = c.name + (reversed ? " (reversed)" : "") + ": count " +
                               std::to_string(mask.Count()) + ", area " + std::to_string(area);
      EXPECT_LE(error, RigorousAreaBound(loop)) << what;
      EXPECT_LE(error, Perimeter(loop) + 4.0) << what;
    }
  }
}

// Pixel-centre sampling of a randomly translated shape is unbiased: the mean
// of count - area over random offsets tends to 0. A half-pixel shift of the
// convention would bias it by about half the perimeter.
TEST(Rasterizer, AreaIsUnbiasedOverRandomOffsets) {
  std::mt19937_64 rng(17);
  Rasterizer r;
  BitMask mask(128, 96, -10, -10);
  const std::vector<Loop> shapes = {RegularPolygon({0, 0}, 30.0, 4, 0.4),
                                    RegularPolygon({0, 0}, 35.0, 64, 0.0),
                                    {{-30.0, 20.0}, {25.0, -31.0}, {10.0, 33.0}},
                                    Rectangle(-20.0, -15.0, 21.0, 16.0)};
  constexpr int kTrials = 400;
  for (size_t k = 0; k < shapes.size(); ++k) {
    const double area = ShoelaceArea(shapes[k]);
    double sum = 0.0, worst = 0.0;
    for (int trial = 0; trial < kTrials; ++trial) {
      const Vec2 offset(Uniform(rng, 40.0, 60.0), Uniform(rng, 30.0, 40.0));
      Loop loop = shapes[k];
      for (Vec2& p : loop) p += offset;
      r.FillPolygons({loop}, mask);
      const double error = static_cast<double>(mask.Count()) - area;
      sum += error;
      worst = std::max(worst, std::abs(error));
      ASSERT_LE(std::abs(error), RigorousAreaBound(loop)) << "shape " << k << ", trial " << trial;
    }
    EXPECT_LE(std::abs(sum / kTrials), 1.5)
        << "shape " << k << ": mean error " << sum / kTrials << " px, worst " << worst;
  }
}

TEST(Rasterizer, MatchesPerPixelWindingOnRandomPolygons) {
  std::mt19937_64 rng(11);
  Rasterizer r;
  BitMask mask(90, 70, -5, 8);
  int checked = 0;
  for (int trial = 0; trial < 40; ++trial) {
    // Random self-intersecting loops, some reaching outside the mask, plus a
    // random second loop of random orientation.
    std::vector<Loop> loops(1 + trial % 2);
    for (Loop& loop : loops) {
      const int n = 3 + static_cast<int>(rng() % 9);
      for (int k = 0; k < n; ++k) {
        loop.push_back({Uniform(rng, -20.0, 100.0), Uniform(rng, -10.0, 90.0)});
      }
    }
    r.FillPolygons(loops, mask);
    for (int y = 0; y < mask.height(); ++y) {
      for (int x = 0; x < mask.width(); ++x) {
        const Vec2 centre(mask.origin_x() + x + 0.5, mask.origin_y() + y + 0.5);
        // Centres within rounding of an edge may go either way.
        if (DistanceToEdges(loops, centre) < 1e-9) continue;
        ++checked;
        ASSERT_EQ(mask.Get(x, y), WindingAt(loops, centre) != 0)
            << "trial " << trial << ", mask pixel (" << x << ", " << y << ")";
      }
    }
  }
  EXPECT_GT(checked, 40 * 90 * 70 * 9 / 10);
}

TEST(Rasterizer, NonZeroWindingFillsThePentagramCentre) {
  Rasterizer r;
  BitMask mask(100, 100);
  const Loop pentagon = RegularPolygon({50.0, 50.0}, 40.0, 5, -std::numbers::pi / 2);
  Loop star;
  for (int k = 0; k < 5; ++k) star.push_back(pentagon[(2 * k) % 5]);
  r.FillPolygons({star}, mask);
  EXPECT_TRUE(mask.Get(49, 49) && mask.Get(50, 50)) << "the doubly wound centre is filled";
  // Two opposite loops cancel: a square with a reversed square inside is a
  // ring.
  Loop inner = Rectangle(30.0, 30.0, 70.0, 70.0);
  std::reverse(inner.begin(), inner.end());
  r.FillPolygons({Rectangle(10.0, 10.0, 90.0, 90.0), inner}, mask);
  EXPECT_EQ(mask.Count(), 80 * 80 - 40 * 40);
  EXPECT_FALSE(mask.Get(50, 50));
}

TEST(Rasterizer, ClipsToTheMaskAndRespectsTheOrigin) {
  std::mt19937_64 rng(5);
  Rasterizer r;
  const std::vector<Loop> loops = {RegularPolygon({30.3, 20.7}, 45.1, 37, 0.1),
                                   {{-40.2, 70.3}, {200.5, 55.1}, {10.9, 130.4}}};
  // The whole scene in a big mask, then windows onto it at several origins,
  // reaching past every side.
  BitMask big(400, 300, -150, -100);
  r.FillPolygons(loops, big);
  ASSERT_GT(big.Count(), 0);
  for (const auto& [ox, oy, w, h] : {std::array{-30, -20, 70, 50}, std::array{0, 0, 64, 64},
                                     std::array{50, 40, 130, 33}, std::array{-5, 60, 65, 80},
                                     std::array{500, 500, 10, 10}}) {
    BitMask window(w, h, ox, oy);
    window.Set(0, 0);  // stale content must be cleared
    r.FillPolygons(loops, window);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int bx = ox + x - big.origin_x(), by = oy + y - big.origin_y();
        const bool inside_big = bx >= 0 && bx < big.width() && by >= 0 && by < big.height();
        ASSERT_EQ(window.Get(x, y), inside_big && big.Get(bx, by))
            << "window origin (" << ox << ", " << oy << "), mask pixel (" << x << ", " << y
            << ")";
      }
    }
  }
}

TEST(Rasterizer, EmptyInputsGiveAnEmptyMask) {
  Rasterizer r;
  BitMask mask(70, 10);
  mask.SetSpan(3, 0, 70);
  r.FillPolygons({}, mask);
  EXPECT_EQ(mask.Count(), 0);
  mask.SetSpan(3, 0, 70);
  r.FillPolygons({{{1.0, 1.0}, {5.0, 5.0}}, Rectangle(1.0, 2.0, 9.0, 2.0)}, mask);
  EXPECT_EQ(mask.Count(), 0) << "a two-point loop and a zero-height rectangle";
  BitMask none;
  r.FillPolygons({Rectangle(0, 0, 5, 5)}, none);
  EXPECT_EQ(none.Count(), 0);
}

TEST(Rasterizer, MeshWindingEqualsTriangleUnion) {
  struct Case {
    std::string name;
    Mesh mesh;
  };
  std::mt19937_64 rng(3);
  const auto no_hole = [](int, int) { return false; };
  std::vector<Case> cases;
  cases.push_back({"grid mesh, integer nodes", testing::MakeGridMesh(12, 8, 4.0, Vec2(10, 6))});
  cases.push_back({"grid mesh, fractional nodes",
                   testing::MakeGridMesh(9, 11, 5.3, Vec2(7.31, 4.77))});
  cases.push_back(
      {"lattice, integer nodes (centres on diagonals)",
       LatticeMesh(15, 10, 4.0, Vec2(12, 9), 0.0, rng, no_hole)});
  cases.push_back({"jittered lattice", LatticeMesh(14, 12, 5.0, Vec2(8.2, 6.9), 1.2, rng, no_hole)});
  cases.push_back({"jittered lattice with holes",
                   LatticeMesh(16, 12, 4.5, Vec2(6.6, 5.1), 1.0, rng, [](int i, int j) {
                     return (i == 4 && j == 3) || (i >= 9 && i <= 11 && j >= 6 && j <= 8) ||
                            (i == 2 && j == 9);
                   })});
  Rasterizer r;
  for (const Case& c : cases) {
    ASSERT_FALSE(c.mesh.boundary_loops.empty()) << c.name;
    for (const auto& [ox, oy, w, h] :
         {std::array{0, 0, 100, 80}, std::array{-7, 3, 150, 90}, std::array{20, 15, 40, 30}}) {
      BitMask fast(w, h, ox, oy), reference(w, h, ox, oy);
      for (double amplitude : {0.0, 1.5, 3.0}) {
        const std::vector<Vec2> x =
            Deform(c.mesh.rest_positions, c.mesh.rest_positions[0], amplitude);
        ASSERT_TRUE(AllTrianglesPositive(c.mesh, x)) << c.name << ", amplitude " << amplitude;
        r.RasterizeMesh(c.mesh, x, fast);
        r.RasterizeTriangles(c.mesh, x, reference);
        EXPECT_GT(reference.Count(), 0) << c.name;
        EXPECT_TRUE(fast == reference)
            << c.name << ", amplitude " << amplitude << ", origin (" << ox << ", " << oy
            << "): " << FirstDifference(fast, reference) << "; counts " << fast.Count() << " vs "
            << reference.Count();
        // The pointer overload is the same computation.
        BitMask via_pointer(w, h, ox, oy);
        r.RasterizeMesh(c.mesh, x.data(), via_pointer);
        EXPECT_TRUE(via_pointer == fast) << c.name;
      }
    }
  }
}

TEST(Rasterizer, MeshAreaMatchesTheMeshArea) {
  const Mesh mesh = testing::MakeGridMesh(10, 6, 6.3, Vec2(5.2, 7.9));
  Rasterizer r;
  BitMask mask(100, 60);
  r.RasterizeMesh(mesh, mesh.rest_positions, mask);
  // A 63 x 37.8 rectangle.
  EXPECT_EQ(mask.Count(), 63 * 38) << Describe(mask);
}

TEST(Rasterizer, TrianglesCoverInvertedParts) {
  // Fold one node of a grid across its neighbours: the winding path may
  // cancel the folded part, the triangle union keeps it.
  const Mesh mesh = testing::MakeGridMesh(4, 4, 10.0, Vec2(5, 5));
  std::vector<Vec2> x = mesh.rest_positions;
  x[0] += Vec2(25.0, 25.0);  // the corner node folds into the mesh
  ASSERT_FALSE(AllTrianglesPositive(mesh, x));
  Rasterizer r;
  BitMask reference(60, 60);
  r.RasterizeTriangles(mesh, x, reference);
  // Every triangle's own pixels are in the union.
  for (const auto& t : mesh.triangles) {
    BitMask one(60, 60);
    r.FillPolygons({{x[t[0]], x[t[1]], x[t[2]]}}, one);
    for (size_t k = 0; k < one.words().size(); ++k) {
      ASSERT_EQ(one.words()[k] & ~reference.words()[k], 0u);
    }
  }
}

TEST(Rasterizer, SteadyStateDoesNotAllocate) {
  const Mesh mesh = testing::MakeGridMesh(20, 14, 6.0, Vec2(30.5, 20.25));
  Rasterizer r;
  BitMask mask(200, 150, 10, 5);
  std::vector<Vec2> x = Deform(mesh.rest_positions, mesh.rest_positions[0], 3.0);
  r.RasterizeMesh(mesh, x, mask);  // warm-up: buffers grow here
  const int64_t before = testing::Allocations();
  int64_t covered = 0;
  for (int frame = 0; frame < 20; ++frame) {
    for (Vec2& p : x) p += Vec2(0.37, -0.21);  // stays well inside the mask rows
    r.RasterizeMesh(mesh, x, mask);
    covered += mask.Count();
  }
  EXPECT_EQ(testing::Allocations() - before, 0);
  EXPECT_GT(covered, 0);
}

}  // namespace
}  // namespace calib
