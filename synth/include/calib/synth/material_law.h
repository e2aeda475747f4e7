#pragma once
// Which hyperelastic law the truth model's material follows: the
// compressible neo-Hookean law (neo_hookean.h, the default) or the
// logarithmic-strain Hencky law (hencky.h). Both read the same Lame pair
// (PlaneStressLame of E and nu) and agree at small strains.

#include "calib/synth/neo_hookean.h"

#include <string>

namespace calib::synth {

enum class MaterialLaw { kNeoHookean, kHencky };

/// "neo_hookean" or "hencky".
std::string ToString(MaterialLaw law);
/// The law named `text`; throws std::invalid_argument naming it otherwise.
MaterialLaw MaterialLawFromString(const std::string& text);

/// The law's energy density (NeoHookeanDensity or HenckyDensity).
EnergyDensity DensityOf(MaterialLaw law);

}  // namespace calib::synth
