// The statistics of an optimiser comparison (optimizer_stats.h).

#include "calib/results/optimizer_stats.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace calib::optimizer_stats {
namespace {

std::vector<double> Finite(std::span<const double> values) {
  std::vector<double> out;
  out.reserve(values.size());
  for (double v : values) {
    if (!std::isnan(v)) out.push_back(v);
  }
  return out;
}

}  // namespace

double Quantile(std::span<const double> values, double q) {
  std::vector<double> v = Finite(values);
  if (v.empty()) return kNaN;
  std::sort(v.begin(), v.end());
  const double h = q * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<size_t>(std::floor(h));
  const size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (h - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

std::vector<double> BestSoFar(std::span<const double> scores) {
  std::vector<double> out(scores.size(), kNaN);
  double best = kNaN;
  for (size_t i = 0; i < scores.size(); ++i) {
    if (!std::isnan(scores[i]) && (std::isnan(best) || scores[i] < best)) best = scores[i];
    out[i] = best;
  }
  return out;
}

RankSumTest MannWhitneyU(std::span<const double> x_in, std::span<const double> y_in) {
  const std::vector<double> x = Finite(x_in);
  const std::vector<double> y = Finite(y_in);
  RankSumTest t;
  if (x.empty() || y.empty()) return t;
  const double n1 = static_cast<double>(x.size());
  const double n2 = static_cast<double>(y.size());
  // Mid-ranks of the pooled sample.
  struct Item {
    double value;
    bool from_x;
  };
  std::vector<Item> pooled;
  for (double v : x) pooled.push_back({v, true});
  for (double v : y) pooled.push_back({v, false});
  std::sort(pooled.begin(), pooled.end(), [](const Item& a, const Item& b) { return a.value < b.value; });
  double rank_sum_x = 0.0;
  double tie_term = 0.0;  // sum of t^3 - t over groups of ties
  for (size_t i = 0; i < pooled.size();) {
    size_t j = i;
    while (j < pooled.size() && pooled[j].value == pooled[i].value) ++j;
    const double mid_rank = 0.5 * static_cast<double>(i + 1 + j);  // ranks i+1 .. j
    const double tied = static_cast<double>(j - i);
    tie_term += tied * tied * tied - tied;
    for (size_t k = i; k < j; ++k) {
      if (pooled[k].from_x) rank_sum_x += mid_rank;
    }
    i = j;
  }
  const double n = n1 + n2;
  t.u = rank_sum_x - n1 * (n1 + 1.0) / 2.0;
  t.a12 = t.u / (n1 * n2);
  t.rank_biserial = 2.0 * t.a12 - 1.0;
  const double mu = n1 * n2 / 2.0;
  const double variance = n1 * n2 / 12.0 * ((n + 1.0) - tie_term / (n * (n - 1.0)));
  const double u_max = std::max(t.u, n1 * n2 - t.u);
  if (!(variance > 0.0)) {
    t.z = 0.0;
    t.p_value = 1.0;
    return t;
  }
  t.z = (u_max - mu - 0.5) / std::sqrt(variance);
  t.p_value = std::min(1.0, std::erfc(t.z / std::sqrt(2.0)));  // 2 * upper tail
  return t;
}

std::vector<double> HolmAdjust(std::span<const double> p_values) {
  const size_t m = p_values.size();
  std::vector<size_t> order(m);
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return p_values[a] < p_values[b]; });
  std::vector<double> adjusted(m, kNaN);
  double running = 0.0;
  for (size_t i = 0; i < m; ++i) {
    const double p = std::min(1.0, static_cast<double>(m - i) * p_values[order[i]]);
    running = std::max(running, p);
    adjusted[order[i]] = running;
  }
  return adjusted;
}

int64_t EvaluationsToTarget(std::span<const double> best_so_far, double target) {
  for (size_t i = 0; i < best_so_far.size(); ++i) {
    if (best_so_far[i] <= target) return static_cast<int64_t>(i) + 1;
  }
  return -1;
}

double ExpectedRunningTime(std::span<const TargetRun> runs) {
  if (runs.empty()) return kNaN;
  double evaluations = 0.0;
  int successes = 0;
  for (const TargetRun& r : runs) {
    if (r.hit >= 1) {
      evaluations += static_cast<double>(r.hit);
      ++successes;
    } else {
      evaluations += static_cast<double>(r.evaluations);
    }
  }
  if (successes == 0) return std::numeric_limits<double>::infinity();
  return evaluations / successes;
}

double FractionReached(std::span<const int64_t> hits, int64_t budget) {
  if (hits.empty()) return kNaN;
  const auto reached = std::count_if(hits.begin(), hits.end(),
                                     [&](int64_t h) { return h >= 1 && h <= budget; });
  return static_cast<double>(reached) / static_cast<double>(hits.size());
}

}  // namespace calib::optimizer_stats
