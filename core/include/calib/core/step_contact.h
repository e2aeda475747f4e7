#pragma once
// A contact the implicit first-order step holds inside its solve
// (implicit_step.h, contact_active_set.h), as the simulator gathers it from
// the obstacles: no solver types, so the simulator's header needs only this.

#include "calib/core/types.h"

#include <array>

namespace calib {

/// A contact the implicit step keeps: the point sum_k weights[k] x[nodes[k]]
/// (a node, or a point of a boundary edge) moves along `normal` by at least
/// `gap`. `normal` is unit and points the way the obstacle pushes;
/// `obstacle_step` is the obstacle's motion over the step (the tangential
/// motion a sticking contact follows).
struct StepContact {
  std::array<int, 2> nodes{-1, -1};  ///< nodes[1] = -1: a node contact
  std::array<double, 2> weights{1.0, 0.0};
  Vec2 normal = Vec2::UnitX();
  double gap = 0.0;  ///< px
  Vec2 obstacle_step = Vec2::Zero();
};

}  // namespace calib
