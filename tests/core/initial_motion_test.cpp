// A model with inertia starts a swinging clamped object from the motion the
// video shows (initial_motion.h): the springs rest at the estimated
// equilibrium, whose area-weighted mean offset from frame 0 is the observed
// one along the object's soft direction; the nodes start with the observed
// centroid velocity; the object then swings about that equilibrium. Without
// inertia, clamps or an observed motion, nothing changes, bit for bit.

#include <gtest/gtest.h>

#include <cmath>

#include "calib/core/initial_motion.h"
#include "calib/core/simulator.h"
#include "support/test_support.h"

namespace calib {
namespace {

using calib::testing::MakeGridMesh;

// A 20 x 100 px strip hanging from a clamp along its top edge.
Mesh StartingStrip() { return MakeGridMesh(2, 10, 10.0, Vec2(100, 100)); }

Scene SwingScene(int frames, const Vec2& offset, const Vec2& velocity) {
  Scene scene;
  scene.frame_time_s = 1.0 / 240.0;
  scene.num_frames = frames;
  scene.clamps.push_back({99.0, 99.0, 22.0, 2.0});
  scene.motion.known = true;
  scene.motion.equilibrium_offset_px = offset;
  scene.motion.initial_velocity_px_s = velocity;
  return scene;
}

ParameterValues InertiaValues(double damping_per_s) {
  ParameterValues values = calib::testing::StiffTestParameters().ToValues();
  values["inertia_damping_per_s"] = damping_per_s;
  values["gravity_px_s2"] = 0.0;
  values["gravity_angle_deg"] = 90.0;
  return values;
}

// Area-weighted mean of a node field (a third of each triangle per corner).
Vec2 AreaMean(const Mesh& mesh, std::span<const Vec2> field) {
  Vec2 sum = Vec2::Zero();
  double area = 0.0;
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    for (int corner : mesh.triangles[t]) sum += mesh.rest_area_px2[t] / 3.0 * field[corner];
    area += mesh.rest_area_px2[t];
  }
  return sum / area;
}

std::vector<Vec2> Difference(std::span<const Vec2> a, std::span<const Vec2> b) {
  std::vector<Vec2> d(a.size());
  for (size_t i = 0; i < a.size(); ++i) d[i] = a[i] - b[i];
  return d;
}

double MaxNorm(std::span<const Vec2> field) {
  double worst = 0.0;
  for (const Vec2& v : field) worst = std::max(worst, v.norm());
  return worst;
}

TEST(InitialMotion, RestsAtTheObservedEquilibriumAndStartsWithTheObservedVelocity) {
  const Mesh mesh = StartingStrip();
  const Scene scene = SwingScene(10, Vec2(6.0, 0.0), Vec2(-40.0, 0.0));
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  sim.Reset(InertiaValues(1.0));
  ASSERT_EQ(sim.status(), SimulationStatus::kRunning) << sim.failure_reason();

  // Frame 0 is the video's: the nodes start at the mesh.
  for (int i = 0; i < mesh.NumNodes(); ++i) EXPECT_EQ(sim.positions()[i], mesh.rest_positions[i]);

  const std::vector<Vec2> deflection = Difference(sim.rest_shape(), mesh.rest_positions);
  const Vec2 mean_offset = AreaMean(mesh, deflection);
  EXPECT_NEAR(mean_offset.x(), 6.0, 1e-6);
  const Vec2 mean_velocity = AreaMean(mesh, sim.initial_velocities());
  EXPECT_NEAR(mean_velocity.x(), -40.0, 1e-5);
  // The free end moves most; the clamped nodes neither move nor rest elsewhere.
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    if (sim.clamped()[i]) {
      EXPECT_EQ(deflection[i], Vec2::Zero());
      EXPECT_EQ(sim.initial_velocities()[i], Vec2::Zero());
    }
  }
  EXPECT_GT(deflection.back().x(), 6.0);

  // The springs rest at the equilibrium: no elastic force there, a restoring
  // force towards it at frame 0.
  std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero()), forces(mesh.NumNodes());
  const ModelParameters params = calib::testing::StiffTestParameters();
  sim.model().ComputeForces(params, sim.rest_shape(), zero, forces);
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    if (!sim.clamped()[i]) {
      EXPECT_LT(forces[i].norm(), 1e-9) << "node " << i;
    }
  }
  sim.model().ComputeForces(params, mesh.rest_positions, zero, forces);
  EXPECT_GT(AreaMean(mesh, forces).x(), 0.0);
}

