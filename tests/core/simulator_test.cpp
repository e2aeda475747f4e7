// The model summed over a mesh, the constraints and the simulator: gradient
// check of the assembled forces, rest and rigid-motion invariants, obstacle
// and clamp constraints after every substep, inversion repair, failure as a
// status, determinism, and the external push with its translation share.

#include "calib/core/constraints.h"
#include "calib/core/energy_terms.h"
#include "calib/core/simulator.h"

#include "support/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace calib {
namespace {

using calib::testing::MakeGridMesh;
using calib::testing::OneDiscScene;
using calib::testing::StillScene;

ModelParameters StiffParameters() { return calib::testing::StiffTestParameters(); }

std::vector<Vec2> Perturbed(const Mesh& mesh, double amount, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<Vec2> x = mesh.rest_positions;
  for (Vec2& p : x) p += Vec2(u(rng), u(rng));
  return x;
}

TEST(Model, AssembledForcesAreNegativeGradientOfEnergy) {
  const Mesh mesh = MakeGridMesh(4, 3, 10.0);
  const Model model(mesh);
  ModelParameters p = StiffParameters();
  p.k_damping = 0.0;
  const auto x = Perturbed(mesh, 2.0, 1);
  std::vector<Vec2> v(x.size(), Vec2::Zero()), f(x.size());
  model.ComputeForces(p, x, v, f);
  double worst = 0.0, max_f = 0.0;
  for (const Vec2& fi : f) max_f = std::max(max_f, fi.cwiseAbs().maxCoeff());
  const double h = 1e-6;
  for (size_t i = 0; i < x.size(); ++i) {
    for (int d = 0; d < 2; ++d) {
      auto plus = x, minus = x;
      plus[i][d] += h;
      minus[i][d] -= h;
      const double numeric = -(model.Energy(p, plus) - model.Energy(p, minus)) / (2 * h);
      worst = std::max(worst, std::abs(numeric - f[i][d]) / max_f);
    }
  }
  EXPECT_LT(worst, 1e-6);
}

// The model's optimised sums against the reference kernels of
// energy_terms.h, term by term, on a deformed mesh with damping.
TEST(Model, SumsMatchTheReferenceKernels) {
  const Mesh mesh = MakeGridMesh(6, 4, 10.0, Vec2(5, 7));
  const Model model(mesh);
  const ModelParameters p = StiffParameters();
  const auto x = Perturbed(mesh, 3.0, 11);
  const auto v = Perturbed(mesh, 0.0, 0);  // rest positions as arbitrary velocities
  std::vector<Vec2> f(x.size()), ref(x.size(), Vec2::Zero());
  const double energy = model.ComputeForces(p, x, v, f);
  double ref_energy = 0.0;
  for (int e = 0; e < mesh.NumEdges(); ++e) {
    const auto [i, j] = mesh.edges[e];
    ref_energy += DistanceEnergy(x[i], x[j], mesh.rest_length_px[e], p.k_distance, ref[i], ref[j]);
    DistanceDamping(x[i], x[j], v[i], v[j], mesh.rest_length_px[e], p.k_damping, ref[i], ref[j]);
  }
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    ref_energy += AreaEnergy(x[a], x[b], x[c], mesh.rest_area_px2[t], p.k_area, ref[a], ref[b],
                             ref[c]);
    std::array<double, 6> cs;
    for (int k = 0; k < 3; ++k) {
      cs[2 * k] = std::cos(mesh.rest_angle_rad[t][k]);
      cs[2 * k + 1] = std::sin(mesh.rest_angle_rad[t][k]);
    }
    ref_energy += TriangleAngleEnergy(x[a], x[b], x[c], cs, p.k_angle, ref[a], ref[b], ref[c]);
  }
  EXPECT_NEAR(energy, ref_energy, 1e-12 * ref_energy);
  double max_f = 0.0;
  for (const Vec2& r : ref) max_f = std::max(max_f, r.norm());
  for (size_t i = 0; i < x.size(); ++i) {
    EXPECT_LT((f[i] - ref[i]).norm(), 1e-12 * max_f) << "node " << i;
  }
}

