// Random search: independent points uniform in the box; the baseline every
// other optimiser is tested against at equal budget.
//
// Settings (JSON object):
//   max_evals   integer >= 1   default 200
#pragma once

#include <cstdint>
#include <memory>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"

namespace calib::search {

struct RandomSearchOptions {
  int64_t max_evals = 200;

  static RandomSearchOptions FromJson(const nlohmann::json& settings);
};

std::unique_ptr<Optimizer> MakeRandomSearch(const RandomSearchOptions& options,
                                            const Bounds& bounds, uint64_t seed);

}  // namespace calib::search
