#pragma once
// The tracer's confidences stated as rates (docs/loop.md, "Confidences as
// rates"): of the first-round hypotheses whose confidence fell in a bin on a
// family of recordings, how many named the effect the object has. A
// hypothesis of an object with no effect, or of an effect other than the
// object's, was wrong. Counted over every effect's hypotheses, and per
// effect: a confidence means different things for different signatures
// (an effect no object of the family has is never right there).
//
// The table the loop states its confidences with was measured on the tuning
// family (examples/families/tune.yaml) by `calib loop-benchmark ...
// --min-confidence 1`, which writes DIR/confidence_rates.json, and is
// compiled in from discovery/confidence_rates.json. The bins are fixed
// (ConfidenceBinEdges), not fitted to the family.

#include "calib/discovery/benchmark_outcome.h"
#include "calib/discovery/benchmark_stats.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace calib {

/// The confidences [from, to) of one bin (the last also holds 1) and how
/// often a hypothesis there was right.
struct ConfidenceBin {
  double from = 0.0;
  double to = 1.0;
  Proportion right;  ///< right hypotheses / hypotheses, 95 % Wilson interval
};

/// One effect's hypotheses by bin.
struct EffectConfidenceBins {
  std::string effect;
  std::vector<ConfidenceBin> bins;
};

struct ConfidenceRates {
  /// Where the counts come from: the family's name, spec and seed, and the
  /// benchmark's command (empty when counted in memory).
  std::string family;
  std::string family_spec;
  uint64_t family_seed = 0;
  std::string command;
  std::vector<ConfidenceBin> bins;  ///< every effect's, ConfidenceBinEdges()'s, in order
  std::vector<EffectConfidenceBins> effects;  ///< per effect traced, by name

  /// The bin holding `confidence` (clamped to [0, 1]); nullptr when there
  /// are no bins or the confidence is NaN.
  const ConfidenceBin* Find(double confidence) const;
  /// As above among `effect`'s bins; nullptr also for an effect not counted.
  const ConfidenceBin* Find(const std::string& effect, double confidence) const;
};

/// The bins' edges: 0, 0.05 (below it: no signature to speak of), 0.25,
/// 0.5, 0.75 and 1.
const std::vector<double>& ConfidenceBinEdges();

/// The rates over the first-round hypotheses of `outcomes` (objects whose
/// loop failed are left out).
ConfidenceRates CountConfidenceRates(const std::vector<ObjectOutcome>& outcomes);

/// "right on 5 of 9 (0.56 [0.27, 0.81]) tuning-family hypotheses at
/// confidence 0.50-0.75"; "no tuning-family hypothesis at ..." for an empty
/// bin.
std::string RateText(const ConfidenceBin& bin);

/// What a hypothesis of `effect` at `confidence` meant on the table's family:
/// "right on 0 of 6 push_relaxation hypotheses (0.00 [0.00, 0.39]) and on 11
/// of 26 of every effect's (...) at confidence 0.75-1.00 on the tuning
/// family"; empty when the table has no bins.
std::string RateText(const ConfidenceRates& rates, const std::string& effect, double confidence);

/// Pseudo-hypotheses of RankingRate's shrinkage: the bin's rate over every
/// effect counts as this many of the effect's own hypotheses. Chosen on the
/// tuning family, leaving one object out of the table at a time: the top
/// ranked hypothesis named the object's effect on 31 of 48 objects for any
/// value from 0.5 to 10 (30 at 20; 19 of 48 ranked by confidence).
inline constexpr double kRankingPriorHypotheses = 5.0;

/// The estimate `calib loop --rank-by rate` ranks hypotheses by: how often a
/// hypothesis of `effect` at `confidence` was right on the table's family, the
/// effect's own count in the bin shrunk toward the bin's rate over every
/// effect,
///   (right + m p) / (hypotheses + m),  m = `prior_hypotheses`,
/// so that a bin where the effect was seldom traced leans on every effect's
/// rate, and one where it often was, on its own. NaN when the table has no
/// hypothesis in the bin (or no bins).
double RankingRate(const ConfidenceRates& rates, const std::string& effect, double confidence,
                   double prior_hypotheses = kRankingPriorHypotheses);

/// One bin: from, to, right, hypotheses, rate, lower, upper (NaN as null).
nlohmann::json ToJson(const ConfidenceBin& bin);

/// confidence_rates.json ("format": "calib-confidence-rates/1").
nlohmann::json ToJson(const ConfidenceRates& rates);
/// Reads what ToJson writes; the rates and intervals are recomputed from the
/// counts. Throws std::invalid_argument naming `source` and the key (bins
/// that do not run from 0 to 1 in order, right > hypotheses, ...).
ConfidenceRates ConfidenceRatesFromJson(const nlohmann::json& doc, const std::string& source);

/// The table compiled in (discovery/confidence_rates.json), read once.
const ConfidenceRates& TuningFamilyConfidenceRates();

}  // namespace calib
