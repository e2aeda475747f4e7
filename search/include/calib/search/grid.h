// Grid: the paper's systematic search, a resolution per parameter, visited
// coarse to fine so that any prefix of the sequence is a useful partial grid.
//
// Axis a with resolution r holds r evenly spaced values including both
// bounds (r = 1: the centre). Each axis orders its values by farthest-point
// refinement (the value nearest the centre first, then repeatedly the value
// farthest from those taken) and gives each value a level: the number of
// times the refinement distance has shrunk. Grid points are visited by
// increasing max-over-axes level, so after each level the points visited
// form a complete, evenly spread coarser grid (r = 5: centre; then the
// 3 x 3 x ... grid of centre and bounds; then the full grid). Within a level
// the order is lexicographic in the axes' refinement ranks, last axis
// fastest. Deterministic: the seed is unused. The grid is enumerated lazily,
// so huge grids cost no memory.
//
// Settings (JSON object):
//   resolution  integer or array of n integers, each >= 1    default 5
//   max_evals   integer >= 1, stop after this many points     default: the whole grid
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"

namespace calib::search {

struct GridOptions {
  std::vector<int> resolution;       // size n, each >= 1
  std::optional<int64_t> max_evals;  // nullopt: the whole grid

  // Throws std::invalid_argument naming "grid", the key, value and rule.
  static GridOptions FromJson(const nlohmann::json& settings, int dimension);
};

std::unique_ptr<Optimizer> MakeGrid(const GridOptions& options, const Bounds& bounds);

}  // namespace calib::search
