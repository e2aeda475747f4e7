// What each effect does to a simulation: gravity makes a clamped strip sag;
// inertia oscillates with the period 2 pi sqrt(m / K); table friction stops
// a pushed body sooner and holds one pushed below its limit; plasticity
// leaves a permanent set; a viscoelastic body recovers slowly; strain
// stiffening is stiffer at large strain only; uneven stiffness softens one
// side; push_relaxation stops the body when the push falls below friction,
// where tau keeps it sliding. Also: effects at neutral parameters give the
// base model's states bit for bit, and every run is deterministic.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numbers>

#include <Eigen/Eigenvalues>

#include "calib/core/mesher.h"
#include "calib/core/model.h"
#include "calib/core/simulator.h"
#include "support/test_support.h"

namespace calib {
namespace {

using calib::testing::MakeGridMesh;
using calib::testing::OneDiscScene;
using calib::testing::StillScene;

ModelParameters Base() { return calib::testing::StiffTestParameters(); }

// A sensor-only push: the force obstacle stands far from the body (never
// touching it), so the measured force alone acts, on the node nearest to it.
Scene ForceOnlyScene(int frames, const Vec2& finger, const std::function<Vec2(int)>& force) {
  return OneDiscScene(frames, 30.0, [&](int) { return Disc{finger, 2.0}; }, force);
}

// A 8 x 4 patch (80 x 40 px at (100, 100)) with its bottom row clamped, dented
// from above by a disc with no force sensor: approach over frames [0, 20),
// hold [20, 40), retract [40, 50), then away until the end.
Mesh ClampedPatch() { return MakeGridMesh(8, 4, 10.0, Vec2(100, 100)); }

Scene DentScene(int frames, double depth_px) {
  const double radius = 8.0, start_y = 100.0 - radius - 2.0;
  Scene scene = OneDiscScene(frames, 30.0, [&](int f) {
    double travel = 0.0;
    if (f < 20)
      travel = f / 20.0;
    else if (f < 40)
      travel = 1.0;
    else if (f < 50)
      travel = 1.0 - (f - 40) / 10.0;
    return Disc{Vec2(140.0, start_y + travel * (depth_px + 2.0)), radius};
  });
  scene.clamps.push_back({99.0, 139.0, 82.0, 2.0});
  return scene;
}

ParameterValues Values(const ModelParameters& base, const ParameterValues& extra) {
  ParameterValues values = base.ToValues();
  for (const auto& [name, value] : extra) values[name] = value;
  return values;
}

// Runs to the end; on_frame(frame, positions) after every frame (frame 0 too).
void RunToEnd(Simulator& sim, const std::function<void(int, const std::vector<Vec2>&)>& on_frame) {
  on_frame(0, sim.positions());
  while (sim.Advance()) on_frame(sim.frame(), sim.positions());
  ASSERT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
}

Vec2 Centroid(const std::vector<Vec2>& x) {
  Vec2 c = Vec2::Zero();
  for (const Vec2& p : x) c += p;
  return c / static_cast<double>(x.size());
}

double MaxDisplacement(const Mesh& mesh, const std::vector<Vec2>& x) {
  double worst = 0.0;
  for (int i = 0; i < mesh.NumNodes(); ++i)
    worst = std::max(worst, (x[i] - mesh.rest_positions[i]).norm());
  return worst;
}

TEST(InertiaEffect, GravityMakesAClampedStripSag) {
  const Mesh mesh = MakeGridMesh(10, 2, 10.0, Vec2(100, 100));  // 100 x 20 px
  Scene scene = StillScene(90);
  scene.clamps.push_back({99.0, 99.0, 2.0, 22.0});  // left end
  const int tip = 10;                               // top right corner
  ParameterValues values = Values(
      Base(),
      {{"inertia_damping_per_s", 4.0}, {"gravity_px_s2", 20.0}, {"gravity_angle_deg", 90.0}});
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  sim.Reset(values);
  EXPECT_TRUE(sim.second_order());
  double late_sag = 0.0;
  RunToEnd(sim, [&](int frame, const std::vector<Vec2>& x) {
    if (frame >= 60) late_sag += (x[tip].y() - mesh.rest_positions[tip].y()) / 30.0;
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      if (sim.clamped()[i]) {
        ASSERT_EQ(x[i], mesh.rest_positions[i]);
      }
    }
  });
  EXPECT_GT(late_sag, 2.0) << "the free end should hang down";

