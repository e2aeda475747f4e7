#include "calib/search/genetic.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "calib/search/rng.h"
#include "settings.h"
#include "state_util.h"

namespace calib::search {

GeneticOptions GeneticOptions::FromJson(const nlohmann::json& settings, int dimension) {
  internal::SettingsReader reader("genetic", settings);
  const double inf = std::numeric_limits<double>::infinity();
  GeneticOptions o;
  o.population = static_cast<int>(reader.Int("population", o.population, 2, 1000000));
  o.generations = static_cast<int>(reader.Int("generations", o.generations, 1, 1000000));
  o.tournament_size = static_cast<int>(
      reader.Int("tournament_size", o.tournament_size, 1, o.population));
  o.crossover = reader.OneOf("crossover", o.crossover, {"blend", "sbx"});
  o.crossover_rate = reader.Number("crossover_rate", o.crossover_rate, 0, false, 1, false);
  o.blend_alpha = reader.Number("blend_alpha", o.blend_alpha, 0, false, inf, false);
  o.sbx_eta = reader.Number("sbx_eta", o.sbx_eta, 0, false, inf, false);
  o.mutation_rate = reader.Number("mutation_rate", 1.0 / dimension, 0, false, 1, false);
  o.mutation_sigma = reader.Number("mutation_sigma", o.mutation_sigma, 0, true, inf, false);
  o.elitism = static_cast<int>(reader.Int("elitism", o.elitism, 0, o.population - 1));
  reader.Finish();
  return o;
}

namespace {

class Genetic final : public Optimizer {
 public:
  Genetic(const GeneticOptions& options, const Bounds& bounds, uint64_t seed)
      : o_(options), bounds_(bounds), rng_(seed) {
    if (o_.mutation_rate < 0) o_.mutation_rate = 1.0 / bounds.dimension();
  }

  std::string name() const override { return "genetic"; }

  std::vector<Candidate> Ask(int max_count) override {
    if (batch_.size() == 0 && generation_ == 0) {
      std::vector<std::vector<double>> x(o_.population);
      for (auto& p : x) p = RandomPoint();
      batch_.Reset(0, std::move(x));
    }
    return batch_.Hand(max_count);
  }

  void Tell(std::span<const Evaluation> results) override {
    for (const Evaluation& e : results) batch_.Record(e);
    if (!batch_.Complete()) return;
    // Population = elites carried over + the generation just evaluated.
    for (int i = 0; i < batch_.size(); ++i) {
      pop_x_.push_back(batch_.x[i]);
      pop_f_.push_back(batch_.value[i]);
    }
    const std::vector<int> order = internal::RankOrder(pop_f_);
    std::vector<std::vector<double>> x;
    std::vector<double> f;
    for (int i : order) {
      x.push_back(pop_x_[i]);
      f.push_back(pop_f_[i]);
    }
    pop_x_ = std::move(x);
    pop_f_ = std::move(f);
    ++generation_;
    const int64_t next_first = batch_.first_id + batch_.size();
    if (generation_ >= o_.generations) {
      batch_.Reset(next_first, {});
      return;
    }
    batch_.Reset(next_first, Breed());
    pop_x_.resize(o_.elitism);
    pop_f_.resize(o_.elitism);
  }

  bool Done() const override { return generation_ >= o_.generations; }
  std::string StopReason() const override {
    return Done() ? fmt::format("{} generations evolved", o_.generations) : "";
  }

  std::optional<std::vector<int64_t>> AwaitedIds() const override { return batch_.AwaitedIds(); }
  std::optional<IdCounts> Counts() const override {
    return IdCounts{batch_.AskedTotal(), batch_.ToldTotal()};
  }

