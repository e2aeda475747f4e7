// The effect terms on a mesh: the catalogue and its parameters, messages
// that name an unknown effect or a bad parameter, and for every effect with
// an energy: forces = -gradient by central differences at random states
// (and with the state of a deformed history), zero force at rest, energy
// invariant under rigid motion.

#include "calib/core/effects.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>

#include "calib/core/model_definition.h"
#include "calib/core/simulator.h"
#include "support/test_support.h"

namespace calib {
namespace {

using calib::testing::MakeGridMesh;

ModelParameters CatalogueBase() { return calib::testing::StiffTestParameters(0.2); }

// Values for the base model and every effect, chosen so that each effect
// does something (a yield that is reached, a gradient, a stiff quartic...).
ParameterValues AllValues() {
  ParameterValues v = CatalogueBase().ToValues();
  v["inertia_damping_per_s"] = 2.0;
  v["gravity_px_s2"] = 300.0;
  v["gravity_angle_deg"] = 60.0;
  v["friction_force"] = 0.4;
  v["plastic_yield_strain"] = 0.02;
  v["plastic_rate_per_s"] = 80.0;
  v["uneven_gradient"] = 0.6;
  v["uneven_angle_deg"] = 30.0;
  v["stiffening_k3"] = 400.0;
  v["visco_share"] = 0.4;
  v["visco_time_s"] = 0.05;
  v["push_friction_force"] = 0.5;
  return v;
}

std::vector<std::string> AllEffectNames() {
  std::vector<std::string> names;
  for (const EffectInfo& info : EffectTermCatalogue()) names.push_back(info.name);
  return names;
}

std::vector<Vec2> Perturbed(const std::vector<Vec2>& x0, double amount, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<Vec2> x = x0;
  for (Vec2& p : x) p += Vec2(u(rng), u(rng));
  return x;
}

std::unique_ptr<EffectTerm> Configured(const std::string& name, const Mesh& mesh) {
  std::unique_ptr<EffectTerm> effect = MakeEffect(name);
  effect->Bind(mesh);
  effect->Configure(AllValues(), CatalogueBase());
  effect->Reset();
  return effect;
}

// Gives a stateful effect a history: several substeps at a strongly
// deformed shape, so plastic and viscoelastic rest lengths have moved.
void Deform(EffectTerm& effect, const Mesh& mesh, double amount, uint64_t seed) {
  const auto x = Perturbed(mesh.rest_positions, amount, seed);
  for (int s = 0; s < 5; ++s) {
    if (effect.hooks().after_substep) effect.AfterSubstep(x, 0.01);
    if (effect.hooks().after_frame) effect.AfterFrame(x, 0.01);
  }
}

TEST(EffectCatalogue, HasTheIssuesEffectsWithUniqueParameters) {
  const std::vector<std::string> expected = {
      "inertia",           "table_friction", "plasticity",     "uneven_stiffness",
      "strain_stiffening", "viscoelastic",   "push_relaxation"};
  EXPECT_EQ(AllEffectNames(), expected);
  std::set<std::string> names;
  for (const ParameterSpec& spec : BaseModelParameterSpecs()) names.insert(spec.name);
  for (const EffectInfo& info : EffectTermCatalogue()) {
    EXPECT_FALSE(info.description.empty()) << info.name;
    EXPECT_FALSE(info.parameters.empty()) << info.name;
    for (const ParameterSpec& spec : info.parameters) {
      EXPECT_TRUE(names.insert(spec.name).second) << "parameter name used twice: " << spec.name;
      EXPECT_FALSE(spec.unit.empty()) << spec.name;
      EXPECT_EQ(spec.description.rfind(info.name + ": ", 0), 0u)
          << spec.name << "'s description should start with its effect: " << spec.description;
      EXPECT_LE(spec.lower, spec.upper) << spec.name;
    }
    const auto effect = MakeEffect(info.name);
    EXPECT_EQ(effect->name(), info.name);
    EXPECT_EQ(effect->parameter_specs().size(), info.parameters.size());
  }
}

TEST(EffectCatalogue, UnknownEffectIsNamedWithTheKnownOnes) {
  try {
    MakeEffect("gravitas");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("'gravitas'"), std::string::npos) << message;
    for (const std::string& name : AllEffectNames()) {
      EXPECT_NE(message.find(name), std::string::npos) << message;
    }
  }
}

TEST(ModelDefinition, ValidatesNamesAndListsParameters) {
  std::string error;
  EXPECT_TRUE(ModelDefinition{}.IsValid(&error)) << error;
  EXPECT_FALSE((ModelDefinition{{"inertia", "frction"}}.IsValid(&error)));
  EXPECT_NE(error.find("effects[1] = 'frction'"), std::string::npos) << error;
  EXPECT_NE(error.find("table_friction"), std::string::npos) << error;
  EXPECT_FALSE((ModelDefinition{{"plasticity", "inertia", "plasticity"}}.IsValid(&error)));
  EXPECT_NE(error.find("effects[2] = 'plasticity'"), std::string::npos) << error;
  EXPECT_THROW(ModelParameterSpecs(ModelDefinition{{"nope"}}), std::invalid_argument);

  const ModelDefinition model{{"viscoelastic", "table_friction"}};
  EXPECT_EQ(model.ToString(), "base+viscoelastic+table_friction");
  const std::vector<ParameterSpec> specs = ModelParameterSpecs(model);
  std::vector<std::string> names;
  for (const ParameterSpec& s : specs) names.push_back(s.name);
  const std::vector<std::string> expected = {
      "k_D", "k_d", "k_A", "k_phi", "mass", "tau", "visco_share", "visco_time_s", "friction_force"};
  EXPECT_EQ(names, expected);
  EXPECT_EQ(ModelParameterSpecs(ModelDefinition{}).size(), BaseModelParameterSpecs().size());
}

TEST(ModelDefinition, SimulatorNamesUnknownEffectAndBadParameters) {
  const Mesh mesh = MakeGridMesh(3, 2, 10.0);
  Scene scene;
  scene.num_frames = 3;
  try {
    Simulator sim(mesh, scene, {}, ModelDefinition{{"table_friction", "wobble"}});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'wobble'"), std::string::npos) << e.what();
  }

  Simulator sim(mesh, scene, {}, ModelDefinition{{"table_friction"}});
  ParameterValues values = CatalogueBase().ToValues();
  values["friction_force"] = -1.0;
  try {
    sim.Reset(values);
    FAIL() << "no exception";
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find("'friction_force' = -1"), std::string::npos) << e.what();
  }
  values.erase("friction_force");
  try {
    sim.Reset(values);
    FAIL() << "no exception";
  } catch (const ParameterError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("missing parameter 'friction_force'"), std::string::npos) << message;
    EXPECT_NE(message.find("table_friction"), std::string::npos) << message;
  }
  values["friction_force"] = 1.0;
  values["friction_mu"] = 0.3;
  try {
    sim.Reset(values);
    FAIL() << "no exception";
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown parameter 'friction_mu'"), std::string::npos)
        << e.what();
  }
  values.erase("friction_mu");
  values["friction_force"] = std::nan("");
  EXPECT_THROW(sim.Reset(values), ParameterError);
  values["friction_force"] = 1.0;
  EXPECT_NO_THROW(sim.Reset(values));
  // The base model's struct cannot configure effects.
  EXPECT_THROW(sim.Reset(CatalogueBase()), std::logic_error);
}