  values["gravity_px_s2"] = 0.0;
  sim.Reset(values);
  RunToEnd(sim, [&](int, const std::vector<Vec2>& x) {
    ASSERT_LT(MaxDisplacement(mesh, x), 1e-12) << "no gravity, no motion";
  });
}

// The second-order step is explicit in the springs: stiff enough springs
// need more substeps than options.substeps to be stable. Each candidate
// takes the fewest with kStabilityMargin h^2 lambda_max <= 4, lambda_max the
// fastest mode rate of M^-1 K (here from a dense eigen solve of the
// finite-difference stiffness, independent of the simulator's power
// iteration), and runs; one that would need more than kMaxSubsteps fails
// saying so.
TEST(InertiaEffect, StiffSpringsTakeTheSubstepsTheSecondOrderStepNeeds) {
  const Mesh mesh = MakeGridMesh(10, 2, 10.0, Vec2(100, 100));  // 100 x 20 px
  Scene scene = StillScene(30);
  scene.clamps.push_back({99.0, 99.0, 2.0, 22.0});  // left end
  SimulationOptions options;
  const auto scaled = [](double factor) {
    ModelParameters p = Base();
    p.k_distance *= factor;
    p.k_area *= factor;
    p.k_angle *= factor;
    p.k_damping = 0.0;
    return p;
  };
  const ParameterValues effect = {
      {"inertia_damping_per_s", 0.0}, {"gravity_px_s2", 20.0}, {"gravity_angle_deg", 90.0}};
  Simulator sim(mesh, scene, options, ModelDefinition{{"inertia"}});

  // The fastest mode of M^-1 K at the rest shape, movable nodes only.
  const auto fastest_rate = [&](const ModelParameters& p) {
    Model model(mesh);
    ForceWorkspace ws = model.MakeWorkspace();
    std::vector<int> free_nodes;
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      if (sim.clamped()[i] == 0) free_nodes.push_back(i);
    }
    const int m = 2 * static_cast<int>(free_nodes.size());
    Eigen::MatrixXd k(m, m);
    std::vector<Vec2> x = mesh.rest_positions, f_plus(x.size()), f_minus(x.size());
    const std::vector<Vec2> v(x.size(), Vec2::Zero());
    constexpr double kProbe = 1e-4;
    for (int c = 0; c < m; ++c) {
      Vec2& node = x[free_nodes[c / 2]];
      node[c % 2] += kProbe;
      model.ComputeForces(p, x, v, f_plus, ws);
      node[c % 2] -= 2.0 * kProbe;
      model.ComputeForces(p, x, v, f_minus, ws);
      node[c % 2] += kProbe;
      for (int r = 0; r < m; ++r) {
        const int i = free_nodes[r / 2];
        k(r, c) = -(f_plus[i][r % 2] - f_minus[i][r % 2]) / (2.0 * kProbe) / p.mass;
      }
    }
    const Eigen::MatrixXd symmetric = 0.5 * (k + k.transpose());
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(symmetric).eigenvalues().maxCoeff();
  };

  // Soft springs: the paper's substeps.
  sim.Reset(Values(scaled(1.0), effect));
  ASSERT_EQ(sim.status(), SimulationStatus::kRunning);
  EXPECT_EQ(sim.substeps(), options.substeps);

