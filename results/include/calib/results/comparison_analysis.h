#pragma once
// What an optimiser comparison found (`calib compare-optimizers`,
// docs/compare.md), from the runs' evaluations: best-so-far curves against
// evaluations and evaluation time (median and interquartile band per
// optimiser), the fixed-budget table, the fixed-target view (expected
// running time, success rates, the runtime ECDF over targets as in COCO),
// pairwise rank-sum tests of the final scores with Holm's correction and
// effect sizes, failure counts and a verdict in plain words. Scores are
// minimised. The statistics are optimizer_stats.h's.

#include <cstdint>
#include <string>
#include <vector>

namespace calib {

/// One run's evaluations, in id order.
struct ComparisonRunData {
  std::string optimizer;  ///< the optimiser's label
  uint64_t seed = 0;
  std::string job;        ///< the job's name in the store
  std::string status;     ///< the job's status ("finished", ...)
  std::vector<double> scores;        ///< per evaluation; NaN for a failed or pruned one
  int64_t pruned = 0;                ///< of those NaN, the pruned ones (stopped early)
  std::vector<double> eval_seconds;  ///< per evaluation (wall time of the evaluation)
};

struct ComparisonAnalysisOptions {
  int64_t budget = 0;                 ///< evaluations per run (>= 1)
  bool relative_targets = true;       ///< targets are fractions of the best score
  std::vector<double> targets;        ///< fractions (relative) or scores (absolute)
  std::vector<double> budget_fractions{0.1, 0.25, 0.5, 1.0};
  double alpha = 0.05;                ///< family-wise error rate of the pairwise tests
  int time_points = 100;              ///< samples of the curves against time
};

/// Median and quartiles of a quantity at one abscissa, over runs.
struct Band {
  double x = 0.0;
  double q25 = 0.0, median = 0.0, q75 = 0.0;
};

struct OptimizerSummary {
  std::string optimizer;
  int runs = 0;
  int64_t evaluations = 0;  ///< over all its runs
  int64_t failed = 0;       ///< failed evaluations over all its runs
  int64_t pruned = 0;       ///< pruned evaluations (a job's budget.prune_factor) over all its runs
  std::vector<double> final_scores;      ///< best score per run (NaN: none finished)
  /// Per budget fraction: the best-so-far's quantiles over runs (x: the
  /// evaluations that fraction of the budget is).
  std::vector<Band> fixed_budget;
  std::vector<Band> by_evaluations;      ///< x = 1..budget
  std::vector<Band> by_seconds;          ///< x = cumulative evaluation seconds
  std::vector<double> ert;               ///< per target; +inf: never reached
  std::vector<double> success_rate;      ///< per target, over runs
  std::vector<Band> ecdf;                ///< x = evaluations; median = fraction of (run, target) pairs reached
};

struct PairwiseTest {
  std::string a, b;
  double median_a = 0.0, median_b = 0.0;
  double p_value = 0.0;    ///< two-sided Mann-Whitney U of the final scores
  double p_holm = 0.0;     ///< Holm-adjusted over every pair
  double a_lower = 0.0;    ///< P(a run of a ends lower than one of b), ties 1/2: 1 - A12(a, b)
  double rank_biserial = 0.0;  ///< of a over b: 2 A12 - 1 (negative: a lower)
  bool significant = false;    ///< p_holm <= alpha
};

struct ComparisonAnalysis {
  int64_t budget = 0;
  /// The fixed-budget fractions (options.budget_fractions): fixed_budget[i]
  /// of each optimiser is at ceil(budget_fractions[i] * budget) evaluations.
  std::vector<double> budget_fractions;
  double alpha = 0.05;
  double best_score = 0.0;            ///< over every run
  std::vector<double> target_values;  ///< as given (fractions or scores)
  std::vector<double> target_scores;  ///< the scores they mean
  bool relative_targets = true;
  std::vector<OptimizerSummary> optimizers;  ///< by median final score, best first
  std::vector<PairwiseTest> pairs;           ///< every pair, in that order
  std::vector<ComparisonRunData> runs;
  /// "On this objective, at N evaluations, X is best ...".
  std::string verdict;
};

/// Analyses the runs (grouped by optimiser, optimisers in the order they
/// first appear, then sorted by median final score). Deterministic: the
/// same runs give the same analysis. Throws std::invalid_argument for a
/// budget < 1 or no runs.
ComparisonAnalysis AnalyseComparison(const std::vector<ComparisonRunData>& runs,
                                     const ComparisonAnalysisOptions& options);

}  // namespace calib