TEST(Model, ZeroForceAtRestAndRigidMotionKeepsEnergy) {
  const Mesh mesh = MakeGridMesh(5, 4, 12.0, Vec2(30, 40));
  const Model model(mesh);
  const ModelParameters p = StiffParameters();
  std::vector<Vec2> v(mesh.NumNodes(), Vec2::Zero()), f(mesh.NumNodes());
  EXPECT_NEAR(model.ComputeForces(p, mesh.rest_positions, v, f), 0.0, 1e-20);
  for (const Vec2& fi : f) EXPECT_LT(fi.norm(), 1e-10);

  auto x = Perturbed(mesh, 1.5, 2);
  const double e = model.Energy(p, x);
  const double c = std::cos(1.1), s = std::sin(1.1);
  for (Vec2& q : x) q = Vec2(c * q.x() - s * q.y(), s * q.x() + c * q.y()) + Vec2(-7.5, 300.25);
  EXPECT_NEAR(model.Energy(p, x), e, 1e-9 * std::max(1.0, e));
}

TEST(Simulator, RestStaysAtRest) {
  const Mesh mesh = MakeGridMesh(4, 2, 10.0);
  const Scene scene = StillScene(20);
  Simulator sim(mesh, scene, {});
  sim.Reset(StiffParameters());
  while (sim.Advance()) {
  }
  EXPECT_EQ(sim.status(), SimulationStatus::kFinished);
  EXPECT_EQ(sim.frame(), 19);
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    EXPECT_LT((sim.positions()[i] - mesh.rest_positions[i]).norm(), 1e-12);
  }
}

// A disc pushed into the side of a free 10 x 4 patch, with the measured force.
Scene PushScene(const Mesh& mesh, int frames) {
  Scene scene = StillScene(frames);
  scene.num_obstacles = 2;
  scene.force_obstacle = 0;
  double y_mid = 0.0, x_min = 1e9, x_max = -1e9;
  for (const Vec2& p : mesh.rest_positions) {
    y_mid += p.y() / mesh.NumNodes();
    x_min = std::min(x_min, p.x());
    x_max = std::max(x_max, p.x());
  }
  for (int f = 0; f < frames; ++f) {
    const double depth = std::min(1.0, f / (0.6 * frames)) * 25.0;
    scene.obstacle_discs.push_back({Vec2(x_min - 8.0 + depth, y_mid), 8.0});  // finger
    scene.obstacle_discs.push_back({Vec2(x_max + 6.0, y_mid), 6.0});          // pencil
    scene.forces.push_back(Vec2(depth > 0 ? 2.0 : 0.0, 0.0));
  }
  return scene;
}

TEST(Simulator, NoObstacleIsPenetratedAfterAnySubstep) {
  const Mesh mesh = MakeGridMesh(10, 4, 10.0, Vec2(100, 100));
  const Scene scene = PushScene(mesh, 40);
  Simulator sim(mesh, scene, {});
  sim.Reset(StiffParameters());
  int substeps = 0;
  double max_move = 0.0;
  const auto check = [&](int s) {
    ++substeps;
    ASSERT_EQ(FindNodeInsideDisc(sim.obstacles(), sim.positions(), 1e-9), -1)
        << "frame " << sim.frame() << " substep " << s;
    ASSERT_EQ(FindInvertedTriangle(mesh, sim.positions()), -1);
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      max_move = std::max(max_move, (sim.positions()[i] - mesh.rest_positions[i]).norm());
    }
  };
  while (sim.Advance(check)) {
  }
  EXPECT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
  EXPECT_EQ(substeps, 39 * 10);
  EXPECT_GT(max_move, 5.0) << "the finger should have moved the patch";
}