// Every effect with an energy: forces against central differences of the
// energy, at random shapes around the rest shape, after a deformed history,
// at coordinate scales 1e-3, 1 and 1e3 (the mesh and the deformation scale
// together).
class EffectGradient : public ::testing::TestWithParam<std::tuple<std::string, double>> {};

TEST_P(EffectGradient, ForcesAreNegativeGradientOfEnergy) {
  const auto [name, scale] = GetParam();
  const Mesh mesh = MakeGridMesh(4, 3, 10.0 * scale, scale * Vec2(3, -2));
  const auto effect = Configured(name, mesh);
  ASSERT_TRUE(effect->info().has_energy);
  Deform(*effect, mesh, 3.0 * scale, 5);
  for (int trial = 0; trial < 3; ++trial) {
    const auto x = Perturbed(mesh.rest_positions, 2.5 * scale, 100 + trial);
    std::vector<Vec2> v(x.size(), Vec2::Zero()), f(x.size(), Vec2::Zero());
    double energy = 0.0;
    effect->AddForces(x, v, f, &energy);
    EXPECT_NEAR(energy, effect->Energy(x), 1e-12 * (1.0 + std::abs(energy)));
    double max_f = 0.0;
    for (const Vec2& fi : f) max_f = std::max(max_f, fi.cwiseAbs().maxCoeff());
    ASSERT_GT(max_f, 0.0) << name << " has no force at a deformed shape";
    const double h = 1e-6 * scale;
    double worst = 0.0;
    for (size_t i = 0; i < x.size(); ++i) {
      for (int d = 0; d < 2; ++d) {
        auto plus = x, minus = x;
        plus[i][d] += h;
        minus[i][d] -= h;
        const double numeric = -(effect->Energy(plus) - effect->Energy(minus)) / (2 * h);
        worst = std::max(worst, std::abs(numeric - f[i][d]) / max_f);
      }
    }
    EXPECT_LT(worst, 1e-6) << name << " scale " << scale << " trial " << trial;
  }
}