TEST(InitialMotion, TheStiffDirectionIsNotExplainedByADeflection) {
  // Stretching a hanging strip along its length is stiff: a vertical centroid
  // offset is a swing's arc, so the rest stays (to rounding) at frame 0.
  const Mesh mesh = StartingStrip();
  const Scene scene = SwingScene(10, Vec2(0.0, 5.0), Vec2(0.0, 30.0));
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  sim.Reset(InertiaValues(1.0));
  ASSERT_EQ(sim.status(), SimulationStatus::kRunning) << sim.failure_reason();
  EXPECT_LT(MaxNorm(Difference(sim.rest_shape(), mesh.rest_positions)), 0.05);
  EXPECT_LT(MaxNorm(sim.initial_velocities()), 0.3);
}

TEST(InitialMotion, TheObjectSwingsAboutTheObservedEquilibrium) {
  const Mesh mesh = StartingStrip();
  const Scene scene = SwingScene(480, Vec2(4.0, 0.0), Vec2::Zero());
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  // Stiff enough to swing a few times in the 2 s of the scene.
  ParameterValues values = InertiaValues(0.5);
  for (const char* k : {"k_D", "k_A", "k_phi"}) values[k] *= 1e4;
  sim.Reset(values);
  const Vec2 start = AreaMean(mesh, mesh.rest_positions);
  double lowest = 0.0, highest = 0.0, mean = 0.0;
  int frames = 0;
  while (sim.Advance()) {
    const double x = AreaMean(mesh, sim.positions()).x() - start.x();
    lowest = std::min(lowest, x);
    highest = std::max(highest, x);
    mean += x;
    ++frames;
  }
  ASSERT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
  mean /= frames;
  // Released at an extreme of the swing: it overshoots to the other side
  // (about twice the offset) and oscillates about the equilibrium.
  EXPECT_GT(highest, 1.5 * 4.0);
  EXPECT_GT(lowest, -0.5);
  EXPECT_NEAR(mean, 4.0, 1.0);
}

TEST(InitialMotion, NothingChangesWithoutInertiaClampsOrObservedMotion) {
  const Mesh mesh = StartingStrip();
  const ParameterValues values = InertiaValues(1.0);
  const auto run = [&](const Scene& scene, const ModelDefinition& model) {
    Simulator sim(mesh, scene, {}, model);
    if (model.effects.empty()) {
      sim.Reset(calib::testing::StiffTestParameters());
    } else {
      sim.Reset(values);
    }
    EXPECT_EQ(MaxNorm(sim.initial_velocities()), 0.0);
    EXPECT_EQ(MaxNorm(Difference(sim.rest_shape(), mesh.rest_positions)), 0.0);
    while (sim.Advance()) {
    }
    return sim.positions();
  };
  Scene unknown = SwingScene(40, Vec2(6.0, 0.0), Vec2(10.0, 0.0));
  unknown.motion.known = false;
  Scene free_object = SwingScene(40, Vec2(6.0, 0.0), Vec2(10.0, 0.0));
  free_object.clamps.clear();
  // Without inertia: the base model, bit for bit as if no motion were known.
  EXPECT_EQ(run(SwingScene(40, Vec2(6.0, 0.0), Vec2(10.0, 0.0)), ModelDefinition{}),
            run(unknown, ModelDefinition{}));
  // Without clamps (nothing holds the mesh against a uniform load): at rest.
  Simulator free_sim(mesh, free_object, {}, ModelDefinition{{"inertia"}});
  free_sim.Reset(values);
  EXPECT_EQ(MaxNorm(Difference(free_sim.rest_shape(), mesh.rest_positions)), 0.0);
  run(unknown, ModelDefinition{{"inertia"}});
}

TEST(InitialMotion, ResetIsDeterministicAndForgetsTheLastCandidate) {
  const Mesh mesh = StartingStrip();
  const Scene scene = SwingScene(60, Vec2(5.0, 0.0), Vec2(20.0, 0.0));
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  const auto run = [&](const ParameterValues& values) {
    sim.Reset(values);
    while (sim.Advance()) {
    }
    EXPECT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
    return sim.positions();
  };
  ParameterValues stiffer = InertiaValues(1.0);
  stiffer["k_D"] = 4.0 * stiffer["k_D"];
  const std::vector<Vec2> first = run(InertiaValues(1.0));
  run(stiffer);
  EXPECT_EQ(run(InertiaValues(1.0)), first);
  Simulator fresh(mesh, scene, {}, ModelDefinition{{"inertia"}});
  fresh.Reset(InertiaValues(1.0));
  while (fresh.Advance()) {
  }
  EXPECT_EQ(fresh.positions(), first);
}

