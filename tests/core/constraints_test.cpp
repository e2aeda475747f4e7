// The constraints' scans (a vectorised search for the next element to act
// on, then the scalar step) against the plain index-order loops they
// replace: same return values and the same bits in every position, on meshes
// whose sizes are not multiples of the scan block, with many, few and no
// elements to act on, and with clamped nodes; and the edges' bounding-box
// prefilter.

#include "calib/core/constraints.h"

#include "support/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>

namespace calib {
namespace {

using calib::testing::MakeGridMesh;

// The plain loops, as constraints.cpp had them before the scans.
int PlainProjectOutOfDiscs(std::span<const Disc> discs, std::span<const double> inverse_weight,
                           std::span<Vec2> x) {
  int moved = 0;
  for (const Disc& disc : discs) {
    const double inner = disc.radius_px * (1.0 - 1e-12);
    const double inner_sq = inner * inner;
    for (size_t i = 0; i < x.size(); ++i) {
      const Vec2 d = x[i] - disc.centre;
      const double dist_sq = d.squaredNorm();
      if (dist_sq >= inner_sq || inverse_weight[i] == 0.0) continue;
      const double dist = std::sqrt(dist_sq);
      x[i] = dist > 0.0 ? Vec2(disc.centre + d * (disc.radius_px / dist))
                        : Vec2(disc.centre + Vec2(disc.radius_px, 0.0));
      ++moved;
    }
  }
  return moved;
}

int PlainRepairInvertedTriangles(const Mesh& mesh, double min_area_fraction,
                                 std::span<const double> inverse_weight, std::span<Vec2> x) {
  int repaired = 0;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    const double target = min_area_fraction * mesh.rest_area_px2[t];
    const double area = SignedArea(x[a], x[b], x[c]);
    if (area >= target) continue;
    const Vec2 ga = 0.5 * Vec2(x[b].y() - x[c].y(), x[c].x() - x[b].x());
    const Vec2 gb = 0.5 * Vec2(x[c].y() - x[a].y(), x[a].x() - x[c].x());
    const Vec2 gc = 0.5 * Vec2(x[a].y() - x[b].y(), x[b].x() - x[a].x());
    const double wa = inverse_weight[a], wb = inverse_weight[b], wc = inverse_weight[c];
    const double denom = wa * ga.squaredNorm() + wb * gb.squaredNorm() + wc * gc.squaredNorm();
    if (!(denom > 0.0)) continue;
    const double lambda = (2.0 * target - area) / denom;
    x[a] += lambda * wa * ga;
    x[b] += lambda * wb * gb;
    x[c] += lambda * wc * gc;
    ++repaired;
  }
  return repaired;
}

int PlainFindInvertedTriangle(const Mesh& mesh, std::span<const Vec2> x) {
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    if (!(SignedArea(x[a], x[b], x[c]) > 0.0)) return static_cast<int>(t);
  }
  return -1;
}

int PlainFindNodeInsideDisc(std::span<const Disc> discs, std::span<const Vec2> x,
                            double tolerance_px) {
  for (const Disc& disc : discs) {
    const double limit = disc.radius_px - tolerance_px;
    if (limit <= 0.0) continue;
    for (size_t i = 0; i < x.size(); ++i) {
      if ((x[i] - disc.centre).squaredNorm() < limit * limit) return static_cast<int>(i);
    }
  }
  return -1;
}

using calib::testing::Jittered;

void ExpectSameBits(const std::vector<Vec2>& expected, const std::vector<Vec2>& actual,
                    const std::string& what) {
  ASSERT_EQ(expected.size(), actual.size()) << what;
  for (size_t i = 0; i < expected.size(); ++i) {
    for (int d = 0; d < 2; ++d) {
      EXPECT_EQ(std::bit_cast<uint64_t>(expected[i][d]), std::bit_cast<uint64_t>(actual[i][d]))
          << what << ": node " << i << " component " << d << ": " << expected[i][d] << " vs "
          << actual[i][d];
    }
  }
}

// Every seventh node clamped (inverse weight 0).
std::vector<double> Weights(const Mesh& mesh) {
  std::vector<double> w(mesh.NumNodes(), 1.0);
  for (int i = 0; i < mesh.NumNodes(); i += 7) w[i] = 0.0;
  return w;
}

