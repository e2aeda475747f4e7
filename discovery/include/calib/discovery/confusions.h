#pragma once
// Effects whose residuals look alike: deformation held by table friction
// and plasticity, an off-centre push's turn of an even object and uneven
// stiffness, slow creep (plastic flow) and viscoelastic relaxation. After
// each round the loop says for each such pair it met whether the evidence
// separated the two (which evidence, in numbers) or that these recordings
// cannot, and proposes the recording that would (docs/loop.md).

#include "calib/discovery/hypotheses.h"
#include "calib/discovery/loop_report.h"

#include <span>
#include <string>
#include <vector>

namespace calib {

struct ConfusablePair {
  const char* effect;
  /// The other effect; "" for the base model itself (no effect).
  const char* confused_with;
  /// What tells them apart, in words.
  const char* separating_evidence;
  /// The recording that would show it.
  const char* proposal;
};

/// The pairs, in a fixed order.
std::span<const ConfusablePair> ConfusablePairs();

/// What one round of the loop shows about the pairs: `ranked` its
/// hypotheses, `tried` its calibrated stages (with their keep-rule tests),
/// `load_eccentricity` the largest over the training recordings
/// (PushSummary::load_eccentricity). A pair is reported when both sides
/// were tried or traced at `min_confidence` or more; the base-model side of
/// a pair only when the push is off-centre (eccentricity >= 0.2).
std::vector<ReportConfusion> JudgeConfusions(int round, const std::vector<Hypothesis>& ranked,
                                             const std::vector<const ReportStage*>& tried,
                                             double load_eccentricity, double min_confidence);

}  // namespace calib
