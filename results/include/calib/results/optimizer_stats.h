#pragma once
// The statistics of an optimiser comparison (`calib compare-optimizers`,
// docs/compare.md): quantiles, best-so-far curves, the Mann-Whitney
// rank-sum test with its effect sizes, Holm's correction, and COCO's
// fixed-target measures (expected running time, the runtime ECDF). Pure
// functions on plain numbers; scores are minimised (lower is better).
//
// tests/results/optimizer_stats_test.cpp checks them against SciPy
// (scripts/optimizer-stats-expected.py writes the expected values).

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace calib::optimizer_stats {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The q-quantile (0 <= q <= 1) of the values by linear interpolation
/// between order statistics (Hyndman & Fan type 7: numpy's "linear",
/// scipy.stats.mstats.mquantiles with alphap = betap = 1). NaN values are
/// left out; NaN when none is left.
double Quantile(std::span<const double> values, double q);

/// The best (lowest) score so far after each evaluation, in evaluation
/// order: out[i] = min of scores[0..i] that are not NaN (a failed
/// evaluation is NaN); NaN until the first finished one.
std::vector<double> BestSoFar(std::span<const double> scores);

/// The two-sided Mann-Whitney U (Wilcoxon rank-sum) test of two samples,
/// by the normal approximation with the tie correction and the continuity
/// correction: scipy.stats.mannwhitneyu(x, y, alternative="two-sided",
/// method="asymptotic"), which is SciPy's default method for samples of
/// more than 8 or with ties.
struct RankSumTest {
  double u = kNaN;        ///< U of x: pairs (x_i, y_j) with x_i > y_j, ties counted 1/2 (SciPy's U1)
  double z = kNaN;        ///< standardised max(U, n m - U), continuity corrected
  double p_value = kNaN;  ///< two-sided; 1 when every value is tied
  /// Vargha-Delaney A of x over y: P(X > Y) + P(X = Y) / 2 = U / (n m).
  /// For scores (lower is better), 1 - A is the chance that a run of x
  /// ends lower than a run of y.
  double a12 = kNaN;
  double rank_biserial = kNaN;  ///< 2 A - 1, in [-1, 1]
};
/// Both samples non-empty (else every field NaN). NaN values are left out.
RankSumTest MannWhitneyU(std::span<const double> x, std::span<const double> y);

/// Holm's step-down adjustment of `p_values` for multiple comparisons, in
/// the order given: sort ascending, p_(i) (m - i) for i = 0.., running
/// maximum, capped at 1. Rejecting where the adjusted p <= alpha controls
/// the family-wise error rate at alpha.
std::vector<double> HolmAdjust(std::span<const double> p_values);

/// The evaluations a best-so-far curve takes to reach `target` (score <=
/// target): 1 + the index of the first such element; -1 when never.
int64_t EvaluationsToTarget(std::span<const double> best_so_far, double target);

/// One run against one target: how many evaluations it used, and after
/// how many it reached the target (-1: it did not).
struct TargetRun {
  int64_t evaluations = 0;
  int64_t hit = -1;
};

/// COCO's expected running time: the evaluations of every run (up to its
/// hit for a successful one, all of them for the others) summed, over the
/// number of successful runs. +infinity when no run succeeded, NaN for no
/// runs.
double ExpectedRunningTime(std::span<const TargetRun> runs);

/// The empirical cumulative distribution of runtimes over (run, target)
/// pairs, as in COCO: the fraction of `hits` (evaluations to reach a
/// target, -1: never) that are >= 1 and <= `budget`. NaN for no pairs.
double FractionReached(std::span<const int64_t> hits, int64_t budget);

}  // namespace calib::optimizer_stats
