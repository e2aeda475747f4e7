#include "calib/core/mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {
namespace {

// Unit square split along its diagonal, both triangles given clockwise in the
// math sense (negative SignedArea) so BuildMesh has to flip them.
Mesh TwoTriangleSquare(double scale = 1.0) {
  return BuildMesh({Vec2(0, 0) * scale, Vec2(1, 0) * scale, Vec2(1, 1) * scale,
                    Vec2(0, 1) * scale},
                   {{0, 2, 1}, {0, 3, 2}});
}

TEST(BuildMesh, OrientsEveryTrianglePositively) {
  const Mesh mesh = BuildMesh({Vec2(0, 0), Vec2(0, 1), Vec2(1, 0)}, {{0, 1, 2}});
  ASSERT_EQ(mesh.NumTriangles(), 1);
  const auto& t = mesh.triangles[0];
  const auto& p = mesh.rest_positions;
  EXPECT_GT(SignedArea(p[t[0]], p[t[1]], p[t[2]]), 0.0);
  EXPECT_NEAR(mesh.rest_area_px2[0], 0.5, 1e-15);
  for (const Mesh& m : {TwoTriangleSquare(), TwoTriangleSquare(1e-8), TwoTriangleSquare(1e8)}) {
    for (int i = 0; i < m.NumTriangles(); ++i) {
      EXPECT_GT(m.rest_area_px2[i], 0.0) << "triangle " << i;
    }
  }
}

TEST(AreaCentroid, IsTheCentroidOfTheCoveredAreaAtAnyPositions) {
  // An L of three unit squares: its centroid is (5/6, 5/6), not the mean of
  // its nodes.
  const Mesh mesh = BuildMesh({Vec2(0, 0), Vec2(1, 0), Vec2(2, 0), Vec2(0, 1), Vec2(1, 1),
                               Vec2(2, 1), Vec2(0, 2), Vec2(1, 2)},
                              {{0, 1, 4}, {0, 4, 3}, {1, 2, 5}, {1, 5, 4}, {3, 4, 7}, {3, 7, 6}});
  const Vec2 c = AreaCentroid(mesh, mesh.rest_positions);
  EXPECT_NEAR(c.x(), 5.0 / 6.0, 1e-15);
  EXPECT_NEAR(c.y(), 5.0 / 6.0, 1e-15);
  // Moved rigidly, it moves with the mesh.
  std::vector<Vec2> moved = mesh.rest_positions;
  for (Vec2& p : moved) p += Vec2(10, -3);
  EXPECT_NEAR((AreaCentroid(mesh, moved) - (c + Vec2(10, -3))).norm(), 0.0, 1e-13);
  // Collapsed to a point: no area, no centroid.
  const std::vector<Vec2> collapsed(mesh.NumNodes(), Vec2(4, 4));
  EXPECT_TRUE(std::isnan(AreaCentroid(mesh, collapsed).x()));
}

TEST(BuildMesh, EdgesAreUniqueSortedPairs) {
  const Mesh mesh = TwoTriangleSquare();
  ASSERT_EQ(mesh.NumEdges(), 5);  // 4 sides and the diagonal
  std::set<std::array<int, 2>> seen;
  for (int e = 0; e < mesh.NumEdges(); ++e) {
    const auto& edge = mesh.edges[e];
    EXPECT_LT(edge[0], edge[1]) << "edge " << e;
    EXPECT_TRUE(seen.insert(edge).second) << "edge " << e << " repeats";
    if (e > 0) {
      EXPECT_LT(mesh.edges[e - 1], edge) << "edges not sorted at " << e;
    }
    const double expected = (mesh.rest_positions[edge[1]] - mesh.rest_positions[edge[0]]).norm();
    EXPECT_DOUBLE_EQ(mesh.rest_length_px[e], expected) << "edge " << e;
  }
  EXPECT_TRUE(seen.count({0, 2})) << "the diagonal is missing";
}

TEST(BuildMesh, BoundaryLoopOfSquareIsClosedAndOrientedLikeTheTriangles) {
  const Mesh mesh = TwoTriangleSquare();
  ASSERT_EQ(mesh.boundary_loops.size(), 1u);
  const auto& loop = mesh.boundary_loops[0];
  ASSERT_EQ(loop.size(), 4u);
  EXPECT_EQ(std::set<int>(loop.begin(), loop.end()), (std::set<int>{0, 1, 2, 3}));
  // Each consecutive pair, the last back to the first, is an edge run in the
  // same direction as in its (positive) triangle.
  for (size_t k = 0; k < loop.size(); ++k) {
    const int a = loop[k], b = loop[(k + 1) % loop.size()];
    bool found = false;
    for (const auto& t : mesh.triangles) {
      for (int c = 0; c < 3; ++c) found |= t[c] == a && t[(c + 1) % 3] == b;
    }
    EXPECT_TRUE(found) << "loop step " << a << " -> " << b << " is not a triangle side";
  }
  double twice_area = 0.0;
  for (size_t k = 0; k < loop.size(); ++k) {
    twice_area += Cross(mesh.rest_positions[loop[k]],
                        mesh.rest_positions[loop[(k + 1) % loop.size()]]);
  }
  EXPECT_NEAR(0.5 * twice_area, 1.0, 1e-15) << "loop should enclose +1 like positive triangles";
}

TEST(BuildMesh, HoleGivesASecondLoopOfOppositeOrientation) {
  // A 3x3 grid of unit squares without the middle one.
  std::vector<Vec2> p;
  for (int y = 0; y <= 3; ++y) {
    for (int x = 0; x <= 3; ++x) p.emplace_back(x, y);
  }
  std::vector<std::array<int, 3>> tris;
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 3; ++x) {
      if (x == 1 && y == 1) continue;
      const int a = 4 * y + x;
      tris.push_back({a, a + 1, a + 5});
      tris.push_back({a, a + 5, a + 4});
    }
  }
  const Mesh mesh = BuildMesh(p, tris);
  ASSERT_EQ(mesh.boundary_loops.size(), 2u);
  EXPECT_EQ(mesh.boundary_loops[0].size(), 12u) << "outer loop first";
  EXPECT_EQ(mesh.boundary_loops[1].size(), 4u);
}