  // 10^5 times stiffer: more substeps, as many as the bound asks (the power
  // iteration's estimate may fall a little short of the eigenvalue).
  const ModelParameters stiff = scaled(1e5);
  const double lambda = fastest_rate(stiff);
  const double needed =
      std::ceil(scene.frame_time_s * std::sqrt(Simulator::kStabilityMargin * lambda) / 2.0);
  ASSERT_GT(needed, options.substeps);
  sim.Reset(Values(stiff, effect));
  ASSERT_EQ(sim.status(), SimulationStatus::kRunning);
  EXPECT_LE(sim.substeps(), needed);
  EXPECT_GE(sim.substeps(), 0.9 * needed);
  // ... and it runs, the strip held near its rest shape by its stiffness.
  while (sim.Advance()) {
  }
  ASSERT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
  EXPECT_LT(MaxDisplacement(mesh, sim.positions()), 1.0);

  // Beyond kMaxSubsteps the candidate fails with the reason.
  sim.Reset(Values(scaled(1e12), effect));
  EXPECT_EQ(sim.status(), SimulationStatus::kFailed);
  EXPECT_NE(sim.failure_reason().find("substeps a frame"), std::string::npos)
      << sim.failure_reason();
}

// Area weighted, gravity still accelerates every node alike (its pull is in
// proportion to each node's mass): a free body falls as the unweighted one,
// whatever the masses of its nodes.
TEST(InertiaEffect, AreaWeightedGravityAcceleratesEveryNodeAlike) {
  // Triangles of unequal areas, so the nodes' masses differ.
  MesherOptions mesher;
  mesher.edge_length_px = 15.0;
  const Mesh mesh =
      MeshPolygon({Vec2(100, 100), Vec2(180, 100), Vec2(150, 160), Vec2(105, 140)}, mesher);
  const Scene scene = StillScene(30);
  const ParameterValues values = Values(
      Base(), {{"inertia_damping_per_s", 0.5}, {"gravity_px_s2", 50.0}, {"gravity_angle_deg", 70.0}});
  SimulationOptions weighted_options;
  weighted_options.area_weighted = true;
  Simulator plain(mesh, scene, {}, ModelDefinition{{"inertia"}});
  Simulator weighted(mesh, scene, weighted_options, ModelDefinition{{"inertia"}});
  plain.Reset(values);
  weighted.Reset(values);
  const AreaWeights w = ComputeAreaWeights(mesh);
  ASSERT_GT(*std::max_element(w.node.begin(), w.node.end()),
            1.5 * *std::min_element(w.node.begin(), w.node.end()));
  // The internal forces of a body moving rigidly are rounding, which the
  // masses divide differently: the same fall to 1e-9 px.
  while (plain.Advance()) {
    ASSERT_TRUE(weighted.Advance()) << weighted.failure_reason();
    double apart = 0.0;
    for (size_t i = 0; i < plain.positions().size(); ++i) {
      apart = std::max(apart, (plain.positions()[i] - weighted.positions()[i]).norm());
    }
    EXPECT_LT(apart, 1e-9) << "frame " << plain.frame();
  }
  EXPECT_GT(Centroid(plain.positions()).y(), Centroid(mesh.rest_positions).y() + 1.0);
}

// Without a second-order effect the mass is a drag and area weighting
// changes nothing.
TEST(InertiaEffect, AreaWeightingWithoutInertiaChangesNothing) {
  const Mesh mesh = ClampedPatch();
  const Scene scene = DentScene(60, 6.0);
  SimulationOptions weighted_options;
  weighted_options.area_weighted = true;
  for (const IntegratorKind integrator : {IntegratorKind::kFirstOrder, IntegratorKind::kImplicitFirstOrder}) {
    SimulationOptions plain_options;
    plain_options.integrator = weighted_options.integrator = integrator;
    Simulator plain(mesh, scene, plain_options, ModelDefinition{{"table_friction"}});
    Simulator weighted(mesh, scene, weighted_options, ModelDefinition{{"table_friction"}});
    const ParameterValues values = Values(Base(), {{"friction_force", 0.2}});
    plain.Reset(values);
    weighted.Reset(values);
    while (plain.Advance()) {
      ASSERT_TRUE(weighted.Advance()) << weighted.failure_reason();
      ASSERT_EQ(plain.positions(), weighted.positions()) << "frame " << plain.frame();
    }
  }
}