TEST(Simulator, ClampedNodesNeverMove) {
  const Mesh mesh = MakeGridMesh(6, 6, 10.0, Vec2(50, 0));
  Scene scene = PushScene(mesh, 30);
  scene.clamps.push_back({50.0 - 1, -1.0, 62.0, 3.0});  // top row of nodes
  Simulator sim(mesh, scene, {});
  int clamped = 0;
  for (uint8_t c : sim.clamped()) clamped += c;
  ASSERT_EQ(clamped, 7);
  sim.Reset(StiffParameters());
  double max_free_move = 0.0;
  while (sim.Advance()) {
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      const double move = (sim.positions()[i] - mesh.rest_positions[i]).norm();
      if (sim.clamped()[i]) {
        ASSERT_EQ(move, 0.0) << "clamped node " << i << " moved at frame " << sim.frame();
      } else {
        max_free_move = std::max(max_free_move, move);
      }
    }
  }
  EXPECT_GT(max_free_move, 1.0);
}

TEST(Constraints, InvertedTriangleIsRepaired) {
  const Mesh mesh = MakeGridMesh(2, 2, 10.0);
  std::vector<Vec2> x = mesh.rest_positions;
  // Drag the centre node far across its neighbours: several triangles invert.
  x[4] += Vec2(14.0, 13.0);
  ASSERT_NE(FindInvertedTriangle(mesh, x), -1);
  std::vector<double> w(x.size(), 1.0);
  int rounds = 0;
  while (RepairInvertedTriangles(mesh, 0.05, w, x) > 0) {
    ASSERT_LT(++rounds, 50) << "repair does not converge";
  }
  EXPECT_EQ(FindInvertedTriangle(mesh, x), -1);
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    EXPECT_GE(SignedArea(x[a], x[b], x[c]), 0.05 * mesh.rest_area_px2[t]) << "triangle " << t;
  }
}

TEST(Constraints, RepairDoesNotMoveFixedNodes) {
  const Mesh mesh = MakeGridMesh(1, 1, 10.0);
  std::vector<Vec2> x = mesh.rest_positions;
  x[3] = Vec2(5.0, -5.0);  // fold the far corner across
  std::vector<double> w = {0.0, 0.0, 1.0, 1.0};
  const std::vector<Vec2> before = x;
  for (int iter = 0; iter < 20; ++iter) RepairInvertedTriangles(mesh, 0.05, w, x);
  EXPECT_EQ(x[0], before[0]);
  EXPECT_EQ(x[1], before[1]);
  EXPECT_EQ(FindInvertedTriangle(mesh, x), -1);
}

TEST(Simulator, BlowUpEndsFailedWithReasonAndFrame) {
  const Mesh mesh = MakeGridMesh(6, 3, 10.0, Vec2(100, 100));
  const Scene scene = PushScene(mesh, 30);
  ModelParameters p = StiffParameters();
  p.k_distance = 1e9;  // far beyond the explicit step's stability limit
  p.mass = 1e-6;
  Simulator sim(mesh, scene, {});
  sim.Reset(p);
  while (sim.Advance()) {
  }
  ASSERT_EQ(sim.status(), SimulationStatus::kFailed);
  EXPECT_FALSE(sim.failure_reason().empty());
  EXPECT_GE(sim.failure_frame(), 1);
  EXPECT_LT(sim.failure_frame(), scene.num_frames);
  // A failed simulator stays failed and can be reset for the next candidate.
  EXPECT_FALSE(sim.Advance());
  sim.Reset(StiffParameters());
  while (sim.Advance()) {
  }
  EXPECT_EQ(sim.status(), SimulationStatus::kFinished);
}

TEST(Simulator, IdenticalInputGivesBitIdenticalStates) {
  const Mesh mesh = MakeGridMesh(8, 4, 10.0, Vec2(100, 100));
  const Scene scene = PushScene(mesh, 25);
  auto run = [&] {
    Simulator sim(mesh, scene, {});
    sim.Reset(StiffParameters());
    while (sim.Advance()) {
    }
    return sim.positions();
  };
  const auto a = run();
  const auto b = run();
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].x(), b[i].x());
    EXPECT_EQ(a[i].y(), b[i].y());
  }
}