TEST(BuildMesh, RestAnglesOfEachTriangleSumToPi) {
  const Mesh mesh = BuildMesh({Vec2(0, 0), Vec2(3, 0.5), Vec2(1, 2), Vec2(4, 3)},
                              {{0, 1, 2}, {1, 3, 2}});
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto& a = mesh.rest_angle_rad[t];
    EXPECT_NEAR(a[0] + a[1] + a[2], std::numbers::pi, 1e-12) << "triangle " << t;
    for (int k = 0; k < 3; ++k) {
      EXPECT_GT(a[k], 0.0) << "triangle " << t << " corner " << k;
      EXPECT_LT(a[k], std::numbers::pi) << "triangle " << t << " corner " << k;
    }
  }
  // Corner 0 of the right triangle (0,0), (1,0), (0,1) is the right angle.
  const Mesh right = BuildMesh({Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)}, {{0, 1, 2}});
  EXPECT_NEAR(right.rest_angle_rad[0][0], std::numbers::pi / 2, 1e-15);
  EXPECT_NEAR(right.rest_angle_rad[0][1], std::numbers::pi / 4, 1e-15);
}

TEST(BuildMesh, DegenerateTriangleThrowsNamingItsIndex) {
  const std::vector<Vec2> p = {Vec2(0, 0), Vec2(1, 0), Vec2(0, 1), Vec2(2, 0)};
  try {
    BuildMesh(p, {{0, 1, 2}, {0, 1, 3}});  // triangle 1 is collinear
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 1"), std::string::npos) << e.what();
  }
  try {
    BuildMesh(p, {{0, 1, 2}, {0, 0, 2}});  // repeated node
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 1"), std::string::npos) << e.what();
  }
}

TEST(BuildMesh, OutOfRangeIndexThrowsNamingTheTriangle) {
  try {
    BuildMesh({Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)}, {{0, 1, 2}, {0, 2, 3}});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("triangle 1"), std::string::npos) << what;
    EXPECT_NE(what.find("3"), std::string::npos) << what;
  }
  EXPECT_THROW(BuildMesh({Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)}, {{-1, 1, 2}}),
               std::invalid_argument);
}

TEST(MeasureQuality, EquilateralPairHasSixtyDegreesEverywhere) {
  const double h = std::sqrt(3.0) / 2.0;
  const Mesh mesh = BuildMesh({Vec2(0, 0), Vec2(1, 0), Vec2(0.5, h), Vec2(1.5, h)},
                              {{0, 1, 2}, {1, 3, 2}});
  const MeshQuality q = MeasureQuality(mesh);
  EXPECT_EQ(q.num_nodes, 4);
  EXPECT_EQ(q.num_triangles, 2);
  EXPECT_NEAR(q.min_angle_deg, 60.0, 1e-9);
  EXPECT_NEAR(q.max_angle_deg, 60.0, 1e-9);
  EXPECT_NEAR(q.worst_radius_ratio, 1.0, 1e-12);
  EXPECT_NEAR(q.mean_edge_px, 1.0, 1e-12);
  EXPECT_NEAR(q.min_edge_px, 1.0, 1e-12);
  EXPECT_NEAR(q.max_edge_px, 1.0, 1e-12);
  EXPECT_NEAR(q.area_px2, 2.0 * std::sqrt(3.0) / 4.0, 1e-12);
  const std::string report = q.BriefReport();
  EXPECT_EQ(report.find('\n'), std::string::npos) << report;
  EXPECT_NE(report.find("4 nodes"), std::string::npos) << report;
}

TEST(MeasureQuality, RightIsoscelesTriangle) {
  const MeshQuality q = MeasureQuality(BuildMesh({Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)}, {{0, 1, 2}}));
  EXPECT_NEAR(q.min_angle_deg, 45.0, 1e-9);
  EXPECT_NEAR(q.max_angle_deg, 90.0, 1e-9);
  // R = sqrt(2)/2, r = (2 - sqrt(2))/2: R / (2r) = (1 + sqrt(2)) / 2.
  EXPECT_NEAR(q.worst_radius_ratio, (1.0 + std::sqrt(2.0)) / 2.0, 1e-12);
}

}  // namespace
}  // namespace calib
