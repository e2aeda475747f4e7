// The catalogue of effects, the defaults of EffectTerm's hooks and the model
// definition built from effect names.

#include <fmt/format.h>

#include <stdexcept>

#include "calib/core/effects.h"
#include "calib/core/model_definition.h"
#include "effect_factories.h"

namespace calib {

// The effects' constructors, one per file of this folder. A new effect is
// its file, a declaration here and a row of kEntries.
namespace effects {
std::unique_ptr<EffectTerm> MakeInertiaEffect();
std::unique_ptr<EffectTerm> MakeTableFrictionEffect();
std::unique_ptr<EffectTerm> MakePlasticityEffect();
std::unique_ptr<EffectTerm> MakeUnevenStiffnessEffect();
std::unique_ptr<EffectTerm> MakeStrainStiffeningEffect();
std::unique_ptr<EffectTerm> MakeViscoelasticEffect();
std::unique_ptr<EffectTerm> MakePushRelaxationEffect();
}  // namespace effects

namespace {

using Factory = std::unique_ptr<EffectTerm> (*)();

struct CatalogueEntry {
  const char* name;
  Factory make;
};

// The order of EffectTermCatalogue() and of the names in messages.
constexpr CatalogueEntry kEntries[] = {
    {"inertia", &effects::MakeInertiaEffect},
    {"table_friction", &effects::MakeTableFrictionEffect},
    {"plasticity", &effects::MakePlasticityEffect},
    {"uneven_stiffness", &effects::MakeUnevenStiffnessEffect},
    {"strain_stiffening", &effects::MakeStrainStiffeningEffect},
    {"viscoelastic", &effects::MakeViscoelasticEffect},
    {"push_relaxation", &effects::MakePushRelaxationEffect},
};

}  // namespace

void EffectTerm::AddForces(std::span<const Vec2>, std::span<const Vec2>, std::span<Vec2>,
                           double*) const {}

void EffectTerm::AfterSubstep(std::span<const Vec2>, double) {}

void EffectTerm::AfterFrame(std::span<const Vec2>, double) {}

void EffectTerm::LimitStep(std::span<const Vec2>, std::span<const double>, std::span<Vec2>,
                           const StepInfo&) const {}

PushSplit EffectTerm::SplitPush(const PushInfo& push) const {
  PushSplit split;
  split.node_force = (1.0 - push.translation) * push.push;
  split.spread_total = push.translation * push.push;
  return split;
}

void EffectTerm::AddShapeStiffness(std::span<const Vec2>, EdgeStiffnessSink&) const {}

double EffectTerm::Energy(std::span<const Vec2> x) const {
  if (!info().has_energy) return 0.0;
  std::vector<Vec2> v(x.size(), Vec2::Zero()), f(x.size(), Vec2::Zero());
  double energy = 0.0;
  AddForces(x, v, f, &energy);
  return energy;
}

const std::vector<EffectInfo>& EffectTermCatalogue() {
  static const std::vector<EffectInfo> catalogue = [] {
    std::vector<EffectInfo> out;
    for (const CatalogueEntry& entry : kEntries) out.push_back(entry.make()->info());
    return out;
  }();
  return catalogue;
}

std::string EffectNames() {
  std::string out;
  for (const CatalogueEntry& entry : kEntries)
    out += (out.empty() ? "" : ", ") + std::string(entry.name);
  return out;
}

std::unique_ptr<EffectTerm> MakeEffect(const std::string& name) {
  for (const CatalogueEntry& entry : kEntries) {
    if (name == entry.name) return entry.make();
  }
  throw std::invalid_argument(
      fmt::format("unknown model effect '{}'; known effects: {}", name, EffectNames()));
}

bool ModelDefinition::IsValid(std::string* error) const {
  for (size_t i = 0; i < effects.size(); ++i) {
    bool known = false;
    for (const CatalogueEntry& entry : kEntries) known = known || effects[i] == entry.name;
    if (!known) {
      if (error != nullptr) {
        *error = fmt::format(
            "ModelDefinition::effects[{}] = '{}': unknown model effect; known effects: {}", i,
            effects[i], EffectNames());
      }
      return false;
    }
    for (size_t j = 0; j < i; ++j) {
      if (effects[j] == effects[i]) {
        if (error != nullptr) {
          *error = fmt::format(
              "ModelDefinition::effects[{}] = '{}'. Violated: each effect at most once (also "
              "effects[{}]).",
              i, effects[i], j);
        }
        return false;
      }
    }
  }
  return true;
}

std::string ModelDefinition::ToString() const {
  std::string out = "base";
  for (const std::string& name : effects) out += "+" + name;
  return out;
}

std::vector<ParameterSpec> ModelParameterSpecs(const ModelDefinition& model) {
  std::string error;
  if (!model.IsValid(&error)) throw std::invalid_argument(error);
  std::vector<ParameterSpec> specs = BaseModelParameterSpecs();
  for (const std::string& name : model.effects) {
    for (const EffectInfo& info : EffectTermCatalogue()) {
      if (info.name == name)
        specs.insert(specs.end(), info.parameters.begin(), info.parameters.end());
    }
  }
  return specs;
}

}  // namespace calib