// One free node on two distance springs from two clamped ones (an
// equilateral triangle, side D0): along the axis of symmetry its stiffness
// is K = 2 (k_D / D0^2) sin^2(60 deg) = 1.5 k_D / D0^2. Gravity along that
// axis starts it oscillating about the sagged equilibrium with the period
// 2 pi sqrt(m / K).
TEST(InertiaEffect, OscillatesWithThePeriodOfMassAndStiffness) {
  const double side = 20.0;
  const Mesh mesh = BuildMesh(
      {Vec2(0, 0), Vec2(side, 0), Vec2(side / 2, side * std::sqrt(3.0) / 2)}, {{0, 1, 2}});
  const double fps = 300.0;
  Scene scene = StillScene(300, fps);  // 1 s
  scene.clamps.push_back({-1.0, -1.0, side + 2.0, 2.0});
  const double mass = 1.0, period = 0.2;
  const double stiffness = mass * std::pow(2.0 * std::numbers::pi / period, 2);  // K
  ModelParameters p = Base();
  p.mass = mass;
  p.k_distance = stiffness * side * side / 1.5;
  p.k_damping = 0.0;
  p.k_area = 0.0;
  p.k_angle = 0.0;
  const ParameterValues values = Values(p, {{"inertia_damping_per_s", 0.0},
                                            {"gravity_px_s2", stiffness / mass},  // 1 px sag
                                            {"gravity_angle_deg", 90.0}});
  Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia"}});
  sim.Reset(values);
  std::vector<double> y;
  RunToEnd(sim, [&](int, const std::vector<Vec2>& x) {
    y.push_back(x[2].y() - mesh.rest_positions[2].y());
  });
  double mean = 0.0;
  for (double v : y) mean += v / y.size();
  EXPECT_NEAR(mean, 1.0, 0.05) << "oscillates about the sagged equilibrium m g / K";
  std::vector<double> crossings;  // times of upward and downward crossings of the mean
  for (size_t f = 1; f < y.size(); ++f) {
    const double a = y[f - 1] - mean, b = y[f] - mean;
    if ((a < 0) != (b < 0)) crossings.push_back((f - 1 + a / (a - b)) / fps);
  }
  ASSERT_GE(crossings.size(), 8u);
  const double measured = 2.0 * (crossings.back() - crossings.front()) / (crossings.size() - 1);
  EXPECT_NEAR(measured, period, 0.02 * period);
  // Undamped: the swing keeps its amplitude.
  double late_max = 0.0;
  for (size_t f = y.size() - 60; f < y.size(); ++f) late_max = std::max(late_max, y[f]);
  EXPECT_GT(late_max, 1.8);
}

TEST(TableFrictionEffect, StopsAPushedBodySooner) {
  const Mesh mesh = MakeGridMesh(6, 3, 10.0, Vec2(100, 100));
  const Scene scene = ForceOnlyScene(120, Vec2(20, 115),
                                     [](int f) { return f < 20 ? Vec2(2.0, 0.0) : Vec2::Zero(); });
  ModelParameters p = Base();
  p.mass = 0.005;
  const auto travel = [&](double friction, double* late_drift) {
    Simulator sim(mesh, scene, {}, ModelDefinition{{"inertia", "table_friction"}});
    sim.Reset(Values(p, {{"inertia_damping_per_s", 0.0},
                         {"gravity_px_s2", 0.0},
                         {"gravity_angle_deg", 0.0},
                         {"friction_force", friction}}));
    Vec2 start, at100, end;
    RunToEnd(sim, [&](int frame, const std::vector<Vec2>& x) {
      if (frame == 0) start = Centroid(x);
      if (frame == 100) at100 = Centroid(x);
      end = Centroid(x);
    });
    *late_drift = (end - at100).norm();
    return (end - start).x();
  };
  double drift_free = 0.0, drift_friction = 0.0;
  const double free = travel(0.0, &drift_free);
  const double held = travel(1.0, &drift_friction);
  EXPECT_GT(drift_free, 3.0) << "without friction the body coasts on";
  EXPECT_LT(drift_friction, 1e-9) << "with friction it has stopped";
  EXPECT_GT(held, 0.5) << "the push exceeds friction: the body moves";
  EXPECT_LT(held, 0.5 * free);
}