std::vector<std::string> EffectsWithEnergy() {
  std::vector<std::string> names;
  for (const EffectInfo& info : EffectTermCatalogue()) {
    if (info.has_energy) names.push_back(info.name);
  }
  return names;
}

INSTANTIATE_TEST_SUITE_P(
    AllWithEnergy, EffectGradient,
    ::testing::Combine(::testing::ValuesIn(EffectsWithEnergy()), ::testing::Values(1e-3, 1.0, 1e3)),
    [](const auto& info) {
      const double scale = std::get<1>(info.param);
      return std::get<0>(info.param) + (scale < 0.1 ? "_small" : scale > 10 ? "_large" : "_unit");
    });

TEST(EffectTerms, EnergiesAreTheOnesWithForcesAndNoneOthers) {
  EXPECT_EQ(EffectsWithEnergy(),
            (std::vector<std::string>{"inertia", "plasticity", "uneven_stiffness",
                                      "strain_stiffening", "viscoelastic"}));
}

// The elastic effects (all with energy but gravity): no force at the rest
// shape from the reset state, and an energy that rigid motion leaves alone,
// also with a plastic or viscoelastic history.
TEST(EffectTerms, ElasticEffectsRestAtRestAndIgnoreRigidMotion) {
  const Mesh mesh = MakeGridMesh(5, 4, 12.0, Vec2(30, 40));
  for (const std::string name :
       {"plasticity", "uneven_stiffness", "strain_stiffening", "viscoelastic"}) {
    const auto effect = Configured(name, mesh);
    std::vector<Vec2> v(mesh.NumNodes(), Vec2::Zero()), f(mesh.NumNodes(), Vec2::Zero());
    double energy = 0.0;
    effect->AddForces(mesh.rest_positions, v, f, &energy);
    EXPECT_NEAR(energy, 0.0, 1e-12) << name;
    for (const Vec2& fi : f) EXPECT_LT(fi.norm(), 1e-10) << name;

    Deform(*effect, mesh, 3.0, 9);
    auto x = Perturbed(mesh.rest_positions, 2.0, 10);
    const double e = effect->Energy(x);
    EXPECT_GT(std::abs(e), 0.0) << name;
    const double c = std::cos(-2.3), s = std::sin(-2.3);
    for (Vec2& q : x) q = Vec2(c * q.x() - s * q.y(), s * q.x() + c * q.y()) + Vec2(55.5, -12.25);
    EXPECT_NEAR(effect->Energy(x), e, 1e-9 * std::max(1.0, std::abs(e))) << name;
  }
}

// The stateful effects return to the rest state on Reset: the forces after
// Reset are those of a fresh effect, bit for bit.
TEST(EffectTerms, ResetForgetsTheHistory) {
  const Mesh mesh = MakeGridMesh(4, 3, 10.0);
  for (const std::string name : {"plasticity", "viscoelastic"}) {
    const auto used = Configured(name, mesh);
    Deform(*used, mesh, 4.0, 3);
    used->Reset();
    const auto fresh = Configured(name, mesh);
    const auto x = Perturbed(mesh.rest_positions, 2.0, 4);
    std::vector<Vec2> v(x.size(), Vec2::Zero()), f1(x.size(), Vec2::Zero()), f2 = f1;
    used->AddForces(x, v, f1, nullptr);
    fresh->AddForces(x, v, f2, nullptr);
    EXPECT_EQ(f1, f2) << name;
  }
}

// The gravity of inertia: m g on every node, along the angle in image axes.
TEST(EffectTerms, GravityIsTheBodyForceAlongItsAngle) {
  const Mesh mesh = MakeGridMesh(2, 2, 10.0);
  const auto effect = MakeEffect("inertia");
  effect->Bind(mesh);
  ParameterValues values = AllValues();
  values["gravity_px_s2"] = 1000.0;
  values["gravity_angle_deg"] = 90.0;  // down the image
  effect->Configure(values, CatalogueBase());
  std::vector<Vec2> v(mesh.NumNodes(), Vec2::Zero()), f(mesh.NumNodes(), Vec2::Zero());
  effect->AddForces(mesh.rest_positions, v, f, nullptr);
  for (const Vec2& fi : f) {
    EXPECT_NEAR(fi.x(), 0.0, 1e-12);
    EXPECT_NEAR(fi.y(), CatalogueBase().mass * 1000.0, 1e-12);
  }
  EXPECT_EQ(effect->SecondOrderDamping(), std::optional<double>(2.0));
}

}  // namespace
}  // namespace calib
