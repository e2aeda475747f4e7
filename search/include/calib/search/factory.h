// Builds an optimiser by name, wrapped in the checks of CheckedOptimizer.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/search/checked_optimizer.h"
#include "calib/search/types.h"

namespace calib::search {

// name: "grid", "random", "genetic", "annealing", "cmaes", or "nlopt:<ALGO>"
// with ALGO one of BOBYQA, COBYLA, NELDERMEAD, SBPLX, DIRECT, DIRECT_L,
// CRS2_LM, ISRES, ESCH, MLSL. settings: a JSON object (null = all defaults)
// whose keys each optimiser's header documents; unknown keys are rejected.
// seed: every random choice derives from it.
// Throws std::invalid_argument naming the optimiser, and for a bad setting
// its key, its value and the rule it broke; bad bounds likewise.
CheckedOptimizer MakeOptimizer(std::string_view name, const nlohmann::json& settings,
                               const Bounds& bounds, uint64_t seed);

// Every name MakeOptimizer accepts.
std::vector<std::string> OptimizerNames();

}  // namespace calib::search
