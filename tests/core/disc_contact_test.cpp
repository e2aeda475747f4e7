// Obstacle discs against the mesh's boundary edges (ProjectBoundaryOutOfDiscs):
// a disc narrower than the mesh's edges may not slip between two boundary
// nodes and poke through the outline.

#include "calib/core/constraints.h"
#include "calib/core/simulator.h"

#include "support/test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace calib {
namespace {

using calib::testing::MakeGridMesh;

double SegmentDistance(const Vec2& a, const Vec2& b, const Vec2& p) {
  const Vec2 e = b - a;
  const double t = std::clamp((p - a).dot(e) / e.squaredNorm(), 0.0, 1.0);
  return (a + t * e - p).norm();
}

// The smallest distance from a disc's centre to a boundary edge, minus its radius
// (negative: the disc pokes through the outline).
double Clearance(const Mesh& mesh, const Disc& disc, const std::vector<Vec2>& x) {
  double clearance = std::numeric_limits<double>::infinity();
  for (const std::vector<int>& loop : mesh.boundary_loops) {
    for (size_t k = 0; k < loop.size(); ++k) {
      const int a = loop[k], b = loop[(k + 1) % loop.size()];
      clearance = std::min(clearance, SegmentDistance(x[a], x[b], disc.centre) - disc.radius_px);
    }
  }
  return clearance;
}

// One 20 px square (nodes (0,0), (20,0), (0,20), (20,20)); the edge y = 0 is on
// its outline, the object below it (larger y).
Mesh Square() { return MakeGridMesh(2, 2, 20.0); }

int NodeAt(const Mesh& mesh, double x, double y) {
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    if ((mesh.rest_positions[i] - Vec2(x, y)).norm() < 1e-12) return i;
  }
  return -1;
}

TEST(DiscContact, PushesAnEdgeOffADiscBetweenItsNodes) {
  const Mesh mesh = Square();
  const std::vector<Disc> discs = {{Vec2(5.0, -2.0), 3.0}};  // 1 px into the edge y = 0
  std::vector<Vec2> x = mesh.rest_positions;
  const std::vector<double> w(mesh.NumNodes(), 1.0);
  // No node is inside the disc: the node projection alone leaves it poking through.
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, x), 0);
  EXPECT_LT(Clearance(mesh, discs[0], x), -0.99);

  EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x), 1);
  // The contact point lies at a quarter of the edge: the nearer node takes
  // three times the move of the farther one, both along the normal (+y),
  // and the point at that quarter lands on the circle.
  const int a = NodeAt(mesh, 0, 0), b = NodeAt(mesh, 20, 0);
  ASSERT_GE(a, 0);
  ASSERT_GE(b, 0);
  EXPECT_NEAR(x[a].x(), 0.0, 1e-12);
  EXPECT_NEAR(x[b].x(), 20.0, 1e-12);
  EXPECT_NEAR(x[a].y(), 3.0 * x[b].y(), 1e-12);
  EXPECT_NEAR((0.75 * x[a] + 0.25 * x[b] - discs[0].centre).norm(), 3.0, 1e-12);
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    if (i != a && i != b) {
      EXPECT_EQ(x[i], mesh.rest_positions[i]) << "node " << i;
    }
  }
  // The edge tilted, so its nearest point is a little inside still; a few
  // more rounds bring the outline within the tolerance of the circle and
  // then move nothing.
  EXPECT_LT(Clearance(mesh, discs[0], x), 0.0);
  int rounds = 0;
  while (ProjectBoundaryOutOfDiscs(mesh, discs, w, x) > 0 && rounds < 50) ++rounds;
  EXPECT_LT(rounds, 3);
  EXPECT_GT(Clearance(mesh, discs[0], x), -kEdgeContactTolerancePx);
  EXPECT_LT(Clearance(mesh, discs[0], x), 0.0);
}

TEST(DiscContact, AClampedEndStaysAndTheOtherTakesTheWholeMove) {
  const Mesh mesh = Square();
  const std::vector<Disc> discs = {{Vec2(10.0, -2.0), 3.0}};
  std::vector<Vec2> x = mesh.rest_positions;
  std::vector<double> w(mesh.NumNodes(), 1.0);
  const int a = NodeAt(mesh, 0, 0), b = NodeAt(mesh, 20, 0);
  w[a] = 0.0;
  EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x), 1);
  EXPECT_NEAR(x[b].y(), 2.0, 1e-12);  // the midpoint moves 1 px: the free end 2 px
  for (int round = 0; round < 50; ++round) ProjectBoundaryOutOfDiscs(mesh, discs, w, x);
  EXPECT_EQ(x[a], mesh.rest_positions[a]);
  EXPECT_GT(Clearance(mesh, discs[0], x), -kEdgeContactTolerancePx);
  // Both ends clamped: nothing can move.
  w[b] = 0.0;
  x = mesh.rest_positions;
  EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x), 0);
  EXPECT_EQ(x, mesh.rest_positions);
}

