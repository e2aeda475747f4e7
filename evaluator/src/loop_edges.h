#pragma once
// The directed edges of closed loops, for the rasterisers (rasterizer.cpp,
// coverage_rasterizer.cpp): each loop's last vertex joins its first.

#include "calib/core/mesh.h"

#include <vector>

namespace calib::detail {

/// Calls add(p, q) for every edge of `mesh.boundary_loops` at `positions`.
template <class AddEdge>
void ForEachBoundaryEdge(const Mesh& mesh, const Vec2* positions, AddEdge&& add) {
  for (const std::vector<int>& loop : mesh.boundary_loops) {
    const size_t n = loop.size();
    for (size_t i = 0; i < n; ++i) add(positions[loop[i]], positions[loop[i + 1 == n ? 0 : i + 1]]);
  }
}

/// Calls add(p, q) for every edge of `loops`; loops of fewer than 3
/// vertices enclose nothing and are skipped.
template <class AddEdge>
void ForEachLoopEdge(const std::vector<std::vector<Vec2>>& loops, AddEdge&& add) {
  for (const std::vector<Vec2>& loop : loops) {
    const size_t n = loop.size();
    if (n < 3) continue;
    for (size_t i = 0; i < n; ++i) add(loop[i], loop[i + 1 == n ? 0 : i + 1]);
  }
}

}  // namespace calib::detail
