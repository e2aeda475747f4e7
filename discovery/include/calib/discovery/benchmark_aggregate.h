#pragma once
// The loop benchmark's rates over a family's objects (docs/loop.md, "Loop
// benchmark"). Objects whose loop failed (status "error") are counted but
// left out of every rate and of the held-out changes; their run time counts.
// Objects the generator did not make (status "not_made") are counted apart
// and left out of everything else.
//
// - confusion: effect present (rows) against effects kept (columns);
// - detection per (effect, magnitude): objects whose loop effect was kept
//   over the objects with that effect and magnitude;
// - false discoveries: objects that kept an effect they do not have, over
//   all objects, and per cell;
// - confusable: objects that kept their confusable_with effect, over the
//   objects that name one, overall and per cell;
// - held-out change of each kept effect, relative to the model before it,
//   grouped by (effect kept, the object's magnitude, or "not present" when
//   the object does not have that effect);
// - run time per object, and the largest 0.1 % nudge sensitivity relative
//   to the held-out error per object;
// - the first round's confidences as rates (confidence_rates.h).
// Every proportion carries its 95 % Wilson score interval.

#include "calib/discovery/benchmark_outcome.h"
#include "calib/discovery/benchmark_stats.h"
#include "calib/discovery/confidence_rates.h"

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <vector>

namespace calib {

/// The magnitude label of kept effects the object does not have.
inline constexpr const char* kNotPresent = "not present";

struct DetectionRate {
  std::string effect;
  std::string magnitude;  ///< empty: the manifest gave none
  Proportion detected;
};

struct CellRate {
  std::string cell;
  Proportion rate;
};

struct ConfusableRate {
  std::string cell;
  std::string effect;           ///< the objects' loop effect (empty: none)
  std::string confusable_with;  ///< the effect it can be mistaken for
  Proportion wrong_kept;        ///< objects that kept confusable_with
};

struct ChangeSummary {
  std::string effect;         ///< the effect kept
  std::string magnitude;      ///< the object's magnitude, or kNotPresent
  Quartiles relative_change;  ///< (after - before) / before of the held-out XOR sum
};

struct BenchmarkAggregate {
  int64_t objects = 0;  ///< every object, failed and not made ones included
  int64_t failed = 0;
  int64_t not_made = 0;
  int64_t resumed = 0;
  ConfusionTable confusion;
  std::vector<DetectionRate> detection;  ///< by effect order, then magnitude (faint, clear, others)
  Proportion false_discoveries;
  std::vector<CellRate> false_discoveries_per_cell;  ///< cells in order of first appearance
  Proportion confusable_wrong_kept;
  std::vector<ConfusableRate> confusable;  ///< per cell that names a confusable effect
  std::vector<ChangeSummary> holdout_change;
  Quartiles run_time_s;  ///< per object
  double total_run_time_s = 0.0;
  Quartiles max_sensitivity_relative;  ///< ObjectOutcome::MaxSensitivityRelative per object
  ConfidenceRates confidence_rates;    ///< CountConfidenceRates (no provenance)
};

/// The rates over `outcomes`; `effects` orders the effects (TracedEffects()).
BenchmarkAggregate AggregateOutcomes(const std::vector<ObjectOutcome>& outcomes,
                                     const std::vector<std::string>& effects);

/// Sorts magnitude labels for tables and plots: "faint", then "clear", then
/// others alphabetically, empty and kNotPresent last.
bool MagnitudeBefore(const std::string& a, const std::string& b);

/// The aggregate as JSON (NaN as null).
nlohmann::json ToJson(const BenchmarkAggregate& aggregate);

}  // namespace calib