// Grids of 7x5 (35 nodes, 48 triangles) to 19x13, jittered from not at all to
// enough to invert many triangles.
TEST(Constraints, RepairMatchesThePlainLoopBitForBit) {
  for (const auto& [nx, ny] : {std::pair{7, 5}, std::pair{13, 9}, std::pair{19, 13}}) {
    const Mesh mesh = MakeGridMesh(nx, ny, 10.0, Vec2(3, 4));
    const std::vector<double> w = Weights(mesh);
    for (const double amount : {0.0, 1.0, 4.0, 8.0}) {
      for (const double fraction : {0.05, 0.3, 0.9}) {
        const std::string what = std::to_string(nx) + "x" + std::to_string(ny) + " jitter " +
                                 std::to_string(amount) + " fraction " + std::to_string(fraction);
        std::vector<Vec2> expected = Jittered(mesh.rest_positions, amount, 11);
        std::vector<Vec2> actual = expected;
        // Several rounds, as the simulator runs them.
        for (int round = 0; round < 3; ++round) {
          const int n_expected = PlainRepairInvertedTriangles(mesh, fraction, w, expected);
          const int n_actual = RepairInvertedTriangles(mesh, fraction, w, actual);
          EXPECT_EQ(n_expected, n_actual) << what << " round " << round;
          ExpectSameBits(expected, actual, what);
        }
        EXPECT_EQ(PlainFindInvertedTriangle(mesh, expected), FindInvertedTriangle(mesh, actual))
            << what;
      }
    }
  }
}

TEST(Constraints, FindInvertedTriangleMatchesThePlainLoop) {
  const Mesh mesh = MakeGridMesh(19, 13, 10.0);
  for (const int t : {0, 5, 15, 16, 17, 100, mesh.NumTriangles() - 1}) {
    std::vector<Vec2> x = mesh.rest_positions;
    EXPECT_EQ(FindInvertedTriangle(mesh, x), -1);
    const auto [a, b, c] = mesh.triangles[t];
    x[c] = x[a] + (x[b] - x[a]) * 0.5;  // zero area: counts as inverted
    EXPECT_EQ(PlainFindInvertedTriangle(mesh, x), FindInvertedTriangle(mesh, x)) << t;
    EXPECT_LE(FindInvertedTriangle(mesh, x), t) << t;
  }
}

TEST(Constraints, ProjectionMatchesThePlainLoopBitForBit) {
  for (const auto& [nx, ny] : {std::pair{7, 5}, std::pair{13, 9}, std::pair{19, 13}}) {
    const Mesh mesh = MakeGridMesh(nx, ny, 10.0);
    const std::vector<double> w = Weights(mesh);
    const std::vector<Vec2> x0 = Jittered(mesh.rest_positions, 3.0, 5);
    // No disc touching the mesh; one over a corner; two overlapping; one
    // centred exactly on a node.
    const std::vector<std::vector<Disc>> cases = {
        {{Vec2(-100, -100), 5.0}},
        {{Vec2(0, 0), 14.0}},
        {{Vec2(30, 20), 17.0}, {Vec2(45, 25), 12.0}},
        {{x0[8], 6.0}, {x0[nx * ny - 1], 25.0}},
    };
    for (size_t k = 0; k < cases.size(); ++k) {
      const std::string what = std::to_string(nx) + "x" + std::to_string(ny) + " case " +
                               std::to_string(k);
      std::vector<Vec2> expected = x0, actual = x0;
      EXPECT_EQ(PlainFindNodeInsideDisc(cases[k], expected, 1e-6),
                FindNodeInsideDisc(cases[k], actual, 1e-6))
          << what;
      EXPECT_EQ(PlainProjectOutOfDiscs(cases[k], w, expected),
                ProjectOutOfDiscs(cases[k], w, actual))
          << what;
      ExpectSameBits(expected, actual, what);
      for (const double tolerance : {1e-6, 0.0, 5.0}) {
        EXPECT_EQ(PlainFindNodeInsideDisc(cases[k], expected, tolerance),
                  FindNodeInsideDisc(cases[k], actual, tolerance))
            << what << " tolerance " << tolerance;
      }
    }
  }
}

TEST(Constraints, BoxWithinIsFalseOnlyForSegmentsBeyondTheDistance) {
  // The prefilter of the edge contacts: false must mean that every point of
  // the segment lies farther than the distance (checked on the nearest
  // point), and it must skip far segments (not answer true always).
  std::mt19937_64 rng(808);
  std::uniform_real_distribution<double> coordinate(-50.0, 50.0), length(0.0, 30.0);
  int skipped = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec2 a(coordinate(rng), coordinate(rng));
    const Vec2 b = a + Vec2(length(rng) - 15.0, length(rng) - 15.0);
    const Vec2 p(coordinate(rng), coordinate(rng));
    const double distance = length(rng);
    if (BoxWithin(a, b, p, distance)) continue;
    ++skipped;
    const Vec2 e = b - a;
    const double t = e.squaredNorm() > 0.0 ? std::clamp((p - a).dot(e) / e.squaredNorm(), 0.0, 1.0)
                                           : 0.0;
    ASSERT_GT((a + t * e - p).norm(), distance) << "trial " << trial;
  }
  EXPECT_GT(skipped, 10000);
  // A segment through the point is never skipped, at any distance.
  EXPECT_TRUE(BoxWithin(Vec2(-1.0, 0.0), Vec2(1.0, 0.0), Vec2(0.0, 0.0), 0.0));
}

}  // namespace
}  // namespace calib
