#pragma once
// Tracing: from the residual signatures of a fitted model (residual.h) to
// ranked hypotheses about the physical effect the model lacks, each with
// its evidence stated in numbers.
//
// Every effect of core's EffectTermCatalogue() (effects.h) has one
// residual signature here (kSignatures in hypotheses.cpp, in the
// catalogue's order); docs/effects.md describes the effects and
// docs/loop.md their signatures.
//
// Every score is a product of smooth ramps of dimensionless signature
// values (shares, ratios, correlations, residual thickness in pixels), so
// it carries over to recordings of other sizes, frame rates and rigs; no
// threshold refers to a particular recording.

#include "calib/discovery/residual.h"

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <vector>

namespace calib {

struct ConfidenceRates;

/// The effect names TraceHypotheses scores, in a fixed order (that of
/// core's EffectCatalogue()).
const std::vector<std::string>& TracedEffects();

/// One measured fact for (or against) an effect.
struct Evidence {
  std::string signature;  ///< e.g. "persistent_ratio"
  double value = 0.0;     ///< the measured number (NaN: not measurable)
  /// How strongly this fact alone supports the effect, [0, 1].
  double support = 0.0;
  std::string statement;  ///< the fact in words, with its numbers
};

struct Hypothesis {
  std::string effect;       ///< a name of TracedEffects()
  double confidence = 0.0;  ///< [0, 1]
  /// How well the recording could show this effect's signature at all, in
  /// [0, 1] (0: e.g. no release to watch for a permanent dent). Used to
  /// weight recordings when merging.
  double applicability = 0.0;
  std::string summary;      ///< one sentence: signature -> effect
  std::vector<Evidence> evidence;
  std::vector<std::string> recordings;  ///< where the evidence came from
};

/// Hypotheses for every traced effect not in `already_in_model`, most
/// confident first (ties in TracedEffects() order). Deterministic.
std::vector<Hypothesis> TraceHypotheses(const ResidualAnalysis& analysis,
                                        const std::vector<std::string>& already_in_model);

/// Merges the hypotheses of several recordings (e.g. every training
/// recording) per effect: confidence = applicability-weighted mean of the
/// recordings' confidences; evidence concatenated with the recording named.
/// Ranked as TraceHypotheses.
std::vector<Hypothesis> MergeHypotheses(const std::vector<std::vector<Hypothesis>>& per_recording);

/// `hypotheses` in the order `calib loop --rank-by rate` tries them: by the
/// rate at which a hypothesis of the same effect and confidence was right on
/// `rates`' family (RankingRate, confidence_rates.h), highest first; ties, and hypotheses the
/// table gives no rate (after those it does), by confidence, then in
/// TracedEffects() order. A confidence is a score of the signatures, not a
/// probability: on the tuning family a push_relaxation hypothesis above 0.75
/// was never right, a plasticity one at 0.5-0.75 more than half the time.
std::vector<Hypothesis> RankedByRate(std::vector<Hypothesis> hypotheses, const ConfidenceRates& rates);

/// Hypotheses in words, one per line with its top evidence (logs, reports).
std::string HypothesesReport(const std::vector<Hypothesis>& hypotheses);

nlohmann::json ToJson(const Hypothesis& hypothesis);
/// Throws std::invalid_argument naming the key on a malformed document.
Hypothesis HypothesisFromJson(const nlohmann::json& doc);

}  // namespace calib
