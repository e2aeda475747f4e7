#pragma once
// Measurements of the closed loop's keep rule (loop.h, docs/loop.md). The
// rule itself is a statistical test (paired_test.h) that KeepCriterion
// (discovery/src/loop_stages.h) applies.

#include "calib/evaluator/bit_mask.h"
#include "calib/core/parameters.h"
#include "calib/results/store.h"

#include <vector>

namespace calib {

/// Segmentation noise of a recording: per frame, the object pixels that
/// differ from both neighbouring frames while those agree (one-frame
/// flicker, which no motion smoother than the frame rate makes). Returns the
/// mean over frames 1..n-2 (0 with fewer than 3 frames).
double SegmentationNoisePx(const std::vector<BitMask>& object_masks);

/// The successful `evaluations` of a calibration (one or more jobs of the
/// same model, scored on the same training recordings), distinct and best
/// first, without `excluded`: at most `limit` of them. Deterministic: ties
/// keep the order of `evaluations`. The candidates of a refit where the
/// best fails on a held-out recording (LoopOptions::refit_candidates).
std::vector<ParameterValues> RankedByTrainingScore(const std::vector<EvaluationRecord>& evaluations,
                                                   const ParameterValues& excluded, int limit);

/// The parameter sets of a calibration as good as its best on the training
/// recordings: the successful `evaluations` (of one or more jobs of the same
/// model) whose score is within `tolerance` of the lowest, distinct, best
/// first. With more than `limit` of them, `limit` spread evenly over their
/// ranks (the best and the last always among them), so that a fit that
/// converged keeps its spread along flat directions. Deterministic: ties
/// keep the order of `evaluations`.
std::vector<ParameterValues> SelectEquallyGoodFits(const std::vector<EvaluationRecord>& evaluations,
                                                   double tolerance, int limit);

}  // namespace calib
