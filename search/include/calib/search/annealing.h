// Simulated annealing, adaptive, after Morris & Salisbury (2008), who
// calibrated deformable models with an annealing whose step sizes adapt to
// the acceptance ratio. The adaptive rule implemented is Corana et al.
// (1987), the standard form of that scheme:
//  - Warm-up: `warmup` uniform points; the start is the best of them and,
//    unless given, the initial temperature is the standard deviation of
//    their finite values (1 if fewer than two are finite or it is 0).
//  - A move changes one coordinate h (cycling 0..n-1) of the current point:
//    u_h + r v_h with r uniform in [-1, 1], in box-normalised units; if that
//    leaves the box, u_h is drawn uniform in it instead. Metropolis
//    acceptance at temperature T; failed evaluations are always rejected.
//  - After `steps_per_adjust` sweeps (x n moves) each v_h is adapted to keep
//    its acceptance ratio rho near 1/2: v *= 1 + c (rho - 0.6) / 0.4 if
//    rho > 0.6, v /= 1 + c (0.4 - rho) / 0.4 if rho < 0.4 (c =
//    `step_factor`), v in [1e-9, 1].
//  - After `adjusts_per_temperature` adjustments T *= `cooling` and the
//    current point returns to the best found.
// Batches (speculative annealing): one batch proposes `batch_size` moves,
// all from the current point on consecutive coordinates, never past the
// next step adjustment. They are processed in id order exactly as serial
// annealing would: the first accepted move becomes the current point and the
// batch's later moves are discarded (still counted in the budget and in the
// best so far). At low temperature, where most moves are rejected, little is
// discarded, but at the ~50% acceptance the step rule aims for, a batch of 4
// wastes about half its evaluations: on 3-D Rosenbrock at 300 evaluations
// batch_size 4 ends ~100x worse than 1. The default, 1, is plain serial
// annealing; raise it to trade evaluations for wall-clock time.
//
// Settings (JSON object):
//   max_evals                 integer >= 2                     default 200
//   warmup                    integer in [1, max_evals - 1]    default 10
//   initial_temperature       number > 0                       default: from warm-up
//   cooling                   number in (0, 1)                 default: auto, so that T
//                             falls by 1e-4 over max_evals were every evaluation a
//                             processed move (speculative batches cool less)
//   initial_step              number in (0, 1], of width       default 0.5
//   step_factor               number > 0                       default 2
//   steps_per_adjust          integer >= 1                     default 5
//   adjusts_per_temperature   integer >= 1                     default 2
//   batch_size                integer >= 1                     default 1
#pragma once

#include <cstdint>
#include <memory>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"

namespace calib::search {

struct AnnealingOptions {
  int64_t max_evals = 200;
  int warmup = 10;
  double initial_temperature = -1.0;  // <= 0: from the warm-up
  double cooling = -1.0;  // <= 0: auto from the budget
  double initial_step = 0.5;
  double step_factor = 2.0;
  int steps_per_adjust = 5;
  int adjusts_per_temperature = 2;
  int batch_size = 1;

  static AnnealingOptions FromJson(const nlohmann::json& settings);
};

std::unique_ptr<Optimizer> MakeAnnealing(const AnnealingOptions& options, const Bounds& bounds,
                                         uint64_t seed);

}  // namespace calib::search
