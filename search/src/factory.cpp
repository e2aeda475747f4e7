#include "calib/search/factory.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "calib/search/annealing.h"
#include "calib/search/cmaes.h"
#include "calib/search/external_optimizer.h"
#include "calib/search/genetic.h"
#include "calib/search/grid.h"
#include "calib/search/nlopt_optimizer.h"
#include "calib/search/random_search.h"

namespace calib::search {

std::vector<std::string> OptimizerNames() {
  std::vector<std::string> names = {"grid", "random", "genetic", "annealing", "cmaes"};
  for (const auto& algo : NloptAlgorithmNames()) names.push_back("nlopt:" + algo);
  return names;
}

std::vector<std::string> AllOptimizerNames() {
  std::vector<std::string> names = OptimizerNames();
  names.push_back("external");
  return names;
}

CheckedOptimizer MakeOptimizer(std::string_view name_view, const nlohmann::json& settings,
                               const Bounds& bounds, uint64_t seed) {
  const std::string name(name_view);
  ValidateBounds(bounds);
  const int n = bounds.dimension();
  std::unique_ptr<Optimizer> plugin;
  if (name == "grid") {
    plugin = MakeGrid(GridOptions::FromJson(settings, n), bounds);
  } else if (name == "random") {
    plugin = MakeRandomSearch(RandomSearchOptions::FromJson(settings), bounds, seed);
  } else if (name == "genetic") {
    plugin = MakeGenetic(GeneticOptions::FromJson(settings, n), bounds, seed);
  } else if (name == "annealing") {
    plugin = MakeAnnealing(AnnealingOptions::FromJson(settings), bounds, seed);
  } else if (name == "cmaes") {
    plugin = MakeCmaes(CmaesOptions::FromJson(settings, bounds), bounds, seed);
  } else if (name.rfind("nlopt:", 0) == 0) {
    plugin = MakeNlopt(NloptOptions::FromJson(name.substr(6), settings, bounds), bounds, seed);
  } else if (name == "external") {
    plugin = MakeExternal(ExternalOptions::FromJson(settings), bounds, seed);
  } else {
    throw std::invalid_argument(fmt::format("optimiser '{}' is unknown. Violated: the name is one of {}",
                                            name, fmt::join(AllOptimizerNames(), ", ")));
  }
  return CheckedOptimizer(std::move(plugin), bounds);
}

namespace {

bool IsNlopt(const std::string& name) { return name.rfind("nlopt:", 0) == 0; }

}  // namespace

std::string BudgetSetting(std::string_view name_view) {
  const std::string name(name_view);
  if (name == "grid" || name == "random" || name == "annealing" || name == "cmaes" || name == "external") {
    return "max_evals";
  }
  return IsNlopt(name) ? "maxeval" : "";
}

bool SeedIndependent(std::string_view name) {
  static const char* const kNames[] = {"grid",         "nlopt:BOBYQA", "nlopt:COBYLA",
                                       "nlopt:NELDERMEAD", "nlopt:SBPLX", "nlopt:DIRECT",
                                       "nlopt:DIRECT_L", "nlopt:MLSL"};
  return std::find(std::begin(kNames), std::end(kNames), name) != std::end(kNames);
}

bool BudgetExtendsExactly(std::string_view name) {
  return name == "random" || name == "cmaes" || name == "genetic";
}

nlohmann::json WithBudget(std::string_view name, nlohmann::json settings, int64_t evaluations) {
  if (settings.is_null()) settings = nlohmann::json::object();
  const std::string key = BudgetSetting(name);
  if (!key.empty() && settings.is_object() && !settings.contains(key)) settings[key] = evaluations;
  return settings;
}

nlohmann::json StartSettings(std::string_view name_view, int dimension, const std::vector<double>* x0,
                             double step, int64_t evaluations) {
  const std::string name(name_view);
  nlohmann::json settings = nlohmann::json::object();
  if (name == "cmaes") {
    // Generations of 4 + 3 ln n candidates (the CMA-ES default), at least
    // 8 so that two threads and more stay busy (never more than the
    // budget).
    const int64_t population = std::max(8, 4 + static_cast<int>(3.0 * std::log(dimension)));
    settings["population"] = std::max<int64_t>(2, std::min(population, evaluations));
    settings["initial_sigma"] = step;
    if (x0 != nullptr) settings["x0"] = *x0;
  } else if (IsNlopt(name) && x0 != nullptr) {
    settings["x0"] = *x0;
  }
  return settings;
}

}  // namespace calib::search
