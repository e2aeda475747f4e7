// Grid: coarse-to-fine order, every point once, prefixes spread over the box.
#include <set>

#include <gtest/gtest.h>

#include "harness.h"

namespace calib::search {
namespace {

std::vector<Candidate> AllPoints(const nlohmann::json& settings, const Bounds& box) {
  CheckedOptimizer grid = MakeOptimizer("grid", settings, box, 0);
  return testing::RunOptimizer(grid, testing::Sphere, 1000).asked;
}

TEST(Grid, VisitsEveryPointOnceIncludingTheBounds) {
  const auto points = AllPoints({{"resolution", {5, 4, 1}}}, {{0, -1, 2}, {4, 2, 3}});
  ASSERT_EQ(points.size(), 5u * 4u * 1u);
  std::set<std::vector<double>> unique;
  for (const auto& c : points) unique.insert(c.x);
  EXPECT_EQ(unique.size(), points.size()) << "a point was visited twice";
  EXPECT_TRUE(unique.count({0, -1, 2.5}) && unique.count({4, 2, 2.5}))
      << "the corners (bounds inclusive) are grid points; resolution 1 is the centre";
  EXPECT_TRUE(unique.count({1, 0, 2.5})) << "x = 1 and y = 0 are on the 5 x 4 grid";
}

TEST(Grid, VisitsCoarseToFineSoPrefixesAreCompleteCoarserGrids) {
  const auto points = AllPoints({{"resolution", 5}}, testing::Box(2, 0, 4));
  ASSERT_EQ(points.size(), 25u);
  EXPECT_EQ(points[0].x, (std::vector<double>{2, 2})) << "the centre comes first";
  // The first 9 points are exactly the 3 x 3 grid {0, 2, 4}^2.
  std::set<std::vector<double>> first9;
  for (int i = 0; i < 9; ++i) first9.insert(points[i].x);
  std::set<std::vector<double>> coarse;
  for (double a : {0, 2, 4}) {
    for (double b : {0, 2, 4}) coarse.insert({a, b});
  }
  EXPECT_EQ(first9, coarse);
}

TEST(Grid, MaxEvalsStopsEarly) {
  EXPECT_EQ(AllPoints({{"resolution", 9}, {"max_evals", 10}}, testing::Box(3, 0, 1)).size(), 10u);
}

TEST(Grid, HugeGridsAreEnumeratedLazily) {
  // 100^8 = 1e16 points: only the asked ones are ever built.
  CheckedOptimizer grid = MakeOptimizer("grid", {{"resolution", 100}}, testing::Box(8, 0, 1), 0);
  EXPECT_EQ(grid.Ask(50).size(), 50u);
}

}  // namespace
}  // namespace calib::search
