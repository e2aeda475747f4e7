#include "calib/search/random_search.h"

#include <fmt/format.h>

#include "calib/search/rng.h"
#include "settings.h"
#include "state_util.h"

namespace calib::search {

RandomSearchOptions RandomSearchOptions::FromJson(const nlohmann::json& settings) {
  internal::SettingsReader reader("random", settings);
  RandomSearchOptions o;
  o.max_evals = reader.Int("max_evals", o.max_evals, 1, INT64_MAX);
  reader.Finish();
  return o;
}

namespace {

class RandomSearch final : public Optimizer {
 public:
  RandomSearch(const RandomSearchOptions& options, const Bounds& bounds, uint64_t seed)
      : options_(options), bounds_(bounds), rng_(seed) {}

  std::string name() const override { return "random"; }

  std::vector<Candidate> Ask(int max_count) override {
    std::vector<Candidate> out;
    while (asked_ < options_.max_evals && static_cast<int>(out.size()) < max_count) {
      std::vector<double> x(bounds_.lower.size());
      for (size_t i = 0; i < x.size(); ++i) {
        x[i] = std::clamp(rng_.Uniform(bounds_.lower[i], bounds_.upper[i]), bounds_.lower[i],
                          bounds_.upper[i]);
      }
      out.push_back({asked_++, std::move(x)});
    }
    return out;
  }

  void Tell(std::span<const Evaluation> results) override {
    told_ += static_cast<int64_t>(results.size());
  }

  bool Done() const override { return told_ == options_.max_evals; }
  std::string StopReason() const override {
    return Done() ? fmt::format("budget of {} evaluations used", options_.max_evals) : "";
  }

  std::optional<IdCounts> Counts() const override { return IdCounts{asked_, told_}; }

  nlohmann::json SaveState() const override {
    return {{"rng", rng_.Save()}, {"asked", asked_}, {"told", told_}};
  }
  void RestoreState(const nlohmann::json& state) override {
    rng_.Restore(state.at("rng"));
    asked_ = internal::IntFromJson<int64_t>(state.at("asked"), "asked");
    told_ = internal::IntFromJson<int64_t>(state.at("told"), "told");
    if (!(0 <= told_ && told_ <= asked_ && asked_ <= options_.max_evals)) {
      throw std::invalid_argument(fmt::format(
          "random state: told {} and asked {} are not 0 <= told <= asked <= max_evals {}", told_,
          asked_, options_.max_evals));
    }
  }

 private:
  RandomSearchOptions options_;
  Bounds bounds_;
  Rng rng_;
  int64_t asked_ = 0;
  int64_t told_ = 0;
};

}  // namespace

std::unique_ptr<Optimizer> MakeRandomSearch(const RandomSearchOptions& options,
                                            const Bounds& bounds, uint64_t seed) {
  return std::make_unique<RandomSearch>(options, bounds, seed);
}

}  // namespace calib::search