TEST(DiscContact, PutsADiscWhoseCentreGotInsideBackOut) {
  const Mesh mesh = Square();
  const std::vector<double> w(mesh.NumNodes(), 1.0);
  const std::vector<Disc> discs = {{Vec2(10.0, 1.0), 3.0}};  // 1 px past the edge y = 0
  std::vector<Vec2> x = mesh.rest_positions;
  EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x), 1);
  // The edge went past the centre, to the circle's far side: the disc is
  // outside the object again, touching it.
  const int a = NodeAt(mesh, 0, 0), b = NodeAt(mesh, 20, 0);
  EXPECT_NEAR(x[a].y(), 4.0, 1e-12);
  EXPECT_NEAR(x[b].y(), 4.0, 1e-12);
  EXPECT_NEAR(Clearance(mesh, discs[0], x), 0.0, 1e-12);
  EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x), 0);
}

TEST(DiscContact, LeavesDiscsClearOfEdgesOrNearestAnEndToTheNodes) {
  const Mesh mesh = Square();
  const std::vector<double> w(mesh.NumNodes(), 1.0);
  for (const Disc& disc : {Disc{Vec2(10.0, 10.0), 3.0},     // inside, touching no edge
                           Disc{Vec2(-1.0, -1.0), 3.0},     // nearest a corner node
                           Disc{Vec2(10.0, -3.0), 3.0},     // touching, not inside
                           Disc{Vec2(10.0, -2.995), 3.0}}) {  // inside within the tolerance
    std::vector<Vec2> x = mesh.rest_positions;
    EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, {&disc, 1}, w, x), 0)
        << disc.centre.transpose() << " r " << disc.radius_px;
    EXPECT_EQ(x, mesh.rest_positions);
  }
}

// Steps longer than a disc's radius (stiff springs with the implicit step
// move a node 10-20 px in one substep): the projections resolve a contact
// back to the side the node or the edge came from, where the nearest way out
// of the disc at the end of the step is its far side.

TEST(DiscContact, ANodeCarriedPastTheCentreGoesBackTheWayItCame) {
  const std::vector<Disc> discs = {{Vec2(10.0, 10.0), 4.0}};
  const std::vector<double> w = {1.0};
  const std::vector<Vec2> start_x = {Vec2(10.0, 4.0)};  // 6 px above the centre
  const SubstepStart start{start_x, discs};
  std::vector<Vec2> radial = {Vec2(10.5, 12.0)};  // 2 px past the centre
  std::vector<Vec2> sided = radial;
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, radial), 1);
  EXPECT_GT(radial[0].y(), 10.0);  // without the start: out of the far side
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, sided, start), 1);
  // Back above the disc, on the tangent at the side it came from, the
  // sideways offset kept.
  EXPECT_NEAR(sided[0].x(), 10.5, 1e-12);
  EXPECT_NEAR(sided[0].y(), 6.0, 1e-12);
  EXPECT_GE((sided[0] - discs[0].centre).norm(), 4.0);
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, sided, start), 0);

  // Exactly on the centre: the side it came from, not the default +x.
  std::vector<Vec2> centred = {discs[0].centre};
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, centred, start), 1);
  EXPECT_NEAR(centred[0].x(), 10.0, 1e-12);
  EXPECT_NEAR(centred[0].y(), 6.0, 1e-12);
}

TEST(DiscContact, ANodeShortOfTheCentreIsProjectedRadiallyAsWithoutTheStart) {
  const std::vector<Disc> discs = {{Vec2(10.0, 10.0), 4.0}};
  const std::vector<double> w = {1.0};
  const std::vector<Vec2> start_x = {Vec2(10.0, 4.0)};
  std::vector<Vec2> plain = {Vec2(11.0, 7.5)};  // 2.5 px short of the centre's level
  std::vector<Vec2> sided = plain;
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, plain), 1);
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, sided, SubstepStart{start_x, discs}), 1);
  EXPECT_EQ(plain, sided);
  EXPECT_NEAR((sided[0] - discs[0].centre).norm(), 4.0, 1e-12);
}

TEST(DiscContact, ADiscThatRanOverANodePushesItAhead) {
  // The disc moved 12 px right in the step, over a still node: relative to
  // the disc, the node came from the right, and stays ahead of the disc.
  const std::vector<Disc> start_discs = {{Vec2(0.0, 10.0), 4.0}};
  const std::vector<Disc> discs = {{Vec2(12.0, 10.0), 4.0}};
  const std::vector<double> w = {1.0};
  const std::vector<Vec2> start_x = {Vec2(10.0, 10.0)};
  std::vector<Vec2> x = start_x;
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, x, SubstepStart{start_x, start_discs}), 1);
  EXPECT_NEAR(x[0].x(), 16.0, 1e-12);
  EXPECT_NEAR(x[0].y(), 10.0, 1e-12);
}