TEST(InitialMotion, ADeflectionTooLargeForTheLinearEstimateIsScaledDown) {
  // 5000 px mean offset for a 100 px strip: the linear response turns
  // triangles over; the rest takes the largest share that keeps them all.
  const Mesh mesh = StartingStrip();
  const Scene scene = SwingScene(10, Vec2(5000.0, 0.0), Vec2::Zero());
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  sim.Reset(InertiaValues(1.0));
  ASSERT_EQ(sim.status(), SimulationStatus::kRunning) << sim.failure_reason();
  const double kept = AreaMean(mesh, Difference(sim.rest_shape(), mesh.rest_positions)).x();
  EXPECT_GT(kept, 0.0);
  EXPECT_LT(kept, 5000.0);
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    EXPECT_GT(SignedArea(sim.rest_shape()[a], sim.rest_shape()[b], sim.rest_shape()[c]), 0.0);
  }
}

TEST(InitialMotion, ATrackedShapeHangsInEquilibriumUnderGravityAndMovesWithTheTrackedVelocities) {
  // The scene's motion as tracked from a video: the strip hangs straight
  // (the mesh) and starts still. With gravity the springs rest above it,
  // by the sag gravity gives them, so the strip stays where it was seen.
  const Mesh mesh = StartingStrip();
  Scene scene = SwingScene(60, Vec2::Zero(), Vec2::Zero());
  scene.motion.node_rest_px = mesh.rest_positions;
  scene.motion.node_velocity_px_s.assign(mesh.NumNodes(), Vec2::Zero());
  ParameterValues values = InertiaValues(0.0);
  for (const char* k : {"k_D", "k_A", "k_phi"}) values[k] = 2e4;  // sags a pixel or two
  values["gravity_px_s2"] = 400.0;
  values["gravity_angle_deg"] = 90.0;
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  sim.Reset(values);
  ASSERT_EQ(sim.status(), SimulationStatus::kRunning) << sim.failure_reason();
  const double sag = MaxNorm(Difference(sim.rest_shape(), mesh.rest_positions));
  ASSERT_GT(sag, 0.2) << "gravity moves the rest shape up by its sag";
  ASSERT_LT(sag, 5.0);
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    EXPECT_LE(sim.rest_shape()[i].y(), mesh.rest_positions[i].y() + 1e-9) << "node " << i;
  }
  double drift = 0.0;
  while (sim.Advance()) drift = std::max(drift, MaxNorm(Difference(sim.positions(), mesh.rest_positions)));
  ASSERT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
  EXPECT_LT(drift, 0.05 * sag) << "the tracked shape is the equilibrium (to the linear estimate)";

  // The tracked velocities are the start's, node by node.
  std::vector<Vec2> velocity(mesh.NumNodes(), Vec2::Zero());
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    if (mesh.rest_positions[i].y() > 101.0) velocity[i] = Vec2(0.3 * (mesh.rest_positions[i].y() - 100.0), 0.0);
  }
  scene.motion.node_velocity_px_s = velocity;
  Simulator moving(mesh, scene, {}, ModelDefinition{{"inertia"}});
  moving.Reset(values);
  ASSERT_EQ(moving.status(), SimulationStatus::kRunning) << moving.failure_reason();
  for (int i = 0; i < mesh.NumNodes(); ++i) EXPECT_EQ(moving.initial_velocities()[i], velocity[i]);
  ASSERT_TRUE(moving.Advance());
  const int foot = mesh.NumNodes() - 2;
  EXPECT_NEAR(moving.positions()[foot].x() - mesh.rest_positions[foot].x(), velocity[foot].x() / 240.0,
              0.1 * velocity[foot].x() / 240.0);
}

TEST(InitialMotion, ATrackedStartPoseIsWhereTheModelStartsAtEveryReset) {
  // The tracked shape's start pose (node_start_px) replaces the mesh's
  // positions at frame 0, at every reset; without one the mesh's stay.
  const Mesh mesh = StartingStrip();
  Scene scene = SwingScene(10, Vec2::Zero(), Vec2::Zero());
  scene.motion.node_rest_px = mesh.rest_positions;
  scene.motion.node_velocity_px_s.assign(mesh.NumNodes(), Vec2::Zero());
  std::vector<Vec2> start = mesh.rest_positions;
  for (Vec2& p : start) p += Vec2(0.5, 0.002 * (p.y() - 100.0));  // moved and a little stretched
  scene.motion.node_start_px = start;
  const ParameterValues values = InertiaValues(0.0);
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  for (int reset = 0; reset < 2; ++reset) {
    sim.Reset(values);
    ASSERT_EQ(sim.status(), SimulationStatus::kRunning) << sim.failure_reason();
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      EXPECT_EQ(sim.positions()[i], start[i]) << "node " << i << ", reset " << reset;
    }
    while (sim.Advance()) {
    }
  }
  scene.motion.node_start_px.clear();
  Simulator own(mesh, scene, {}, ModelDefinition{{"inertia"}});
  own.Reset(values);
  for (int i = 0; i < mesh.NumNodes(); ++i) EXPECT_EQ(own.positions()[i], mesh.rest_positions[i]);
}

}  // namespace
}  // namespace calib
