#include "calib/search/factory.h"

#include <stdexcept>

#include <fmt/format.h>

#include "calib/search/annealing.h"
#include "calib/search/cmaes.h"
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
  } else {
    throw std::invalid_argument(fmt::format("optimiser '{}' is unknown. Violated: the name is one of {}",
                                            name, fmt::join(OptimizerNames(), ", ")));
  }
  return CheckedOptimizer(std::move(plugin), bounds);
}

}  // namespace calib::search
