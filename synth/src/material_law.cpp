#include "calib/synth/material_law.h"

#include "calib/core/enum_names.h"
#include "calib/synth/hencky.h"

namespace calib::synth {
namespace {

constexpr auto kMaterialLawNames = std::to_array<EnumName<MaterialLaw>>({
    {MaterialLaw::kNeoHookean, "neo_hookean"},
    {MaterialLaw::kHencky, "hencky"},
});

}  // namespace

std::string ToString(MaterialLaw law) { return EnumToString(kMaterialLawNames, law); }

MaterialLaw MaterialLawFromString(const std::string& text) {
  return EnumFromString(kMaterialLawNames, "material law", text);
}

EnergyDensity DensityOf(MaterialLaw law) {
  return law == MaterialLaw::kHencky ? &HenckyDensity : &NeoHookeanDensity;
}

}  // namespace calib::synth
