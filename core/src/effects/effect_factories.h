#pragma once
// The effects' constructors (private to core): one per file of this folder,
// listed by effect_catalogue.cpp.

#include <limits>
#include <memory>

#include "calib/core/effects.h"

namespace calib::effects {

std::unique_ptr<EffectTerm> MakeInertiaEffect();
std::unique_ptr<EffectTerm> MakeTableFrictionEffect();
std::unique_ptr<EffectTerm> MakePlasticityEffect();
std::unique_ptr<EffectTerm> MakeUnevenStiffnessEffect();
std::unique_ptr<EffectTerm> MakeStrainStiffeningEffect();
std::unique_ptr<EffectTerm> MakeViscoelasticEffect();
std::unique_ptr<EffectTerm> MakePushRelaxationEffect();

/// +infinity, for open-ended parameter bounds.
inline constexpr double kUnbounded = std::numeric_limits<double>::infinity();

}  // namespace calib::effects
