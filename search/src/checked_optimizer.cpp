#include "calib/search/checked_optimizer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "state_util.h"

namespace calib::search {

void ValidateBounds(const Bounds& bounds) {
  if (bounds.lower.size() != bounds.upper.size()) {
    throw std::invalid_argument(fmt::format(
        "bounds: lower has {} entries, upper has {}. Violated: one lower and one upper per "
        "parameter",
        bounds.lower.size(), bounds.upper.size()));
  }
  if (bounds.lower.empty()) {
    throw std::invalid_argument("bounds: no parameters. Violated: dimension >= 1");
  }
  for (size_t i = 0; i < bounds.lower.size(); ++i) {
    const double lo = bounds.lower[i], hi = bounds.upper[i];
    if (!std::isfinite(lo) || !std::isfinite(hi) || !(lo < hi)) {
      throw std::invalid_argument(fmt::format(
          "bounds: parameter {} has lower = {}, upper = {}. Violated: finite and lower < upper",
          i, lo, hi));
    }
  }
}

namespace {

bool SameBits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

nlohmann::json EvaluationToJson(const Evaluation& e) {
  return {{"id", e.id},
          {"x", internal::VectorToJson(e.x)},
          {"value", internal::DoubleToJson(e.value)},
          {"failed", e.failed}};
}

Evaluation EvaluationFromJson(const nlohmann::json& j) {
  return {internal::IntFromJson<int64_t>(j.at("id"), "id"), internal::VectorFromJson(j.at("x")),
          internal::DoubleFromJson(j.at("value")), j.at("failed").get<bool>()};
}

}  // namespace

CheckedOptimizer::CheckedOptimizer(std::unique_ptr<Optimizer> plugin, Bounds bounds)
    : plugin_(std::move(plugin)), bounds_(std::move(bounds)) {
  if (!plugin_) throw std::invalid_argument("CheckedOptimizer: no optimiser given");
  ValidateBounds(bounds_);
}

std::vector<Candidate> CheckedOptimizer::Ask(int max_count) {
  if (max_count < 1) {
    throw std::invalid_argument(fmt::format(
        "optimiser '{}': Ask(max_count = {}). Violated: max_count >= 1", name(), max_count));
  }
  std::vector<Candidate> candidates = plugin_->Ask(max_count);
  const auto bug = [&](const std::string& what) {
    return std::logic_error(fmt::format("optimiser '{}' broke the ask contract: {}", name(), what));
  };
  if (static_cast<int>(candidates.size()) > max_count) {
    throw bug(fmt::format("returned {} candidates for max_count = {}", candidates.size(),
                          max_count));
  }
  const size_t n = bounds_.lower.size();
  int64_t expected = next_id_;
  for (const Candidate& c : candidates) {
    if (c.id != expected) {
      throw bug(fmt::format("candidate id {} where {} was expected (ids are consecutive)", c.id,
                            expected));
    }
    if (c.x.size() != n) {
      throw bug(fmt::format("candidate {} has {} coordinates, expected {}", c.id, c.x.size(), n));
    }
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(c.x[i]) || c.x[i] < bounds_.lower[i] || c.x[i] > bounds_.upper[i]) {
        throw bug(fmt::format("candidate {} has x[{}] = {}, outside [{}, {}]", c.id, i, c.x[i],
                              bounds_.lower[i], bounds_.upper[i]));
      }
    }
    ++expected;
  }
  for (const Candidate& c : candidates) outstanding_.emplace(c.id, c.x);
  next_id_ = expected;
  return candidates;
}

void CheckedOptimizer::Tell(std::span<const Evaluation> results) {
  std::vector<Evaluation> sorted(results.begin(), results.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const Evaluation& a, const Evaluation& b) { return a.id < b.id; });
  for (size_t k = 0; k < sorted.size(); ++k) {
    Evaluation& e = sorted[k];
    const auto it = outstanding_.find(e.id);
    if (it == outstanding_.end()) {
      throw std::invalid_argument(fmt::format(
          "optimiser '{}': told a result for id {}, which is {}", name(), e.id,
          e.id < 0 || e.id >= next_id_ ? "not an asked id" : "already told"));
    }
    if (k > 0 && sorted[k - 1].id == e.id) {
      throw std::invalid_argument(
          fmt::format("optimiser '{}': id {} told twice in one call", name(), e.id));
    }
    if (!SameBits(e.x, it->second)) {
      throw std::invalid_argument(fmt::format(
          "optimiser '{}': result for id {} has x of size {} that differs from the asked x "
          "(size {})",
          name(), e.id, e.x.size(), it->second.size()));
    }
    if (!std::isfinite(e.value)) e.failed = true;
  }
  for (const Evaluation& e : sorted) {
    outstanding_.erase(e.id);
    ++told_count_;
    if (e.failed) {
      ++failed_count_;
      continue;
    }
    if (!best_ || e.value < best_->value || (e.value == best_->value && e.id < best_->id)) {
      best_ = e;
    }
  }
  if (!sorted.empty()) plugin_->Tell(sorted);
}