// A push below the body's friction limit, held on: the body creeps while
// its deformation spreads the load over enough nodes' friction, ever more
// slowly, and is held; without friction it slides on at P / (N m).
TEST(TableFrictionEffect, HoldsAFirstOrderBodyPushedBelowItsLimit) {
  const Mesh mesh = MakeGridMesh(6, 3, 10.0, Vec2(100, 100));
  const Scene scene = ForceOnlyScene(200, Vec2(20, 115), [](int) { return Vec2(0.2, 0.0); });
  const auto drift = [&](double friction, double* early) {
    Simulator sim(mesh, scene, {}, ModelDefinition{{"table_friction"}});
    sim.Reset(Values(Base(), {{"friction_force", friction}}));
    Vec2 at20, at40, at180, end;
    RunToEnd(sim, [&](int frame, const std::vector<Vec2>& x) {
      if (frame == 20) at20 = Centroid(x);
      if (frame == 40) at40 = Centroid(x);
      if (frame == 180) at180 = Centroid(x);
      end = Centroid(x);
    });
    *early = (at40 - at20).norm();
    return (end - at180).norm();
  };
  double early_sliding = 0.0, early_held = 0.0;
  const double sliding = drift(0.0, &early_sliding);
  const double held = drift(0.3, &early_held);
  // Frames 180 to 199: 19 frame times at P / (N m).
  EXPECT_NEAR(sliding, 19.0 / 30.0 * 0.2 / (28 * Base().mass), 1e-9) << "P / (N m)";
  EXPECT_LT(held, 0.01 * sliding) << "friction 0.3 > push 0.2 holds the body";
  EXPECT_LT(held, 0.05 * early_held) << "the creep dies out";
}

TEST(PlasticityEffect, LeavesAPermanentSetAfterTheLoad) {
  const Mesh mesh = ClampedPatch();
  const Scene scene = DentScene(150, 12.0);
  const auto final_set = [&](const ModelDefinition& model, const ParameterValues& values,
                             double* change_late) {
    Simulator sim(mesh, scene, {}, model);
    sim.Reset(values);
    double max_during_load = 0.0;
    std::vector<Vec2> at120;
    std::vector<Vec2> last;
    RunToEnd(sim, [&](int frame, const std::vector<Vec2>& x) {
      max_during_load = std::max(max_during_load, MaxDisplacement(mesh, x));
      if (frame == 120) at120 = x;
      last = x;
    });
    EXPECT_GT(max_during_load, 8.0) << "the disc should dent the patch";
    *change_late = 0.0;
    for (size_t i = 0; i < last.size(); ++i)
      *change_late = std::max(*change_late, (last[i] - at120[i]).norm());
    return MaxDisplacement(mesh, last);
  };
  double late_base = 0.0, late_plastic = 0.0;
  const double base = final_set(ModelDefinition{}, Base().ToValues(), &late_base);
  const double plastic =
      final_set(ModelDefinition{{"plasticity"}},
                Values(Base(), {{"plastic_yield_strain", 0.03}, {"plastic_rate_per_s", 20.0}}),
                &late_plastic);
  EXPECT_LT(base, 0.1) << "elastic: back to the rest shape";
  EXPECT_GT(plastic, 2.0) << "plastic: a permanent dent";
  EXPECT_LT(late_plastic, 0.05) << "the dent has settled: permanent, not slow recovery";
}

