#pragma once
// What the effects of this folder share (private to core). Each effect's
// file defines its constructor, effects::Make<Name>Effect(), which
// effect_catalogue.cpp declares and lists.

#include <limits>
#include <memory>

#include "calib/core/effects.h"

namespace calib::effects {

/// +infinity, for open-ended parameter bounds.
inline constexpr double kUnbounded = std::numeric_limits<double>::infinity();

}  // namespace calib::effects
