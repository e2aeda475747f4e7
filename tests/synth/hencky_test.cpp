// The Hencky (logarithmic strain) truth material: energy, stress and
// Hessian against differences and against its closed form in principal
// stretches, the small-strain limit (the linear plate of the same E and nu,
// as the neo-Hookean law), rigid motions, PSD projection, a truth-model push
// that converges; and the law's selection (material.law), which leaves the
// neo-Hookean path exactly as it was.

#include "calib/synth/hencky.h"

#include "calib/synth/material_law.h"
#include "calib/synth/scenario.h"
#include "calib/synth/truth_simulator.h"
#include "error_text.h"
#include "support/test_support.h"
#include "triangle_checks.h"

#include <gtest/gtest.h>

#include <cmath>

namespace calib::synth {
namespace {

using testing::Deformations;
using testing::MakeRest;
using testing::Parameters;
using testing::RestTriangle;

Eigen::Matrix2d Rotation(double angle) {
  Eigen::Matrix2d r;
  r << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  return r;
}

// F = R(a) diag(s1, s2) R(b)^T.
Eigen::Matrix2d Stretch(double s1, double s2, double a, double b) {
  return Rotation(a) * Eigen::Vector2d(s1, s2).asDiagonal() * Rotation(b).transpose();
}

TEST(Hencky, GradientMatchesCentralDifferencesAtAllScales) {
  testing::ExpectGradientMatchesDifferences(&HenckyTriangleEnergy);
}

TEST(Hencky, HessianMatchesDifferencesOfTheGradient) {
  testing::ExpectHessianMatchesDifferences(&HenckyTriangleEnergy, 1e-10);
}

TEST(Hencky, DerivativesHoldAtAndNearEqualStretches) {
  const NeoHookeanParameters p = Parameters(1.0);
  for (const double split : {0.0, 1e-9, 1e-6, 1e-4, 1e-2}) {
    const Eigen::Matrix2d F = Stretch(1.1 * (1.0 + split), 1.1, 0.4, -0.9);
    Eigen::Matrix2d P;
    Eigen::Matrix4d dPdF;
    HenckyDensity(F, p, &P, &dPdF);
    const double h = 1e-7;
    double worst_p = 0.0, worst_dp = 0.0;
    for (int k = 0; k < 4; ++k) {
      Eigen::Matrix2d Fp = F, Fm = F;
      Fp.data()[k] += h;
      Fm.data()[k] -= h;
      Eigen::Matrix2d Pp, Pm;
      const double wp = HenckyDensity(Fp, p, &Pp, nullptr);
      const double wm = HenckyDensity(Fm, p, &Pm, nullptr);
      worst_p = std::max(worst_p, std::abs((wp - wm) / (2.0 * h) - P.data()[k]));
      const Eigen::Matrix2d column = (Pp - Pm) / (2.0 * h);
      for (int i = 0; i < 4; ++i) worst_dp = std::max(worst_dp, std::abs(column.data()[i] - dPdF(i, k)));
    }
    EXPECT_LE(worst_p, 1e-6 * p.mu_pa) << "split " << split;
    EXPECT_LE(worst_dp, 1e-5 * p.mu_pa) << "split " << split;
    EXPECT_TRUE(dPdF.allFinite()) << "split " << split;
  }
}

TEST(Hencky, DensityIsTheLogStrainFormulaInPrincipalStretches) {
  const NeoHookeanParameters p = Parameters(0.0);
  const double kappa = p.mu_pa + p.lambda_pa;
  for (const auto& [s1, s2] : {std::pair{1.3, 0.7}, {0.5, 0.9}, {2.0, 2.0}, {1.0, 0.6}}) {
    const double e1 = std::log(s1), e2 = std::log(s2);
    const double expected = 0.5 * p.mu_pa * (e1 - e2) * (e1 - e2) + 0.5 * kappa * (e1 + e2) * (e1 + e2);
    EXPECT_NEAR(HenckyDensity(Stretch(s1, s2, 0.3, 1.2), p, nullptr, nullptr), expected, 1e-12 * p.mu_pa)
        << s1 << ", " << s2;
  }
}

TEST(Hencky, SmallStrainsMatchTheLinearLawOfTheSameEAndNu) {
  // W of the linear plate: mu |eps|^2 + lambda*/2 (tr eps)^2 (plane stress).
  const double E = 30e3, nu = 0.3;
  const NeoHookeanParameters p = PlaneStressLame(E, nu);
  for (const double angle : {0.0, 0.8}) {
    Eigen::Matrix2d eps;
    eps << 2e-5, -0.7e-5, -0.7e-5, -1.3e-5;
    const Eigen::Matrix2d F = Rotation(angle) * (Eigen::Matrix2d::Identity() + eps);
    const double linear = p.mu_pa * eps.squaredNorm() + 0.5 * p.lambda_pa * eps.trace() * eps.trace();
    const double hencky = HenckyDensity(F, p, nullptr, nullptr);
    EXPECT_NEAR(hencky, linear, 1e-3 * linear) << "angle " << angle;
    EXPECT_NEAR(hencky, NeoHookeanDensity(F, p, nullptr, nullptr), 1e-3 * linear) << "angle " << angle;
  }
  testing::ExpectUniaxialPlaneStressHooke(&HenckyDensity);
  // At rest the tangent is the linear law's: the same as the neo-Hookean one.
  Eigen::Matrix4d hencky_tangent, neo_tangent;
  HenckyDensity(Eigen::Matrix2d::Identity(), p, nullptr, &hencky_tangent);
  NeoHookeanDensity(Eigen::Matrix2d::Identity(), p, nullptr, &neo_tangent);
  EXPECT_LE((hencky_tangent - neo_tangent).cwiseAbs().maxCoeff(), 1e-9 * E);
}

TEST(Hencky, ZeroAtRestAndInvariantUnderRigidMotion) {
  const RestTriangle rest = MakeRest(1e-2);
  const NeoHookeanParameters p = Parameters(0.5);
  Vec6 g;
  EXPECT_LE(std::abs(HenckyTriangleEnergy(rest.x, rest.rest_inverse, rest.volume_m3, p, &g, nullptr, false)),
            1e-20);
  EXPECT_LE(g.norm(), 1e-12);
  const Eigen::Matrix2d R = Rotation(1.1);
  for (const Vec6& x : Deformations(rest, 1e-2, 5)) {
    Vec6 moved, gm;
    for (int a = 0; a < 3; ++a) moved.segment<2>(2 * a) = R * x.segment<2>(2 * a) + Vec2(0.1, 0.2);
    const double e = HenckyTriangleEnergy(x, rest.rest_inverse, rest.volume_m3, p, &g, nullptr, false);
    const double em = HenckyTriangleEnergy(moved, rest.rest_inverse, rest.volume_m3, p, &gm, nullptr, false);
    EXPECT_NEAR(em, e, 1e-12 * std::abs(e));
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE((gm.segment<2>(2 * a) - R * g.segment<2>(2 * a)).norm(), 1e-9 * g.norm());
    }
    double moment = 0.0;
    for (int a = 0; a < 3; ++a) moment += Cross(x.segment<2>(2 * a), g.segment<2>(2 * a));
    EXPECT_LE(std::abs(moment), 1e-12 * g.norm());
  }
}

TEST(Hencky, ProjectedHessianIsPositiveSemiDefinite) {
  const RestTriangle rest = MakeRest(1.0);
  const NeoHookeanParameters p = Parameters(0.0);
  std::vector<Vec6> states = Deformations(rest, 1.0, 30);
  // Large stretch, where Hencky's stress-strain curve bends over: indefinite.
  Vec6 stretched;
  for (int a = 0; a < 3; ++a) {
    stretched.segment<2>(2 * a) = Stretch(3.0, 2.5, 0.2, 0.0) * rest.x.segment<2>(2 * a);
  }
  states.push_back(stretched);
  const int indefinite_seen = testing::ExpectProjectedHessiansPsd(&HenckyTriangleEnergy, rest, states, p);
  EXPECT_GT(indefinite_seen, 0) << "the sample should include indefinite states";
}

TEST(Hencky, InvertedElementIsInfeasible) {
  const RestTriangle rest = MakeRest(1.0);
  Vec6 flipped = rest.x;
  flipped(5) = -flipped(5);
  Vec6 g = Vec6::Constant(7.0);
  EXPECT_TRUE(std::isinf(
      HenckyTriangleEnergy(flipped, rest.rest_inverse, rest.volume_m3, Parameters(0.0), &g, nullptr, false)));
  EXPECT_EQ(g, Vec6::Constant(7.0)) << "nothing written for an infeasible element";
}

// A 120 x 48 px block pushed 3 px at the middle of its top against the
// table: Newton converges every step; the force at full depth is within a
// few per cent of the neo-Hookean block's (small strains), not equal.
TEST(Hencky, TruthModelPushConverges) {
  TruthScene scene;
  scene.rest_mesh = calib::testing::MakeGridMesh(10, 4, 12.0, Vec2(100.0, 100.0));
  scene.num_frames = 12;
  scene.substeps = 2;
  for (int f = 0; f < scene.num_frames; ++f) {
    const double u = std::min(1.0, f / 8.0);
    scene.obstacles.push_back({Disc{Vec2(160.0, 100.0 - 8.0 - 1.0 + 4.0 * u), 8.0},
                               Disc{Vec2(160.0, 148.0 + 6.0), 6.0}});
  }
  scene.force_obstacle = 0;
  TruthMaterial neo, hencky;
  hencky.law = MaterialLaw::kHencky;
  const TruthEnvironment environment;
  const auto a = SimulateTruth(scene, neo, environment);
  const auto b = SimulateTruth(scene, hencky, environment);
  ASSERT_EQ(b.size(), 12u);
  const double fa = a.back().contact_force_n.norm(), fb = b.back().contact_force_n.norm();
  EXPECT_GT(fa, 0.0);
  EXPECT_NEAR(fb, fa, 0.1 * fa);
  EXPECT_NE(fb, fa);
}

// ---------------------------------------------------------------- the law's selection

TEST(MaterialLaw, NamesReadBothWaysAndDensitiesDiffer) {
  EXPECT_EQ(MaterialLawFromString("hencky"), MaterialLaw::kHencky);
  EXPECT_EQ(ToString(MaterialLaw::kNeoHookean), "neo_hookean");
  EXPECT_THROW(MaterialLawFromString("mooney"), std::invalid_argument);
  EXPECT_EQ(DensityOf(MaterialLaw::kNeoHookean), &NeoHookeanDensity);
  EXPECT_EQ(DensityOf(MaterialLaw::kHencky), &HenckyDensity);
}

// Values of the neo-Hookean triangle (energy, gradient, projected and exact
// Hessian entries) as the truth model computed them before the Hencky law
// was added: the default law's path gives the same bits.
TEST(MaterialLaw, NeoHookeanPathGivesTheSameBitsAsBefore) {
  Vec6 x;
  x << 0.001, -0.0005, 0.0262, 0.0031, 0.0049, 0.0231;
  Eigen::Matrix2d dm;
  dm << 0.025, 0.004, 0.002, 0.024;
  NeoHookeanParameters p = PlaneStressLame(30e3, 0.3);
  p.stiffening = 1.5;
  const EnergyDensity law = DensityOf(Scenario{}.material.law);
  Vec6 g;
  Mat6 h, exact;
  EXPECT_EQ(TriangleEnergy(law, x, dm.inverse(), 6e-6, p, &g, &h, true), 0x1.a224a053a31fp-13);
  TriangleEnergy(law, x, dm.inverse(), 6e-6, p, nullptr, &exact, false);
  const Vec6 expected_g = (Vec6() << -0x1.4e3182604e7d3p-3, 0x1.749457985df6p-6, -0x1.b4b7dd45d7659p-6,
                           0x1.ae10bb7423127p-3, 0x1.84c87e090969ep-3, -0x1.dca346672ed13p-3)
                              .finished();
  EXPECT_EQ(g, expected_g);
  EXPECT_EQ(h(0, 0), 0x1.61877f4598dc6p+8);
  EXPECT_EQ(h(1, 3), -0x1.e436790fad0fap+5);
  EXPECT_EQ(h(2, 5), 0x1.ac3ce925c9e25p+6);
  EXPECT_EQ(h(4, 4), 0x1.1a086abd81daap+7);
  EXPECT_EQ(exact(0, 0), 0x1.5fcbac2401fbcp+8);
  EXPECT_EQ(exact(1, 3), -0x1.d53e3e9a37b5bp+5);
  EXPECT_EQ(exact(2, 5), 0x1.ac5ee65398db7p+6);
  EXPECT_EQ(exact(4, 4), 0x1.157f86ef62cd7p+7);
}

TEST(MaterialLaw, ScenarioSelectsTheLawAndDefaultsToNeoHookean) {
  EXPECT_EQ(ParseScenario("kind: push\n", "a.yaml").material.law, MaterialLaw::kNeoHookean);
  const Scenario s = ParseScenario("kind: push\nmaterial: {law: hencky}\n", "b.yaml");
  EXPECT_EQ(s.material.law, MaterialLaw::kHencky);
  EXPECT_EQ(ToTruthMaterial(s).law, MaterialLaw::kHencky);
  EXPECT_EQ(ParseScenario(ScenarioToYaml(s), "c.yaml").material.law, MaterialLaw::kHencky);
  const std::string text = "kind: push\nmaterial: {law: mooney}\n";
  const std::string error = calib::testing::ErrorOf<ScenarioError>([&] { ParseScenario(text, "bad.yaml"); });
  calib::testing::ExpectMessageNames(error, text, {"bad.yaml", "material.law", "'mooney'", "neo_hookean or hencky"});
}

}  // namespace
}  // namespace calib::synth
