// CMA-ES: Hansen's standard (mu/mu_w, lambda)-CMA-ES (Hansen, "The CMA
// Evolution Strategy: A Tutorial", 2016, default parameters), written here
// on Eigen. Debian's pagmo2 has a CMA-ES, but its algorithms run their own
// evolve loop and cannot be driven ask/tell or checkpointed mid-run.
//
// It works in box-normalised coordinates u in [0, 1]^n. Bounds are handled
// by repair with penalty (Hansen's recommendation for optima on the
// boundary): a sample u outside the box is evaluated at its projection
// clip(u), and ranked by f(clip(u)) + spread * |u - clip(u)|^2 / sigma^2,
// spread being the range of the generation's finite values; the update uses
// the unrepaired sample. Failed evaluations rank last (ties by id). One
// batch = one generation of lambda candidates; only whole generations run,
// so at most max_evals are used. Stops early when sigma * sqrt(max eig C)
// < tol_x or the condition number of C exceeds 1e14.
//
// Settings (JSON object):
//   population     integer >= 2 (lambda)            default 4 + floor(3 ln n)
//   initial_sigma  number > 0, fraction of width     default 0.3
//   x0             array of n numbers in the box     default: box centre
//   max_evals      integer >= population             default 200
//   tol_x          number >= 0, fraction of width    default 1e-12
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"

namespace calib::search {

struct CmaesOptions {
  int population = 0;  // 0: default for n
  double initial_sigma = 0.3;
  std::optional<std::vector<double>> x0;
  int64_t max_evals = 200;
  double tol_x = 1e-12;

  static CmaesOptions FromJson(const nlohmann::json& settings, const Bounds& bounds);
};

std::unique_ptr<Optimizer> MakeCmaes(const CmaesOptions& options, const Bounds& bounds,
                                     uint64_t seed);

}  // namespace calib::search