TEST(DiscContact, AnEdgeThatSweptOverAWholeDiscIsPutBackInFrontOfIt) {
  const Mesh mesh = Square();
  const std::vector<double> w(mesh.NumNodes(), 1.0);
  // The disc 5 px above the edge y = 0, outside; in one step the square
  // moves 10 px up, its top edge 5 px past the centre, more than the radius.
  const std::vector<Disc> discs = {{Vec2(10.0, -5.0), 3.0}};
  const std::vector<Vec2> start_x = mesh.rest_positions;
  std::vector<Vec2> moved = mesh.rest_positions;
  for (Vec2& p : moved) p.y() -= 10.0;
  // From the end of the step alone the edge is too far past the disc to
  // tell it from an edge behind it: it is left alone, the disc inside.
  std::vector<Vec2> x = moved;
  EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x), 0);
  EXPECT_EQ(x, moved);
  // With the step's start, the edge goes back past the centre and touches
  // the disc from below, as before the step.
  x = moved;
  EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x, SubstepStart{start_x, discs}), 1);
  const int a = NodeAt(mesh, 0, 0), b = NodeAt(mesh, 20, 0);
  EXPECT_NEAR(x[a].y(), -2.0, 1e-12);
  EXPECT_NEAR(x[b].y(), -2.0, 1e-12);
  EXPECT_NEAR(Clearance(mesh, discs[0], x), 0.0, 1e-12);
  // An edge that had the centre behind it at the start (the square's
  // bottom, facing away) is not pulled through the disc.
  EXPECT_EQ(x[NodeAt(mesh, 0, 20)].y(), 10.0);
  EXPECT_EQ(x[NodeAt(mesh, 20, 20)].y(), 10.0);
}

// A finger narrower than the mesh's edges pushed 12 px into the middle of a
// side between two nodes: with outline contact the simulator keeps it out of
// the outline at every substep and it moves the patch; with the paper's
// node-only contact it pokes through.
double WorstClearance(bool outline_contact);

TEST(DiscContact, ANarrowFingerNeverPokesThroughTheOutline) {
  EXPECT_GT(WorstClearance(true), -kEdgeContactTolerancePx);
  EXPECT_LT(WorstClearance(false), -3.0);  // most of its 4 px radius
}

double WorstClearance(bool outline_contact) {
  const Mesh mesh = MakeGridMesh(6, 4, 20.0, Vec2(100, 100));  // sides 100 x 60
  // Radius 4 < half the 20 px spacing; enters the top side at x = 150, midway
  // between the nodes at 140 and 160, 12 px deep by the last frame.
  constexpr int kFrames = 30;
  const Scene scene = calib::testing::OneDiscScene(
      kFrames, 30.0,
      [](int f) { return Disc{Vec2(150.0, 100.0 - 4.0 + 12.0 * f / (kFrames - 1)), 4.0}; },
      [](int) { return Vec2::Zero(); });
  SimulationOptions options;
  options.outline_contact = outline_contact;
  Simulator sim(mesh, scene, options);
  sim.Reset(calib::testing::StiffTestParameters());
  double worst = std::numeric_limits<double>::infinity();
  const auto check = [&](int) {
    const std::vector<Vec2> x(sim.positions().begin(), sim.positions().end());
    worst = std::min(worst, Clearance(mesh, sim.obstacles()[0], x));
  };
  while (sim.Advance(check)) {
  }
  EXPECT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
  if (outline_contact) {
    // The top side's two nodes next to the finger went down with it.
    const std::vector<Vec2> x(sim.positions().begin(), sim.positions().end());
    EXPECT_GT(x[NodeAt(mesh, 140, 100)].y() + x[NodeAt(mesh, 160, 100)].y() - 200.0, 10.0);
  }
  return worst;
}

}  // namespace
}  // namespace calib