  nlohmann::json SaveState() const override {
    return {{"rng", rng_.Save()},
            {"generation", generation_},
            {"batch", batch_.Save()},
            {"population_x", internal::MatrixToJson(pop_x_)},
            {"population_f", internal::VectorToJson(pop_f_)}};
  }
  void RestoreState(const nlohmann::json& state) override {
    rng_.Restore(state.at("rng"));
    generation_ = internal::IntFromJson<int>(state.at("generation"), "generation");
    batch_.Restore(state.at("batch"), bounds_);
    pop_x_ = internal::PointsInBoxFromJson(state.at("population_x"), bounds_, "population_x");
    pop_f_ = internal::VectorFromJson(state.at("population_f"), pop_x_.size(), "population_f");
  }

 private:
  std::vector<double> RandomPoint() {
    std::vector<double> x(bounds_.lower.size());
    for (size_t i = 0; i < x.size(); ++i) {
      x[i] = std::clamp(rng_.Uniform(bounds_.lower[i], bounds_.upper[i]), bounds_.lower[i],
                        bounds_.upper[i]);
    }
    return x;
  }

  // pop_ sorted best first, so the lower index wins ties.
  int Tournament() {
    int winner = static_cast<int>(rng_.UniformInt(pop_x_.size()));
    for (int k = 1; k < o_.tournament_size; ++k) {
      winner = std::min(winner, static_cast<int>(rng_.UniformInt(pop_x_.size())));
    }
    return winner;
  }

  void Cross(std::vector<double>& a, std::vector<double>& b) {
    for (size_t i = 0; i < a.size(); ++i) {
      const double p1 = a[i], p2 = b[i];
      if (o_.crossover == "blend") {
        const double lo = std::min(p1, p2), hi = std::max(p1, p2), d = hi - lo;
        a[i] = rng_.Uniform(lo - o_.blend_alpha * d, hi + o_.blend_alpha * d);
        b[i] = rng_.Uniform(lo - o_.blend_alpha * d, hi + o_.blend_alpha * d);
      } else {
        // SBX: spread factor beta from the polynomial distribution of index eta.
        const double u = rng_.Uniform01();
        const double beta = u <= 0.5 ? std::pow(2.0 * u, 1.0 / (o_.sbx_eta + 1.0))
                                     : std::pow(1.0 / (2.0 * (1.0 - u)), 1.0 / (o_.sbx_eta + 1.0));
        a[i] = 0.5 * ((1.0 + beta) * p1 + (1.0 - beta) * p2);
        b[i] = 0.5 * ((1.0 - beta) * p1 + (1.0 + beta) * p2);
      }
    }
  }

  void MutateAndClip(std::vector<double>& x) {
    for (size_t i = 0; i < x.size(); ++i) {
      const double width = bounds_.upper[i] - bounds_.lower[i];
      if (rng_.Uniform01() < o_.mutation_rate) x[i] += o_.mutation_sigma * width * rng_.Normal();
      x[i] = std::clamp(x[i], bounds_.lower[i], bounds_.upper[i]);
    }
  }

  std::vector<std::vector<double>> Breed() {
    const int children = o_.population - o_.elitism;
    std::vector<std::vector<double>> out;
    while (static_cast<int>(out.size()) < children) {
      std::vector<double> a = pop_x_[Tournament()];
      std::vector<double> b = pop_x_[Tournament()];
      if (rng_.Uniform01() < o_.crossover_rate) Cross(a, b);
      MutateAndClip(a);
      MutateAndClip(b);
      out.push_back(std::move(a));
      if (static_cast<int>(out.size()) < children) out.push_back(std::move(b));
    }
    return out;
  }

  GeneticOptions o_;
  Bounds bounds_;
  Rng rng_;
  int generation_ = 0;  // generations fully evaluated
  internal::Batch batch_;
  std::vector<std::vector<double>> pop_x_;  // elites between generations, best first
  std::vector<double> pop_f_;
};

}  // namespace

std::unique_ptr<Optimizer> MakeGenetic(const GeneticOptions& options, const Bounds& bounds,
                                       uint64_t seed) {
  return std::make_unique<Genetic>(options, bounds, seed);
}

}  // namespace calib::search
