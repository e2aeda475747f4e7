#pragma once
// A calibration request: what RunCalibration (runner.h) searches and how:
// the parameters (a box each, or fixed), the optimiser and its settings, the
// budget, the seed, checkpoints and the failure policy. It says nothing of
// what is evaluated (the objective) or where results go (the store): a job
// spec (job_spec.h) is a request plus its recordings, model and results,
// and `calib loop` builds requests directly for its stage calibrations.
//
// The search space: the optimiser searches the unit box [0, 1]^n, one
// coordinate per searched parameter in the order of `parameters`. Coordinate
// u maps to lower + u (upper - lower) on a linear scale and to
// exp(ln lower + u (ln upper - ln lower)) on a log scale (SearchSpace below).
// Optimiser settings that hold points (x0 of cmaes / nlopt) are therefore in
// unit-box coordinates.

#include "calib/core/parameters.h"
#include "calib/search/checked_optimizer.h"
#include "calib/search/types.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace calib {

/// One model parameter: searched within [lower, upper] (both finite,
/// lower < upper, inside the parameter's allowed range; log scale: lower > 0)
/// or held fixed at `fixed`.
struct ParameterSetting {
  std::string name;
  std::optional<double> fixed;  ///< set: not searched
  double lower = 0.0;           ///< searched only
  double upper = 0.0;           ///< searched only
  ParameterScale scale = ParameterScale::kLinear;

  bool searched() const { return !fixed.has_value(); }
};

struct OptimizerSpec {
  std::string name;  ///< a name search::OptimizerNames() lists
  /// What search::MakeOptimizer receives: the spec's settings object, plus
  /// the optimiser's own evaluation budget set to budget.evaluations when the
  /// spec leaves it out (max_evals for grid, random, annealing, cmaes;
  /// maxeval for nlopt:*; genetic's budget follows population and
  /// generations).
  nlohmann::json settings = nlohmann::json::object();
};

struct BudgetSpec {
  int64_t evaluations = 0;            ///< >= 1; the runner never evaluates more
  std::optional<double> wall_time_s;  ///< > 0 when set; the runner stops (resumably) after it
  /// > 1 when set: candidates whose score so far exceeds this factor times
  /// the best score before them are stopped and recorded as pruned
  /// (pruning.h). Unset: none is.
  std::optional<double> prune_factor;
};

/// A checkpoint is written when either trigger fires (0 disables a trigger;
/// at least one is on). The runner checkpoints between batches.
struct CheckpointSpec {
  int64_t every_evaluations = 100;
  double every_seconds = 60.0;
};

enum class FailureMode {
  kPenalty,  ///< record the failure; tell the optimiser failed (or penalty_score)
  kRetry,    ///< re-evaluate up to max_retries times, then as kPenalty
  kAbort,    ///< as kPenalty, and stop the job after abort_after failures
};
std::string ToString(FailureMode mode);  ///< "penalty" / "retry" / "abort"
/// Throws std::invalid_argument naming the value.
FailureMode FailureModeFromString(const std::string& name);

/// What happens to a candidate whose evaluation failed (its simulation blew
/// up or its worker was lost). Every failure is recorded with its reason.
struct FailurePolicy {
  FailureMode mode = FailureMode::kPenalty;
  /// Unset: the optimiser is told the evaluation failed (worse than any
  /// finite score). Set (finite): the optimiser is told this score instead.
  std::optional<double> penalty_score;
  int max_retries = 1;      ///< kRetry: >= 1 further attempts
  int64_t abort_after = 0;  ///< stop the job after this many failed candidates; 0: never
                            ///< (kAbort: >= 1, default 1)
};

/// Everything a calibration needs besides the objective and the store.
struct CalibrationRequest {
  std::string name;  ///< names the calibration in messages and the store
  std::vector<ParameterSetting> parameters;  ///< the search space, in coordinate order
  OptimizerSpec optimizer;
  BudgetSpec budget;
  uint64_t seed = 1;
  CheckpointSpec checkpoint;
  FailurePolicy failure_policy;

  /// The names of the searched parameters, in search-space order.
  std::vector<std::string> SearchedNames() const;
};

/// Maps the optimiser's unit box to parameter values and back.
class SearchSpace {
 public:
  /// From a validated spec's parameters.
  explicit SearchSpace(const std::vector<ParameterSetting>& parameters);
  explicit SearchSpace(const CalibrationRequest& request) : SearchSpace(request.parameters) {}

  int dimension() const { return static_cast<int>(searched_.size()); }
  /// Searched parameter names, coordinate order.
  std::vector<std::string> names() const;
  /// [0, 1]^n.
  search::Bounds UnitBounds() const;

  /// Every parameter (searched and fixed) for the point u of the unit box
  /// (size dimension(); each coordinate clamped to [0, 1]). Results are
  /// clamped to [lower, upper] so rounding in exp/log never leaves the
  /// bounds; u = 0 and u = 1 give lower and upper exactly.
  ParameterValues ToParameters(std::span<const double> u) const;
  /// The unit-box point of the searched values in `values` (which must hold
  /// every searched name; std::invalid_argument otherwise). Values outside
  /// [lower, upper] map outside [0, 1].
  std::vector<double> ToUnit(const ParameterValues& values) const;

 private:
  struct Axis {
    std::string name;
    double lower, upper;
    bool log;
  };
  std::vector<Axis> searched_;
  ParameterValues fixed_;
};

/// The request's optimiser: search::MakeOptimizer(request.optimizer.name,
/// request.optimizer.settings, SearchSpace(request).UnitBounds(),
/// request.seed).
search::CheckedOptimizer MakeRequestOptimizer(const CalibrationRequest& request);

}  // namespace calib