TEST(ViscoelasticEffect, RecoversSlowly) {
  const Mesh mesh = ClampedPatch();
  const Scene scene = DentScene(150, 12.0);
  const auto history = [&](const ModelDefinition& model, const ParameterValues& values) {
    Simulator sim(mesh, scene, {}, model);
    sim.Reset(values);
    std::vector<double> dent;
    RunToEnd(sim,
             [&](int, const std::vector<Vec2>& x) { dent.push_back(MaxDisplacement(mesh, x)); });
    return dent;
  };
  const std::vector<double> base = history(ModelDefinition{}, Base().ToValues());
  const std::vector<double> visco =
      history(ModelDefinition{{"viscoelastic"}},
              Values(Base(), {{"visco_share", 0.6}, {"visco_time_s", 1.0}}));
  // Frame 50: the disc has just left; the base patch is almost back by 70.
  EXPECT_GT(visco[70], 3.0 * base[70]) << "base " << base[70] << " visco " << visco[70];
  EXPECT_LT(base[149], 0.01);
  EXPECT_LT(visco[149], 0.5 * visco[70]) << "it does recover";
  EXPECT_LT(visco[149], visco[100]);
  EXPECT_LT(visco[100], visco[70]);
}

// Sensor-only push down on the top row of a bottom-clamped patch; the dent
// is the pushed node's settled displacement.
double SettledDent(const ModelDefinition& model, const ParameterValues& values, double force,
                   double finger_x, int nx = 8) {
  const Mesh mesh = MakeGridMesh(nx, 4, 10.0, Vec2(100, 100));
  Scene scene = ForceOnlyScene(150, Vec2(finger_x, 40.0), [&](int) { return Vec2(0.0, force); });
  scene.clamps.push_back({99.0, 139.0, nx * 10.0 + 2.0, 2.0});
  const int node = static_cast<int>(std::lround((finger_x - 100.0) / 10.0));  // top row
  Simulator sim(mesh, scene, {}, model);
  sim.Reset(values);
  double dent = 0.0;
  RunToEnd(sim, [&](int, const std::vector<Vec2>& x) {
    dent = x[node].y() - mesh.rest_positions[node].y();
  });
  return dent;
}

TEST(StrainStiffeningEffect, StifferAtLargeStrainOnly) {
  const ModelDefinition stiffening{{"strain_stiffening"}};
  const ParameterValues with = Values(Base(), {{"stiffening_k3", 20000.0}});
  const double small_base = SettledDent({}, Base().ToValues(), 0.05, 140.0);
  const double small_stiff = SettledDent(stiffening, with, 0.05, 140.0);
  const double large_base = SettledDent({}, Base().ToValues(), 4.0, 140.0);
  const double large_stiff = SettledDent(stiffening, with, 4.0, 140.0);
  ASSERT_GT(small_base, 0.0);
  EXPECT_GT(large_base, 3.0) << "a large strain";
  EXPECT_GT(small_stiff / small_base, 0.98) << small_stiff << " vs " << small_base;
  EXPECT_LT(large_stiff / large_base, 0.8) << large_stiff << " vs " << large_base;
}

TEST(UnevenStiffnessEffect, SoftensOneSide) {
  const ModelDefinition uneven{{"uneven_stiffness"}};
  // Stiffer towards +x: the left side is the soft one.
  const ParameterValues with =
      Values(Base(), {{"uneven_gradient", 0.6}, {"uneven_angle_deg", 0.0}});
  const double base_left = SettledDent({}, Base().ToValues(), 0.5, 120.0, 10);
  const double base_right = SettledDent({}, Base().ToValues(), 0.5, 180.0, 10);
  const double left = SettledDent(uneven, with, 0.5, 120.0, 10);
  const double right = SettledDent(uneven, with, 0.5, 180.0, 10);
  EXPECT_NEAR(base_left / base_right, 1.0, 0.1) << "the base patch is nearly symmetric";
  EXPECT_GT(left / right, 1.5 * base_left / base_right) << left << " vs " << right;
  EXPECT_GT(left, base_left);
  EXPECT_LT(right, base_right);
}

