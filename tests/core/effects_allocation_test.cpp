// The simulator allocates nothing per substep, with every effect on: all
// effect state is sized when the simulator is built. Counted by replacing
// the global operator new in this test program.

#include <gtest/gtest.h>

#include "calib/core/simulator.h"
#include "support/allocation_counter.h"
#include "support/test_support.h"

namespace calib {
namespace {

Scene PushedPatchScene() {
  return calib::testing::OneDiscScene(
      40, 30.0, [](int f) { return Disc{Vec2(92.0 + std::min(1.0, f / 24.0) * 15.0, 120.0), 8.0}; },
      [](int) { return Vec2(1.0, 0.0); });
}

// The parameters of every effect but inertia's.
ParameterValues FirstOrderEffectValues() {
  return {{"friction_force", 0.3},     {"plastic_yield_strain", 0.02}, {"plastic_rate_per_s", 20.0},
          {"uneven_gradient", 0.5},    {"uneven_angle_deg", 0.0},      {"stiffening_k3", 300.0},
          {"visco_share", 0.3},        {"visco_time_s", 0.5},          {"push_friction_force", 0.4}};
}

// Frames run with the allocation counter on; expects a finished run.
int64_t AllocationsWhileRunning(Simulator& sim, int expected_frames) {
  const int64_t before = testing::Allocations();
  int frames = 0;
  while (sim.Advance()) ++frames;
  const int64_t during = testing::Allocations() - before;
  EXPECT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
  EXPECT_EQ(frames, expected_frames);
  return during;
}

TEST(EffectsAllocation, NoAllocationPerSubstepWithEveryEffect) {
  const Mesh mesh = calib::testing::MakeGridMesh(8, 4, 10.0, Vec2(100, 100));
  const Scene scene = PushedPatchScene();
  ModelDefinition model{{"inertia", "table_friction", "plasticity", "uneven_stiffness",
                         "strain_stiffening", "viscoelastic", "push_relaxation"}};
  Simulator sim(mesh, scene, {}, model);
  ModelParameters base;
  base.k_distance = 50.0;
  base.k_damping = 0.5;
  base.k_area = 20.0;
  base.k_angle = 5.0;
  base.mass = 0.02;
  base.translation = 0.2;
  ParameterValues values = base.ToValues();
  values.insert({{"inertia_damping_per_s", 3.0}, {"gravity_px_s2", 40.0}, {"gravity_angle_deg", 90.0}});
  const ParameterValues effects = FirstOrderEffectValues();
  values.insert(effects.begin(), effects.end());
  sim.Reset(values);
  EXPECT_EQ(AllocationsWhileRunning(sim, scene.num_frames - 1), 0);
}

TEST(EffectsAllocation, NoAllocationPerSubstepWithTheImplicitStep) {
  // Every effect but inertia (which owns the dynamics): the implicit step's
  // solve with its factor and the finger's contacts, and the effects beside
  // it. The step caches its factor's columns for the coordinates the
  // contacts touch, growing the cache the first time a coordinate is
  // touched: a simulator's first candidate warms it, the next allocate
  // nothing.
  const Mesh mesh = calib::testing::MakeGridMesh(8, 4, 10.0, Vec2(100, 100));
  const Scene scene = PushedPatchScene();
  ModelDefinition model{{"table_friction", "plasticity", "uneven_stiffness", "strain_stiffening",
                         "viscoelastic", "push_relaxation"}};
  SimulationOptions options;
  options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator sim(mesh, scene, options, model);
  ParameterValues values = calib::testing::StiffTestParameters(0.2).ToValues();
  const ParameterValues effects = FirstOrderEffectValues();
  values.insert(effects.begin(), effects.end());
  sim.Reset(values);
  while (sim.Advance()) {
  }
  sim.Reset(values);
  EXPECT_EQ(AllocationsWhileRunning(sim, scene.num_frames - 1), 0);
}

}  // namespace
}  // namespace calib