bool CheckedOptimizer::Done() const { return outstanding_.empty() && plugin_->Done(); }

std::vector<Candidate> CheckedOptimizer::Outstanding() const {
  std::vector<Candidate> out;
  for (const auto& [id, x] : outstanding_) out.push_back({id, x});
  return out;
}

nlohmann::json CheckedOptimizer::SaveState() const {
  nlohmann::json outstanding = nlohmann::json::array();
  for (const auto& [id, x] : outstanding_) {
    outstanding.push_back({{"id", id}, {"x", internal::VectorToJson(x)}});
  }
  return {{"optimizer", name()},
          {"dimension", dimension()},
          {"next_id", next_id_},
          {"told", told_count_},
          {"failed", failed_count_},
          {"best", best_ ? EvaluationToJson(*best_) : nlohmann::json()},
          {"outstanding", outstanding},
          {"plugin", plugin_->SaveState()}};
}

void CheckedOptimizer::RestoreState(const nlohmann::json& state) {
  try {
    if (!state.is_object()) throw std::invalid_argument("not a JSON object");
    const std::string saved_name = state.at("optimizer").get<std::string>();
    const int saved_dimension = internal::IntFromJson<int>(state.at("dimension"), "dimension");
    if (saved_name != name() || saved_dimension != dimension()) {
      throw std::invalid_argument(fmt::format("it was saved by '{}' in dimension {}", saved_name,
                                              saved_dimension));
    }
    plugin_->RestoreState(state.at("plugin"));
    next_id_ = internal::IntFromJson<int64_t>(state.at("next_id"), "next_id");
    told_count_ = internal::IntFromJson<int64_t>(state.at("told"), "told");
    failed_count_ = internal::IntFromJson<int64_t>(state.at("failed"), "failed");
    best_.reset();
    if (!state.at("best").is_null()) best_ = EvaluationFromJson(state.at("best"));
    outstanding_.clear();
    for (const auto& o : state.at("outstanding")) {
      outstanding_.emplace(internal::IntFromJson<int64_t>(o.at("id"), "id"), internal::VectorFromJson(o.at("x")));
    }
    CheckRestoredCounts();
  } catch (const std::exception& e) {
    throw std::invalid_argument(fmt::format("optimiser '{}' (dimension {}): cannot restore state: {}",
                                            name(), dimension(), e.what()));
  }
}

// What the wrapper's own part of a restored state must satisfy, and that
// the plug-in waits for exactly the outstanding candidates (found by
// fuzz/fuzz_checkpoint: an NLopt state whose outstanding id was one already
// told was taken, and the first Tell after the resume threw std::logic_error,
// the plug-in-bug error, instead of the restore refusing the state).
void CheckedOptimizer::CheckRestoredCounts() const {
  if (next_id_ < 0 || told_count_ < 0 || failed_count_ < 0 || failed_count_ > told_count_ ||
      told_count_ + static_cast<int64_t>(outstanding_.size()) != next_id_) {
    throw std::invalid_argument(fmt::format(
        "counts next_id = {}, told = {}, failed = {} and {} outstanding do not add up", next_id_,
        told_count_, failed_count_, outstanding_.size()));
  }
  for (const auto& [id, x] : outstanding_) {
    if (id < 0 || id >= next_id_) {
      throw std::invalid_argument(
          fmt::format("outstanding id {} is not one of the asked ids 0..{}", id, next_id_ - 1));
    }
    if (static_cast<int>(x.size()) != dimension()) {
      throw std::invalid_argument(
          fmt::format("outstanding id {} has {} coordinates", id, x.size()));
    }
    for (int i = 0; i < dimension(); ++i) {
      if (!(x[i] >= bounds_.lower[i] && x[i] <= bounds_.upper[i])) {
        throw std::invalid_argument(fmt::format(
            "outstanding id {}: coordinate {} = {} is outside the bounds", id, i, x[i]));
      }
    }
  }
  if (std::optional<std::vector<int64_t>> awaited = plugin_->AwaitedIds()) {
    std::vector<int64_t> ids;
    for (const auto& entry : outstanding_) ids.push_back(entry.first);
    std::sort(awaited->begin(), awaited->end());
    if (ids != *awaited) {
      throw std::invalid_argument(
          fmt::format("outstanding ids [{}] are not the ones the optimiser's own state waits for "
                      "([{}])",
                      fmt::join(ids, ", "), fmt::join(*awaited, ", ")));
    }
  }
  // (also found by fuzz_checkpoint: a grid state that counted 16 told of 14
  // asked was taken, and the resumed search never ended).
  if (const std::optional<Optimizer::IdCounts> counts = plugin_->Counts();
      counts && (counts->asked != next_id_ || counts->told != told_count_)) {
    throw std::invalid_argument(fmt::format(
        "the optimiser's own state counts {} asked and {} told, the checkpoint {} asked and {} "
        "told",
        counts->asked, counts->told, next_id_, told_count_));
  }
}

}  // namespace calib::search