// A free patch under a uniform push (tau = 1, far finger): first order moves
// it at the constant speed F / (N m); Verlet accelerates it at F / (N m).
TEST(Simulator, TranslationShareMovesTheWholeBody) {
  const Mesh mesh = MakeGridMesh(3, 2, 10.0, Vec2(100, 100));
  const Scene scene = OneDiscScene(
      11, 10.0, [](int) { return Disc{Vec2(0, 0), 1.0}; }, [](int) { return Vec2(3.0, -1.5); });
  ModelParameters p = StiffParameters();
  p.translation = 1.0;
  p.mass = 0.2;
  const double n = mesh.NumNodes();
  const Vec2 accel = Vec2(3.0, -1.5) / (n * p.mass);
  const double duration = (scene.num_frames - 1) * scene.frame_time_s;

  SimulationOptions first;
  Simulator sim(mesh, scene, first);
  sim.Reset(p);
  while (sim.Advance()) {
  }
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    const Vec2 moved = sim.positions()[i] - mesh.rest_positions[i];
    EXPECT_LT((moved - accel * duration).norm(), 1e-9) << "node " << i;
  }

  SimulationOptions verlet;
  verlet.integrator = IntegratorKind::kVerlet;
  Simulator sim2(mesh, scene, verlet);
  sim2.Reset(p);
  while (sim2.Advance()) {
  }
  // Position Verlet from rest: x_k = x_0 + a h^2 k (k + 1) / 2.
  const double h = scene.frame_time_s / verlet.substeps;
  const double k = (scene.num_frames - 1) * verlet.substeps;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    const Vec2 moved = sim2.positions()[i] - mesh.rest_positions[i];
    EXPECT_LT((moved - accel * h * h * k * (k + 1) / 2).norm(), 1e-9) << "node " << i;
  }
}

TEST(Simulator, PushWithoutTranslationActsOnTheNearestNode) {
  const Mesh mesh = MakeGridMesh(4, 4, 10.0, Vec2(100, 100));
  // Finger just off the top-left corner (node 0); it does not touch the mesh.
  const Scene scene = OneDiscScene(
      2, 30.0, [](int) { return Disc{Vec2(95, 95), 2.0}; }, [](int) { return Vec2(1.0, 0.0); });
  ModelParameters p = StiffParameters();
  p.k_damping = 0.0;
  SimulationOptions options;
  options.substeps = 1;
  Simulator sim(mesh, scene, options);
  sim.Reset(p);
  ASSERT_TRUE(sim.Advance());
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    const double moved = (sim.positions()[i] - mesh.rest_positions[i]).norm();
    if (i == 0) {
      EXPECT_NEAR(moved, scene.frame_time_s / p.mass, 1e-12);
    } else {
      EXPECT_EQ(moved, 0.0) << "node " << i;
    }
  }
}

TEST(SimulationOptions, InvalidFieldIsNamed) {
  SimulationOptions o;
  std::string error;
  EXPECT_TRUE(o.IsValid(&error));
  o.substeps = 0;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_EQ(error, "SimulationOptions::substeps = 0. Violated: substeps >= 1.");
  o = {};
  o.min_area_fraction = 1.5;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("min_area_fraction = 1.5"), std::string::npos) << error;
}

TEST(Integrator, NamesRoundTripAndUnknownIsNamed) {
  for (auto kind : {IntegratorKind::kFirstOrder, IntegratorKind::kVerlet,
                    IntegratorKind::kImplicitFirstOrder}) {
    EXPECT_EQ(IntegratorKindFromString(ToString(kind)), kind);
  }
  try {
    IntegratorKindFromString("rk4");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'rk4'"), std::string::npos);
  }
}

}  // namespace
}  // namespace calib