// The paper's suspect: with tau, a body keeps sliding as long as the sensor
// reads a force, also once the finger holds still. With push_relaxation the
// table's friction balances a hold force below its limit: the body stops.
TEST(PushRelaxationEffect, StopsWhenThePushFallsBelowFrictionUnlikeTau) {
  const Mesh mesh = MakeGridMesh(10, 4, 10.0, Vec2(100, 100));
  // Pushing (3) for a second, then holding (1) for two.
  const Scene scene = ForceOnlyScene(
      90, Vec2(20, 120), [](int f) { return f < 30 ? Vec2(3.0, 0.0) : Vec2(1.0, 0.0); });
  ModelParameters p = Base();
  p.translation = 0.5;
  const auto drift = [&](const ModelDefinition& model, const ParameterValues& values,
                         double* push_phase) {
    Simulator sim(mesh, scene, {}, model);
    sim.Reset(values);
    Vec2 at0, at30, at60, end;
    RunToEnd(sim, [&](int frame, const std::vector<Vec2>& x) {
      if (frame == 0) at0 = Centroid(x);
      if (frame == 30) at30 = Centroid(x);
      if (frame == 60) at60 = Centroid(x);
      end = Centroid(x);
    });
    *push_phase = (at30 - at0).x();
    return (end - at60).norm();
  };
  double push_tau = 0.0, push_relax = 0.0;
  const double hold_tau = drift({}, p.ToValues(), &push_tau);
  const double hold_relax = drift(ModelDefinition{{"push_relaxation"}},
                                  Values(p, {{"push_friction_force", 2.0}}), &push_relax);
  EXPECT_GT(hold_tau, 0.3) << "tau: the held push keeps the body sliding";
  EXPECT_LT(hold_relax, 1e-9) << "push_relaxation: friction holds the body";
  EXPECT_GT(push_relax, 0.3) << "while the push exceeds friction the body slides";
  EXPECT_LT(push_relax, push_tau);
}

// A disc that really pushes (finger and sensor), for the checks below.
Scene PushScene(int frames) {
  Scene scene = StillScene(frames);
  scene.num_obstacles = 2;
  scene.force_obstacle = 0;
  for (int f = 0; f < frames; ++f) {
    const double depth = std::min(1.0, f / (0.6 * frames)) * 18.0;
    scene.obstacle_discs.push_back({Vec2(100.0 - 8.0 + depth, 120.0), 8.0});
    scene.obstacle_discs.push_back({Vec2(186.0, 120.0), 6.0});
    scene.forces.push_back(Vec2(depth > 0 ? 1.5 : 0.0, 0.0));
  }
  return scene;
}

std::vector<std::vector<Vec2>> Trajectory(Simulator& sim, const ParameterValues& values) {
  std::vector<std::vector<Vec2>> states;
  sim.Reset(values);
  RunToEnd(sim, [&](int, const std::vector<Vec2>& x) { states.push_back(x); });
  return states;
}

