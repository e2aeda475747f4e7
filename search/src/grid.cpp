#include "calib/search/grid.h"

#include <algorithm>
#include <climits>
#include <cstdlib>

#include <fmt/format.h>

#include "settings.h"
#include "state_util.h"

namespace calib::search {

GridOptions GridOptions::FromJson(const nlohmann::json& settings, int dimension) {
  internal::SettingsReader reader("grid", settings);
  GridOptions o;
  o.resolution.assign(dimension, 5);
  if (reader.Has("resolution")) {
    const nlohmann::json& r = reader.Raw("resolution");
    const std::string rule =
        fmt::format("resolution is an integer >= 1 or an array of {} integers >= 1", dimension);
    if (r.is_number_integer()) {
      if (r.get<int64_t>() < 1 || r.get<int64_t>() > INT_MAX) reader.Fail("resolution", r, rule);
      o.resolution.assign(dimension, r.get<int>());
    } else if (r.is_array() && static_cast<int>(r.size()) == dimension) {
      for (int i = 0; i < dimension; ++i) {
        if (!r[i].is_number_integer() || r[i].get<int64_t>() < 1 || r[i].get<int64_t>() > INT_MAX) {
          reader.Fail("resolution", r, rule);
        }
        o.resolution[i] = r[i].get<int>();
      }
    } else {
      reader.Fail("resolution", r, rule);
    }
  }
  if (reader.Has("max_evals")) o.max_evals = reader.Int("max_evals", 0, 1, INT64_MAX);
  reader.Finish();
  return o;
}

namespace {

// One axis: its values in refinement order and each one's level.
struct Axis {
  std::vector<double> value;  // by rank
  std::vector<int> level;     // by rank, nondecreasing
};

Axis MakeAxis(int r, double lower, double upper) {
  Axis axis;
  if (r == 1) {
    axis.value = {0.5 * (lower + upper)};
    axis.level = {0};
    return axis;
  }
  std::vector<int> min_dist(r, INT_MAX);
  std::vector<uint8_t> taken(r, 0);
  int level = 0;
  int last_dist = INT_MAX;
  for (int k = 0; k < r; ++k) {
    int pick = -1;
    if (k == 0) {
      pick = (r - 1) / 2;  // nearest the centre (lower of two when r is even)
    } else {
      for (int j = 0; j < r; ++j) {
        if (!taken[j] && (pick < 0 || min_dist[j] > min_dist[pick])) pick = j;
      }
      if (min_dist[pick] < last_dist) ++level;
      last_dist = min_dist[pick];
    }
    taken[pick] = 1;
    for (int j = 0; j < r; ++j) min_dist[j] = std::min(min_dist[j], std::abs(j - pick));
    const double t = static_cast<double>(pick) / (r - 1);
    axis.value.push_back(pick == r - 1 ? upper : std::min(upper, lower + t * (upper - lower)));
    axis.level.push_back(level);
  }
  return axis;
}

class Grid final : public Optimizer {
 public:
  Grid(const GridOptions& options, const Bounds& bounds) {
    const int n = bounds.dimension();
    int64_t total = 1;
    for (int a = 0; a < n; ++a) {
      axes_.push_back(MakeAxis(options.resolution[a], bounds.lower[a], bounds.upper[a]));
      max_level_ = std::max(max_level_, axes_.back().level.back());
      const int64_t r = options.resolution[a];
      total = total > INT64_MAX / r ? INT64_MAX : total * r;
    }
    budget_ = options.max_evals ? std::min(*options.max_evals, total) : total;
    counter_.assign(n, 0);
  }

  std::string name() const override { return "grid"; }

  std::vector<Candidate> Ask(int max_count) override {
    std::vector<Candidate> out;
    while (asked_ < budget_ && static_cast<int>(out.size()) < max_count) {
      AdvanceToValid();
      std::vector<double> x(axes_.size());
      for (size_t a = 0; a < axes_.size(); ++a) x[a] = axes_[a].value[counter_[a]];
      out.push_back({asked_++, std::move(x)});
      Increment();
    }
    return out;
  }

  void Tell(std::span<const Evaluation> results) override {
    told_ += static_cast<int64_t>(results.size());
  }
  bool Done() const override { return told_ == budget_; }
  std::string StopReason() const override {
    return Done() ? fmt::format("{} grid points evaluated", budget_) : "";
  }

  std::optional<IdCounts> Counts() const override { return IdCounts{asked_, told_}; }

  nlohmann::json SaveState() const override {
    return {{"asked", asked_}, {"told", told_}, {"level", level_}, {"counter", counter_}};
  }
  void RestoreState(const nlohmann::json& state) override {
    asked_ = internal::IntFromJson<int64_t>(state.at("asked"), "asked");
    told_ = internal::IntFromJson<int64_t>(state.at("told"), "told");
    level_ = internal::IntFromJson<int>(state.at("level"), "level");
    counter_ = internal::IntVectorFromJson<int>(state.at("counter"), "counter");
    if (counter_.size() != axes_.size()) throw std::invalid_argument("grid state: bad counter");
    if (!(0 <= told_ && told_ <= asked_ && asked_ <= budget_)) {
      throw std::invalid_argument(fmt::format(
          "grid state: told {} and asked {} are not 0 <= told <= asked <= {} points", told_,
          asked_, budget_));
    }
  }

 private:
  // Ranks allowed on axis a at the current level.
  int Limit(size_t a) const {
    const auto& lv = axes_[a].level;
    return static_cast<int>(std::upper_bound(lv.begin(), lv.end(), level_) - lv.begin());
  }
  bool OnShell() const {
    for (size_t a = 0; a < axes_.size(); ++a) {
      if (axes_[a].level[counter_[a]] == level_) return true;
    }
    return false;
  }
  // Mixed-radix increment within the current level's cube, last axis
  // fastest; past the end moves to the next level.
  void Increment() {
    for (size_t a = axes_.size(); a-- > 0;) {
      if (++counter_[a] < Limit(a)) return;
      counter_[a] = 0;
    }
    ++level_;
  }
  void AdvanceToValid() {
    while (level_ <= max_level_ && !OnShell()) Increment();
  }

  std::vector<Axis> axes_;
  int max_level_ = 0;
  int64_t budget_ = 0;
  int64_t asked_ = 0;
  int64_t told_ = 0;
  int level_ = 0;
  std::vector<int> counter_;
};

}  // namespace

std::unique_ptr<Optimizer> MakeGrid(const GridOptions& options, const Bounds& bounds) {
  return std::make_unique<Grid>(options, bounds);
}

}  // namespace calib::search
