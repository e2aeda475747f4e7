// NLopt's derivative-free, bound-constrained algorithms behind ask/tell.
//
// NLopt runs its own loop and cannot save its state, so ask/tell is a
// replay: each time a new point is needed, nlopt_optimize restarts from
// scratch with the same settings and the same RNG seed (nlopt_srand), and
// the objective callback answers the first k calls from the k evaluations
// already told, in order. The (k+1)-th call is the next candidate: it is
// recorded and NLopt is stopped (nlopt_force_stop). Every replayed point is
// checked to be bitwise equal to the stored one; a mismatch (NLopt not
// deterministic) throws std::logic_error. No exception leaves the C
// callback. When NLopt returns by itself (maxeval, a tolerance, roundoff),
// the optimiser is done. Saved state = the told evaluations; restore
// replays. Cost: replaying k evaluations for candidate k, i.e. O(N^2)
// callback calls over a run, negligible beside a simulation. Replays hold a
// process-wide mutex, because NLopt's RNG may be shared between threads.
// One candidate per Ask. maxeval is a hard limit: where NLopt itself would
// evaluate past it (CRS2_LM's initial population), the adapter stops.
//
// A failed evaluation is reported to NLopt as `failure_value` if set, else
// as worst + max(1, worst - best) over the finite values told before it (in
// ask order), or 1e10 if none; deterministic on replay. Points NLopt asks
// for are clipped to the box (the listed algorithms honour bounds; this is a
// guard), the raw point is what replay compares.
//
// Algorithms (ALGO in "nlopt:ALGO"): local BOBYQA, COBYLA, NELDERMEAD, SBPLX;
// global DIRECT (GN_DIRECT), DIRECT_L (GN_DIRECT_L), CRS2_LM (GN_CRS2_LM),
// ISRES (GN_ISRES), ESCH (GN_ESCH), MLSL (G_MLSL_LDS: multi-level single
// linkage on a low-discrepancy sequence, with `local_algorithm` as its local
// optimiser).
//
// Settings (JSON object):
//   maxeval          integer >= 1                         default 200
//   xtol_rel         number >= 0 (0: off)                 default 1e-8
//   ftol_rel         number >= 0 (0: off)                 default 0
//   x0               array of n numbers in the box        default: box centre
//   initial_step     number > 0, fraction of width        default: NLopt's
//   population       integer >= 0 (0: NLopt's default)    default 0; CRS2_LM, ISRES, ESCH, MLSL
//   local_algorithm  BOBYQA, COBYLA, NELDERMEAD or SBPLX  default "BOBYQA"; MLSL only
//   local_xtol_rel   number > 0                           default 1e-4; MLSL only
//   local_maxeval    integer >= 0 (0: none)               default 0; MLSL only
//   failure_value    finite number                        default: adaptive, above
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"

namespace calib::search {

struct NloptOptions {
  std::string algorithm;  // e.g. "BOBYQA"
  int maxeval = 200;
  double xtol_rel = 1e-8;
  double ftol_rel = 0.0;
  std::optional<std::vector<double>> x0;
  std::optional<double> initial_step;
  int population = 0;
  std::string local_algorithm = "BOBYQA";
  double local_xtol_rel = 1e-4;
  int local_maxeval = 0;
  std::optional<double> failure_value;

  static NloptOptions FromJson(const std::string& algorithm, const nlohmann::json& settings,
                               const Bounds& bounds);
};

// The ALGO names accepted, in the order listed above.
std::vector<std::string> NloptAlgorithmNames();

std::unique_ptr<Optimizer> MakeNlopt(const NloptOptions& options, const Bounds& bounds,
                                     uint64_t seed);

}  // namespace calib::search
