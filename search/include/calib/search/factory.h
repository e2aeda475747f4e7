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

// name: "grid", "random", "genetic", "annealing", "cmaes", "nlopt:<ALGO>"
// with ALGO one of BOBYQA, COBYLA, NELDERMEAD, SBPLX, DIRECT, DIRECT_L,
// CRS2_LM, ISRES, ESCH, MLSL, or "external" (a program speaking ask/tell,
// external_optimizer.h). settings: a JSON object (null = all defaults)
// whose keys each optimiser's header documents; unknown keys are rejected.
// seed: every random choice derives from it.
// Throws std::invalid_argument naming the optimiser, and for a bad setting
// its key, its value and the rule it broke; bad bounds likewise.
CheckedOptimizer MakeOptimizer(std::string_view name, const nlohmann::json& settings,
                               const Bounds& bounds, uint64_t seed);

// The optimisers that run in this process: every name MakeOptimizer
// accepts but "external" (which needs a program to run).
std::vector<std::string> OptimizerNames();

// Every name MakeOptimizer accepts: OptimizerNames() and "external".
std::vector<std::string> AllOptimizerNames();

// What the rest of the program needs to know of an optimiser beyond
// MakeOptimizer, kept here so that a new optimiser touches search/ only.

// The setting of optimiser `name` that caps its own evaluations
// ("max_evals": grid, random, annealing, cmaes, external; "maxeval":
// nlopt:*), or ""
// where it has none (genetic: population x generations).
std::string BudgetSetting(std::string_view name);

// Whether optimiser `name` ignores its seed: the same candidates whatever
// the seed (grid; NLopt's BOBYQA, COBYLA, NELDERMEAD, SBPLX from their x0,
// DIRECT, DIRECT_L, and MLSL on its low-discrepancy sequence). A comparison runs such an optimiser once rather than
// once per seed.
bool SeedIndependent(std::string_view name);

// Whether optimiser `name`, restored from a state saved when its budget was
// used and given a larger one, proposes what a search with the larger
// budget from the start would have (`calib resume --budget`): random (its
// points do not depend on the budget), cmaes (the budget only stops it; it
// keeps whole generations) and genetic (the budget only cuts it, up to
// population x generations). Not: grid (its points are spread for the
// budget), annealing (its cooling schedule spans the budget) and nlopt:*
// (NLopt's own run is laid out for maxeval).
bool BudgetExtendsExactly(std::string_view name);

// `settings` (an object, or null for none) with BudgetSetting(name) set to
// `evaluations` where the settings leave it out.
nlohmann::json WithBudget(std::string_view name, nlohmann::json settings, int64_t evaluations);

// Settings that start a search of `dimension` unit-box coordinates at `x0`
// (null: the optimiser's own start) with an initial step of `step` (unit
// box) and a budget of `evaluations`, for the optimisers that take a start:
// cmaes (x0, initial_sigma, and generations of max(8, 4 + 3 ln n)
// candidates, never more than the budget, so that two threads and more stay
// busy) and nlopt:* (x0). Others: an empty object (they start as they do).
nlohmann::json StartSettings(std::string_view name, int dimension, const std::vector<double>* x0,
                             double step, int64_t evaluations);

}  // namespace calib::search
