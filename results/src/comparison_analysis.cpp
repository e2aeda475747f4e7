// What an optimiser comparison found (comparison_analysis.h).

#include "calib/results/comparison_analysis.h"

#include "calib/results/optimizer_stats.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>

namespace calib {
namespace {

namespace stats = optimizer_stats;

// The run's best-so-far after k evaluations (k >= 1); a run that ended
// earlier (its optimiser was done) keeps its last value.
double BestAfter(const std::vector<double>& best, int64_t k) {
  if (best.empty()) return stats::kNaN;
  return best[static_cast<size_t>(std::min<int64_t>(k, static_cast<int64_t>(best.size())) - 1)];
}

Band Quartiles(double x, const std::vector<double>& values) {
  return {x, stats::Quantile(values, 0.25), stats::Quantile(values, 0.5), stats::Quantile(values, 0.75)};
}

// Best so far at each time point, where a run's evaluations finish at the
// cumulative sum of their evaluation seconds.
double BestAtTime(const std::vector<double>& best, const std::vector<double>& finish_s, double t) {
  const auto it = std::upper_bound(finish_s.begin(), finish_s.end(), t);
  if (it == finish_s.begin()) return stats::kNaN;
  return best[static_cast<size_t>(it - finish_s.begin()) - 1];
}

std::string Score(double v) { return std::isfinite(v) ? fmt::format("{:.6g}", v) : "none"; }

std::string Verdict(const ComparisonAnalysis& a) {
  if (a.optimizers.empty()) return "";
  const OptimizerSummary& best = a.optimizers.front();
  std::string out = fmt::format(
      "On this objective, at {} evaluations, {} is best (median final score {} over {} run{}).",
      a.budget, best.optimizer, Score(stats::Quantile(best.final_scores, 0.5)), best.runs,
      best.runs == 1 ? "" : "s");
  std::vector<std::string> same, worse;
  for (size_t i = 1; i < a.optimizers.size(); ++i) {
    const std::string& name = a.optimizers[i].optimizer;
    for (const PairwiseTest& p : a.pairs) {
      if (!((p.a == best.optimizer && p.b == name) || (p.b == best.optimizer && p.a == name))) continue;
      (p.significant ? worse : same).push_back(fmt::format("{} (Holm-adjusted p = {:.3g})", name, p.p_holm));
    }
  }
  const auto join = [](const std::vector<std::string>& items) {
    std::string s;
    for (size_t i = 0; i < items.size(); ++i) {
      s += (i == 0 ? "" : (i + 1 == items.size() ? " and " : ", ")) + items[i];
    }
    return s;
  };
  if (!same.empty()) {
    out += fmt::format(" {} {} indistinguishable from {} at the {:g} level.", join(same),
                       same.size() == 1 ? "is" : "are", best.optimizer, a.alpha);
  }
  if (!worse.empty()) {
    out += fmt::format(" {} {} worse.", join(worse), worse.size() == 1 ? "is" : "are");
  }
  const bool few = std::any_of(a.optimizers.begin(), a.optimizers.end(),
                               [](const OptimizerSummary& o) { return o.runs < 5; });
  if (few) {
    out += " With fewer than 5 runs of an optimiser (one for those that ignore the seed) the tests "
           "can hardly tell it apart from the others.";
  }
  return out;
}

}  // namespace

ComparisonAnalysis AnalyseComparison(const std::vector<ComparisonRunData>& runs,
                                     const ComparisonAnalysisOptions& options) {
  if (options.budget < 1) throw std::invalid_argument("comparison analysis: budget must be >= 1");
  if (runs.empty()) throw std::invalid_argument("comparison analysis: no runs");
  ComparisonAnalysis a;
  a.budget = options.budget;
  a.budget_fractions = options.budget_fractions;
  a.alpha = options.alpha;
  a.runs = runs;
  a.relative_targets = options.relative_targets;
  a.target_values = options.targets;

  // Per run: best so far and when each evaluation finished.
  std::vector<std::vector<double>> best(runs.size()), finish(runs.size());
  double best_score = std::numeric_limits<double>::infinity();
  double longest_s = 0.0;
  for (size_t r = 0; r < runs.size(); ++r) {
    best[r] = stats::BestSoFar(runs[r].scores);
    finish[r].resize(runs[r].eval_seconds.size());
    std::partial_sum(runs[r].eval_seconds.begin(), runs[r].eval_seconds.end(), finish[r].begin());
    if (!finish[r].empty()) longest_s = std::max(longest_s, finish[r].back());
    if (!best[r].empty() && std::isfinite(best[r].back())) best_score = std::min(best_score, best[r].back());
  }
  a.best_score = std::isfinite(best_score) ? best_score : stats::kNaN;
  for (double t : options.targets) {
    a.target_scores.push_back(options.relative_targets ? a.best_score + t * std::abs(a.best_score) : t);
  }

  // Optimisers in order of first appearance.
  std::vector<std::string> order;
  std::map<std::string, std::vector<size_t>> members;
  for (size_t r = 0; r < runs.size(); ++r) {
    if (!members.count(runs[r].optimizer)) order.push_back(runs[r].optimizer);
    members[runs[r].optimizer].push_back(r);
  }
  for (const std::string& name : order) {
    const std::vector<size_t>& rs = members[name];
    OptimizerSummary o;
    o.optimizer = name;
    o.runs = static_cast<int>(rs.size());
    for (size_t r : rs) {
      o.evaluations += static_cast<int64_t>(runs[r].scores.size());
      o.failed += std::count_if(runs[r].scores.begin(), runs[r].scores.end(),
                                [](double s) { return std::isnan(s); }) -
                  runs[r].pruned;
      o.pruned += runs[r].pruned;
      o.final_scores.push_back(best[r].empty() ? stats::kNaN : best[r].back());
    }
    const auto across = [&](const auto& value_of_run) {
      std::vector<double> v;
      for (size_t r : rs) v.push_back(value_of_run(r));
      return v;
    };
    for (double f : options.budget_fractions) {
      const auto k = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(f * static_cast<double>(a.budget))));
      o.fixed_budget.push_back(Quartiles(static_cast<double>(k), across([&](size_t r) { return BestAfter(best[r], k); })));
    }
    for (int64_t k = 1; k <= a.budget; ++k) {
      o.by_evaluations.push_back(
          Quartiles(static_cast<double>(k), across([&](size_t r) { return BestAfter(best[r], k); })));
    }
    for (int i = 1; i <= options.time_points && longest_s > 0.0; ++i) {
      const double t = longest_s * i / options.time_points;
      o.by_seconds.push_back(Quartiles(t, across([&](size_t r) { return BestAtTime(best[r], finish[r], t); })));
    }
    std::vector<int64_t> hits;  // every (run, target) pair
    for (double target : a.target_scores) {
      std::vector<stats::TargetRun> target_runs;
      int successes = 0;
      for (size_t r : rs) {
        const int64_t hit = std::isnan(target) ? -1 : stats::EvaluationsToTarget(best[r], target);
        target_runs.push_back({static_cast<int64_t>(runs[r].scores.size()), hit});
        hits.push_back(hit);
        if (hit >= 1) ++successes;
      }
      o.ert.push_back(stats::ExpectedRunningTime(target_runs));
      o.success_rate.push_back(static_cast<double>(successes) / static_cast<double>(rs.size()));
    }
    for (int64_t k = 1; k <= a.budget; ++k) {
      const double f = stats::FractionReached(hits, k);
      o.ecdf.push_back({static_cast<double>(k), f, f, f});
    }
    a.optimizers.push_back(std::move(o));
  }
  // Best median first; NaN (no finished run) last; ties keep spec order.
  const auto median_of = [](const OptimizerSummary& o) {
    const double m = stats::Quantile(o.final_scores, 0.5);
    return std::isnan(m) ? std::numeric_limits<double>::infinity() : m;
  };
  std::stable_sort(a.optimizers.begin(), a.optimizers.end(),
                   [&](const OptimizerSummary& x, const OptimizerSummary& y) { return median_of(x) < median_of(y); });

  std::vector<double> p_values;
  for (size_t i = 0; i < a.optimizers.size(); ++i) {
    for (size_t j = i + 1; j < a.optimizers.size(); ++j) {
      const OptimizerSummary& x = a.optimizers[i];
      const OptimizerSummary& y = a.optimizers[j];
      const stats::RankSumTest t = stats::MannWhitneyU(x.final_scores, y.final_scores);
      PairwiseTest p;
      p.a = x.optimizer;
      p.b = y.optimizer;
      p.median_a = stats::Quantile(x.final_scores, 0.5);
      p.median_b = stats::Quantile(y.final_scores, 0.5);
      p.p_value = std::isnan(t.p_value) ? 1.0 : t.p_value;
      p.a_lower = 1.0 - t.a12;
      p.rank_biserial = t.rank_biserial;
      a.pairs.push_back(p);
      p_values.push_back(p.p_value);
    }
  }
  const std::vector<double> holm = stats::HolmAdjust(p_values);
  for (size_t i = 0; i < a.pairs.size(); ++i) {
    a.pairs[i].p_holm = holm[i];
    a.pairs[i].significant = holm[i] <= a.alpha;
  }
  a.verdict = Verdict(a);
  return a;
}

}  // namespace calib
