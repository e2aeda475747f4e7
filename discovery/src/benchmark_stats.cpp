// The loop benchmark's statistics (benchmark_stats.h).

#include "calib/discovery/benchmark_stats.h"

#include <fmt/format.h>

#include <algorithm>
#include <set>
#include <stdexcept>

namespace calib {

Proportion WilsonInterval(int64_t successes, int64_t trials, double z) {
  if (successes < 0 || successes > trials || !(z > 0.0)) {
    throw std::invalid_argument(fmt::format(
        "WilsonInterval: successes = {}, trials = {}, z = {}. Violated: 0 <= successes <= "
        "trials, z > 0.",
        successes, trials, z));
  }
  Proportion out;
  out.successes = successes;
  out.trials = trials;
  if (trials == 0) return out;
  const double n = static_cast<double>(trials);
  const double p = static_cast<double>(successes) / n;
  const double z2 = z * z;
  const double denominator = 1.0 + z2 / n;
  const double centre = (p + z2 / (2.0 * n)) / denominator;
  const double half = z / denominator * std::sqrt(p * (1.0 - p) / n + z2 / (4.0 * n * n));
  out.rate = p;
  out.lower = std::max(0.0, centre - half);
  out.upper = std::min(1.0, centre + half);
  return out;
}

double SortedQuantile(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return NAN;
  const double rank = (static_cast<double>(sorted.size()) - 1.0) * std::clamp(p, 0.0, 1.0);
  const size_t below = static_cast<size_t>(std::floor(rank));
  const size_t above = std::min(below + 1, sorted.size() - 1);
  const double share = rank - static_cast<double>(below);
  return sorted[below] + share * (sorted[above] - sorted[below]);
}

Quartiles QuartilesOf(std::vector<double> values) {
  values.erase(std::remove_if(values.begin(), values.end(), [](double v) { return std::isnan(v); }),
               values.end());
  Quartiles q;
  q.count = static_cast<int>(values.size());
  if (values.empty()) return q;
  std::sort(values.begin(), values.end());
  q.min = values.front();
  q.q1 = SortedQuantile(values, 0.25);
  q.median = SortedQuantile(values, 0.5);
  q.q3 = SortedQuantile(values, 0.75);
  q.max = values.back();
  return q;
}

int64_t ConfusionTable::At(const std::string& row, const std::string& column) const {
  const auto r = std::find(rows.begin(), rows.end(), row);
  const auto c = std::find(columns.begin(), columns.end(), column);
  if (r == rows.end() || c == columns.end()) return 0;
  return counts[r - rows.begin()][c - columns.begin()];
}

ConfusionTable CountConfusion(const std::vector<std::string>& effects,
                              const std::vector<PresentKept>& objects) {
  std::set<std::string> others;
  const auto note = [&](const std::string& name) {
    if (!name.empty() && std::find(effects.begin(), effects.end(), name) == effects.end()) {
      others.insert(name);
    }
  };
  for (const PresentKept& o : objects) {
    note(o.present);
    for (const std::string& k : o.kept) note(k);
  }
  ConfusionTable t;
  t.rows = effects;
  t.rows.insert(t.rows.end(), others.begin(), others.end());
  t.columns = t.rows;
  t.rows.emplace_back(kNoEffect);
  t.columns.emplace_back(kNothingKept);
  t.counts.assign(t.rows.size(), std::vector<int64_t>(t.columns.size(), 0));
  t.row_objects.assign(t.rows.size(), 0);
  const auto index = [](const std::vector<std::string>& labels, const std::string& name) {
    return static_cast<size_t>(std::find(labels.begin(), labels.end(), name) - labels.begin());
  };
  for (const PresentKept& o : objects) {
    const size_t row = index(t.rows, o.present.empty() ? std::string(kNoEffect) : o.present);
    ++t.row_objects[row];
    if (o.kept.empty()) ++t.counts[row][index(t.columns, kNothingKept)];
    for (const std::string& k : o.kept) ++t.counts[row][index(t.columns, k)];
  }
  return t;
}

}  // namespace calib
