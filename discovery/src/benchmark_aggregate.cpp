// The loop benchmark's rates (benchmark_aggregate.h).

#include "calib/discovery/benchmark_aggregate.h"

#include "calib/evaluator/json_number.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>
#include <tuple>

namespace calib {
namespace {

using nlohmann::json;

// Successes and trials, counted by key in order of first appearance.
template <class Key>
class Tally {
 public:
  void Add(const Key& key, bool success) {
    auto it = std::find(keys_.begin(), keys_.end(), key);
    if (it == keys_.end()) {
      keys_.push_back(key);
      counts_.push_back({0, 0});
      it = keys_.end() - 1;
    }
    auto& [successes, trials] = counts_[it - keys_.begin()];
    successes += success ? 1 : 0;
    ++trials;
  }
  const std::vector<Key>& keys() const { return keys_; }
  Proportion Interval(size_t i) const {
    return WilsonInterval(counts_[i].first, counts_[i].second);
  }

 private:
  std::vector<Key> keys_;
  std::vector<std::pair<int64_t, int64_t>> counts_;
};

int MagnitudeRank(const std::string& m) {
  if (m == "faint") return 0;
  if (m == "clear") return 1;
  if (m.empty()) return 3;
  if (m == kNotPresent) return 4;
  return 2;
}

// Rows of (effect, magnitude): effects in the order of `effects` (others
// after them, by name), then magnitudes by MagnitudeBefore.
template <class Row>
void SortByEffectAndMagnitude(std::vector<Row>& rows, const std::vector<std::string>& effects) {
  const auto rank = [&](const std::string& e) {
    return std::make_pair(std::find(effects.begin(), effects.end(), e) - effects.begin(), e);
  };
  std::sort(rows.begin(), rows.end(), [&](const Row& x, const Row& y) {
    if (x.effect != y.effect) return rank(x.effect) < rank(y.effect);
    return MagnitudeBefore(x.magnitude, y.magnitude);
  });
}

json ToJson(const Proportion& p) {
  return {{"successes", p.successes},
          {"trials", p.trials},
          {"rate", JsonNumber(p.rate)},
          {"lower", JsonNumber(p.lower)},
          {"upper", JsonNumber(p.upper)}};
}

json ToJson(const Quartiles& q) {
  return {{"count", q.count},       {"min", JsonNumber(q.min)},
          {"q1", JsonNumber(q.q1)}, {"median", JsonNumber(q.median)},
          {"q3", JsonNumber(q.q3)}, {"max", JsonNumber(q.max)}};
}

json Nullable(const std::string& s) { return s.empty() ? json(nullptr) : json(s); }

// A JSON array of `to_json` of each item.
template <class T, class F>
json ListOf(const std::vector<T>& items, F to_json) {
  json list = json::array();
  for (const T& item : items) list.push_back(to_json(item));
  return list;
}

}  // namespace

bool MagnitudeBefore(const std::string& a, const std::string& b) {
  const int ra = MagnitudeRank(a), rb = MagnitudeRank(b);
  return ra != rb ? ra < rb : a < b;
}

BenchmarkAggregate AggregateOutcomes(const std::vector<ObjectOutcome>& outcomes,
                                     const std::vector<std::string>& effects) {
  BenchmarkAggregate a;
  std::vector<PresentKept> confusion_input;
  Tally<std::pair<std::string, std::string>> detection;  // (effect, magnitude)
  Tally<std::string> false_discoveries;                  // cell
  Tally<std::tuple<std::string, std::string, std::string>> confusable;
  std::map<std::pair<std::string, std::string>, std::vector<double>> changes;
  std::vector<double> run_times, sensitivities;
  int64_t false_discovered = 0, confusable_kept = 0, confusable_objects = 0;
  for (const ObjectOutcome& o : outcomes) {
    ++a.objects;
    if (o.NotMade()) {
      ++a.not_made;
      continue;
    }
    if (o.resumed) ++a.resumed;
    if (std::isfinite(o.run_time_s)) {
      run_times.push_back(o.run_time_s);
      a.total_run_time_s += o.run_time_s;
    }
    if (!o.ok()) {
      ++a.failed;
      continue;
    }
    confusion_input.push_back({o.loop_effect, o.effects_kept});
    if (!o.loop_effect.empty()) detection.Add({o.loop_effect, o.magnitude}, o.Detected());
    false_discoveries.Add(o.cell, o.FalseDiscovery());
    false_discovered += o.FalseDiscovery() ? 1 : 0;
    if (!o.confusable_with.empty()) {
      confusable.Add({o.cell, o.loop_effect, o.confusable_with}, o.ConfusableKept());
      ++confusable_objects;
      confusable_kept += o.ConfusableKept() ? 1 : 0;
    }
    for (const KeptEffectChange& c : o.kept_changes) {
      const std::string magnitude = c.effect == o.loop_effect ? o.magnitude : kNotPresent;
      changes[{c.effect, magnitude}].push_back(c.Relative());
    }
    sensitivities.push_back(o.MaxSensitivityRelative());
  }
  const int64_t judged = a.objects - a.failed - a.not_made;
  a.confusion = CountConfusion(effects, confusion_input);
  a.false_discoveries = WilsonInterval(false_discovered, judged);
  a.confusable_wrong_kept = WilsonInterval(confusable_kept, confusable_objects);
  for (size_t i = 0; i < detection.keys().size(); ++i) {
    const auto& [effect, magnitude] = detection.keys()[i];
    a.detection.push_back({effect, magnitude, detection.Interval(i)});
  }
  SortByEffectAndMagnitude(a.detection, effects);
  for (size_t i = 0; i < false_discoveries.keys().size(); ++i) {
    a.false_discoveries_per_cell.push_back(
        {false_discoveries.keys()[i], false_discoveries.Interval(i)});
  }
  for (size_t i = 0; i < confusable.keys().size(); ++i) {
    const auto& [cell, effect, with] = confusable.keys()[i];
    a.confusable.push_back({cell, effect, with, confusable.Interval(i)});
  }
  for (const auto& [key, values] : changes) {
    a.holdout_change.push_back({key.first, key.second, QuartilesOf(values)});
  }
  SortByEffectAndMagnitude(a.holdout_change, effects);
  a.run_time_s = QuartilesOf(run_times);
  a.max_sensitivity_relative = QuartilesOf(sensitivities);
  a.confidence_rates = CountConfidenceRates(outcomes);
  return a;
}

json ToJson(const BenchmarkAggregate& a) {
  json j;
  j["objects"] = a.objects;
  j["failed"] = a.failed;
  j["not_made"] = a.not_made;
  j["resumed"] = a.resumed;
  json counts = json::object();
  for (size_t r = 0; r < a.confusion.rows.size(); ++r) {
    json row = json::object();
    for (size_t c = 0; c < a.confusion.columns.size(); ++c) {
      row[a.confusion.columns[c]] = a.confusion.counts[r][c];
    }
    counts[a.confusion.rows[r]] = row;
  }
  j["confusion"] = {{"rows", a.confusion.rows},
                    {"columns", a.confusion.columns},
                    {"row_objects", a.confusion.row_objects},
                    {"counts", counts}};
  j["detection"] = ListOf(a.detection, [](const DetectionRate& d) -> json {
    return {{"effect", d.effect},
            {"magnitude", Nullable(d.magnitude)},
            {"detected", ToJson(d.detected)}};
  });
  j["false_discoveries"] = {
      {"all", ToJson(a.false_discoveries)},
      {"per_cell", ListOf(a.false_discoveries_per_cell, [](const CellRate& c) -> json {
         return {{"cell", c.cell}, {"rate", ToJson(c.rate)}};
       })}};
  j["confusable"] = {{"all", ToJson(a.confusable_wrong_kept)},
                     {"per_cell", ListOf(a.confusable, [](const ConfusableRate& c) -> json {
                        return {{"cell", c.cell},
                                {"effect", Nullable(c.effect)},
                                {"confusable_with", c.confusable_with},
                                {"wrong_kept", ToJson(c.wrong_kept)}};
                      })}};
  j["holdout_change_of_kept_effects"] =
      ListOf(a.holdout_change, [](const ChangeSummary& c) -> json {
        return {{"effect", c.effect},
                {"magnitude", Nullable(c.magnitude)},
                {"relative_change", ToJson(c.relative_change)}};
      });
  j["run_time_s"] = ToJson(a.run_time_s);
  j["run_time_s"]["total"] = a.total_run_time_s;
  j["max_sensitivity_relative"] = ToJson(a.max_sensitivity_relative);
  j["confidence_rates"] = ToJson(a.confidence_rates)["bins"];
  return j;
}

}  // namespace calib