// An effect whose parameters switch it off leaves the base model's states
// bit for bit (push_relaxation with no friction splits the push with other
// roundings, so it is only close).
TEST(Effects, NeutralParametersGiveTheBaseModelsBits) {
  const Mesh mesh = MakeGridMesh(8, 4, 10.0, Vec2(100, 100));
  const Scene scene = PushScene(40);
  ModelParameters p = Base();
  p.translation = 0.3;
  Simulator base(mesh, scene, {});
  base.Reset(p);
  std::vector<std::vector<Vec2>> reference;
  RunToEnd(base, [&](int, const std::vector<Vec2>& x) { reference.push_back(x); });
  Simulator plain(mesh, scene, {}, ModelDefinition{});
  EXPECT_EQ(Trajectory(plain, p.ToValues()), reference) << "no effects, named values";
  const std::vector<std::pair<std::string, ParameterValues>> neutral = {
      {"table_friction", {{"friction_force", 0.0}}},
      {"plasticity", {{"plastic_yield_strain", 0.01}, {"plastic_rate_per_s", 0.0}}},
      {"uneven_stiffness", {{"uneven_gradient", 0.0}, {"uneven_angle_deg", 45.0}}},
      {"strain_stiffening", {{"stiffening_k3", 0.0}}},
      {"viscoelastic", {{"visco_share", 0.0}, {"visco_time_s", 1.0}}},
  };
  for (const auto& [name, extra] : neutral) {
    Simulator sim(mesh, scene, {}, ModelDefinition{{name}});
    EXPECT_EQ(Trajectory(sim, Values(p, extra)), reference) << name;
  }
  Simulator relax(mesh, scene, {}, ModelDefinition{{"push_relaxation"}});
  const auto close = Trajectory(relax, Values(p, {{"push_friction_force", 0.0}}));
  ASSERT_EQ(close.size(), reference.size());
  double worst = 0.0;
  for (size_t f = 0; f < close.size(); ++f) {
    for (size_t i = 0; i < close[f].size(); ++i)
      worst = std::max(worst, (close[f][i] - reference[f][i]).norm());
  }
  EXPECT_LT(worst, 1e-9);
}

ParameterValues AllEffectValues() {
  ModelParameters p = Base();
  p.translation = 0.2;
  p.mass = 0.02;
  return Values(p, {{"inertia_damping_per_s", 3.0},
                    {"gravity_px_s2", 40.0},
                    {"gravity_angle_deg", 100.0},
                    {"friction_force", 0.3},
                    {"plastic_yield_strain", 0.04},
                    {"plastic_rate_per_s", 10.0},
                    {"uneven_gradient", 0.5},
                    {"uneven_angle_deg", -30.0},
                    {"stiffening_k3", 300.0},
                    {"visco_share", 0.3},
                    {"visco_time_s", 0.5},
                    {"push_friction_force", 0.4}});
}

ModelDefinition AllEffects() {
  return ModelDefinition{{"inertia", "table_friction", "plasticity", "uneven_stiffness",
                          "strain_stiffening", "viscoelastic", "push_relaxation"}};
}

TEST(Effects, EveryRunIsDeterministicAndResetForgetsThePast) {
  const Mesh mesh = MakeGridMesh(8, 4, 10.0, Vec2(100, 100));
  const Scene scene = PushScene(40);
  Simulator first(mesh, scene, {}, AllEffects());
  const auto a = Trajectory(first, AllEffectValues());
  EXPECT_GT(MaxDisplacement(mesh, a.back()), 1.0);
  // A fresh simulator gives the same bits...
  Simulator second(mesh, scene, {}, AllEffects());
  EXPECT_EQ(Trajectory(second, AllEffectValues()), a);
  // ...and so does one that ran another candidate before.
  ParameterValues other = AllEffectValues();
  other["plastic_yield_strain"] = 0.01;
  other["gravity_px_s2"] = 200.0;
  Trajectory(first, other);
  EXPECT_EQ(Trajectory(first, AllEffectValues()), a);
}

TEST(Effects, TwoEffectsCannotBothOwnTheDynamicsOrThePush) {
  // The catalogue has one effect per such hook, so only a repeated name
  // could clash; that is caught by the definition's validation.
  const Mesh mesh = MakeGridMesh(2, 2, 10.0);
  const Scene scene = StillScene(3);
  EXPECT_THROW(Simulator(mesh, scene, {}, ModelDefinition{{"inertia", "inertia"}}),
               std::invalid_argument);
}

}  // namespace
}  // namespace calib
