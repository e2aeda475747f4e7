#pragma once
// What the closed loop did on one object of a family (loop_benchmark.h):
// the object's effect as the manifest states it, the effects the loop kept,
// the first round's hypotheses, the training and held-out XOR sums of the
// base and the final model, and the sensitivity of the held-out error to a
// 0.1 % nudge of the fits. Read off the object's LoopReport; written as
// DIR/objects/<id>/summary.json and one row of DIR/benchmark.csv.

#include "calib/discovery/family_manifest.h"
#include "calib/discovery/loop_report.h"

#include <nlohmann/json_fwd.hpp>

#include <cmath>
#include <string>
#include <vector>

namespace calib {

/// An effect the loop kept, and the held-out XOR sum (over every held-out
/// recording) of the model before it was added and of the model with it.
struct KeptEffectChange {
  std::string effect;
  double holdout_xor_before = NAN;
  double holdout_xor_after = NAN;

  /// (after - before) / before; NaN without a held-out sum.
  double Relative() const;
};

/// A hypothesis of the first round (the base model's residual).
struct HypothesisConfidence {
  std::string effect;
  double confidence = 0.0;
};

struct ObjectOutcome {
  // From the manifest (FamilyObject; empty: null).
  std::string id;
  std::string cell;
  std::string effect;
  std::string loop_effect;
  std::string magnitude;
  std::string confusable_with;

  /// "ok"; "error" when the loop threw (`error` holds its message);
  /// "not_made" when the generator could not make the object's recordings
  /// (`error` holds its reason; the loop did not run).
  std::string status = "ok";
  std::string error;
  /// Read back from an earlier run's report.json instead of run.
  bool resumed = false;

  std::vector<std::string> effects_kept;          ///< in the order kept
  std::vector<HypothesisConfidence> first_round;  ///< ranked, best first
  /// XOR sums over the training / held-out recordings of the base and the
  /// final model (NaN: no such recording, or not measured).
  double train_xor_before = NAN;
  double train_xor_after = NAN;
  double holdout_xor_before = NAN;
  double holdout_xor_after = NAN;
  /// holdout_sensitivity_px of the base and the final stage (px).
  double base_sensitivity_px = NAN;
  double final_sensitivity_px = NAN;
  std::vector<KeptEffectChange> kept_changes;  ///< one per kept effect
  double run_time_s = NAN;                     ///< the loop's run time

  bool ok() const { return status == "ok"; }
  bool NotMade() const { return status == kNotMadeStatus; }
  static constexpr const char* kNotMadeStatus = "not_made";
  /// The first round's top-ranked effect; empty when there was none.
  std::string TopHypothesis() const;
  /// The first round's confidence of `effect`; NaN when not ranked.
  double FirstRoundConfidence(const std::string& effect) const;
  /// The object's loop effect was kept.
  bool Detected() const;
  /// An effect was kept that the object does not have.
  bool FalseDiscovery() const;
  /// The object's confusable_with effect was kept.
  bool ConfusableKept() const;
  /// (holdout_xor_after - holdout_xor_before) / holdout_xor_before.
  double HoldoutChange() const;
  /// The larger of the base and the final stage's sensitivity relative to
  /// its held-out XOR sum; NaN without held-out recordings.
  double MaxSensitivityRelative() const;
  /// The change of `effect` among kept_changes, or nullptr.
  const KeptEffectChange* ChangeOf(const std::string& effect) const;
};

/// The outcome of `object` from its loop's report.
ObjectOutcome SummariseObject(const FamilyObject& object, const LoopReport& report);
/// The outcome of `object` whose loop threw `message`.
ObjectOutcome FailedObject(const FamilyObject& object, const std::string& message,
                           double run_time_s);
/// The outcome of `object` that the generator did not make (its not_made).
ObjectOutcome NotMadeObject(const FamilyObject& object);

/// summary.json: every field above, plus the derived ones (top_hypothesis,
/// detected, false_discovery, confusable_kept, holdout_change,
/// max_sensitivity_relative; ignored on reading). NaN is written as null.
nlohmann::json ToJson(const ObjectOutcome& outcome);
/// Reads what ToJson writes. Throws std::invalid_argument naming `source`
/// and the key.
ObjectOutcome ObjectOutcomeFromJson(const nlohmann::json& doc, const std::string& source);

/// The columns of benchmark.csv: the manifest's fields, status, error,
/// resumed, effects_kept (';'-separated), detected, false_discovery,
/// confusable_kept (1 / 0, empty for an error), top_hypothesis,
/// top_confidence, the XOR sums, holdout_change, the sensitivities,
/// max_sensitivity_relative, run_time_s, then per effect of `effects`
/// "confidence:<effect>" (first round) and "kept_change:<effect>" (the
/// relative held-out change when kept). Empty fields for NaN / not
/// applicable.
std::vector<std::string> OutcomeCsvHeader(const std::vector<std::string>& effects);
std::vector<std::string> OutcomeCsvRow(const ObjectOutcome& outcome,
                                       const std::vector<std::string>& effects);

}  // namespace calib