namespace calib {
namespace {

// Contact friction (SubstepStart::friction): position-based Coulomb
// friction between the discs and the object.

// The component of v across n (2D cross product).
double Across(const Vec2& v, const Vec2& n) { return v.x() * n.y() - v.y() * n.x(); }

TEST(ContactFriction, ANodeSlidingOnADiscSticksWithinTheLimitAndSlidesLessBeyond) {
  const std::vector<Disc> discs = {{Vec2(0.0, 0.0), 4.0}};
  const std::vector<double> w = {1.0};
  const std::vector<Vec2> start_x = {Vec2(0.0, -4.5)};  // above the disc
  const Vec2 end(1.0, -3.5);                             // 1 px along, 1 px down: inside
  const double dist = end.norm();
  const double depth = 4.0 - dist;
  const Vec2 normal = end / dist;
  // Frictionless: radially onto the circle, the slide along it kept.
  std::vector<Vec2> free_x = {end};
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, free_x, SubstepStart{start_x, discs, 0.0}), 1);
  const Vec2 free_slide = free_x[0] - start_x[0];
  const double free_tangent = std::abs(Across(free_slide, normal));
  ASSERT_GT(free_tangent, 0.5);
  // Strong friction: the slide along the surface is undone, only the push
  // along the normal is left; the node is outside the disc.
  std::vector<Vec2> stuck = {end};
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, stuck, SubstepStart{start_x, discs, 100.0}), 1);
  EXPECT_NEAR(Across(stuck[0] - start_x[0], normal), 0.0, 1e-12);
  EXPECT_GE(stuck[0].norm(), 4.0 - 1e-12);
  // Weak friction: the slide is shortened by friction x depth.
  const double mu = 0.5;
  std::vector<Vec2> slid = {end};
  EXPECT_EQ(ProjectOutOfDiscs(discs, w, slid, SubstepStart{start_x, discs, mu}), 1);
  EXPECT_NEAR(std::abs(Across(slid[0] - start_x[0], normal)), free_tangent - mu * depth, 1e-12);
  EXPECT_GE(slid[0].norm(), 4.0 - 1e-12);
}

TEST(ContactFriction, ADiscPressingANodeCarriesItAlong) {
  // The disc moves 1 px right and 1 px up into a node resting on its top.
  const std::vector<Disc> start_discs = {{Vec2(0.0, 0.0), 4.0}};
  const std::vector<Disc> discs = {{Vec2(1.0, -1.0), 4.0}};
  const std::vector<double> w = {1.0};
  const std::vector<Vec2> start_x = {Vec2(0.0, -4.0)};
  std::vector<Vec2> frictionless = start_x, gripped = start_x;
  ProjectOutOfDiscs(discs, w, frictionless, SubstepStart{start_x, start_discs, 0.0});
  ProjectOutOfDiscs(discs, w, gripped, SubstepStart{start_x, start_discs, 100.0});
  // Without friction the node is pushed up and to the left, off the disc's
  // top; gripped, it goes with the disc: against the disc it moved only
  // along the push, not along the surface.
  EXPECT_LT(frictionless[0].x(), 0.0);
  EXPECT_GT(gripped[0].x(), 0.9);
  const Vec2 normal = (start_x[0] - discs[0].centre).normalized();  // where it was pushed out
  const Vec2 against = gripped[0] - discs[0].centre;
  EXPECT_NEAR(Across(against - (start_x[0] - start_discs[0].centre), normal), 0.0, 1e-12);
  EXPECT_GE(against.norm(), 4.0);
}

TEST(ContactFriction, AnEdgeIsDraggedAlongByADiscSlidingOverIt) {
  const Mesh mesh = MakeGridMesh(2, 2, 20.0);
  const std::vector<double> w(mesh.NumNodes(), 1.0);
  const int a = NodeAt(mesh, 0, 0), b = NodeAt(mesh, 20, 0);
  // The disc slid 5 px along the edge y = 0 and pressed 1 px into it at its
  // middle.
  const std::vector<Disc> start_discs = {{Vec2(5.0, -3.0), 3.0}};
  const std::vector<Disc> discs = {{Vec2(10.0, -2.0), 3.0}};
  const std::vector<Vec2> start_x = mesh.rest_positions;
  for (double mu : {0.0, 2.0, 100.0}) {
    std::vector<Vec2> x = mesh.rest_positions;
    EXPECT_EQ(ProjectBoundaryOutOfDiscs(mesh, discs, w, x, SubstepStart{start_x, start_discs, mu}),
              1);
    // Pushed 1 px down as without friction; dragged along by friction x
    // depth (2 px at mu 2), at most the whole 5 px slide.
    const double drag = std::min(mu * 1.0, 5.0);
    EXPECT_NEAR(x[a].y(), 1.0, 1e-12) << "mu " << mu;
    EXPECT_NEAR(x[b].y(), 1.0, 1e-12) << "mu " << mu;
    EXPECT_NEAR(x[a].x(), 0.0 + drag, 1e-12) << "mu " << mu;
    EXPECT_NEAR(x[b].x(), 20.0 + drag, 1e-12) << "mu " << mu;
  }
}

TEST(ContactFriction, ANegativeOrNonFiniteCoefficientIsNamed) {
  for (double bad : {-0.1, std::numeric_limits<double>::infinity(), std::nan("")}) {
    SimulationOptions options;
    options.contact_friction = bad;
    std::string error;
    EXPECT_FALSE(options.IsValid(&error)) << bad;
    EXPECT_NE(error.find("contact_friction"), std::string::npos) << error;
  }
}

}  // namespace
}  // namespace calib
