#include "calib/search/annealing.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "calib/search/rng.h"
#include "settings.h"
#include "state_util.h"

namespace calib::search {

AnnealingOptions AnnealingOptions::FromJson(const nlohmann::json& settings) {
  internal::SettingsReader reader("annealing", settings);
  const double inf = std::numeric_limits<double>::infinity();
  AnnealingOptions o;
  o.max_evals = reader.Int("max_evals", o.max_evals, 2, INT64_MAX);
  o.warmup = static_cast<int>(reader.Int("warmup", o.warmup, 1, std::min<int64_t>(o.max_evals - 1, 1000000)));
  o.initial_temperature = reader.Number("initial_temperature", -1.0, 0, true, inf, false);
  o.cooling = reader.Number("cooling", -1.0, 0, true, 1, true);
  o.initial_step = reader.Number("initial_step", o.initial_step, 0, true, 1, false);
  o.step_factor = reader.Number("step_factor", o.step_factor, 0, true, inf, false);
  o.steps_per_adjust = static_cast<int>(reader.Int("steps_per_adjust", o.steps_per_adjust, 1, 1000000));
  o.adjusts_per_temperature =
      static_cast<int>(reader.Int("adjusts_per_temperature", o.adjusts_per_temperature, 1, 1000000));
  o.batch_size = static_cast<int>(reader.Int("batch_size", o.batch_size, 1, 1000000));
  reader.Finish();
  return o;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kAutoCoolingSpan = 1e-4;

class Annealing final : public Optimizer {
 public:
  Annealing(const AnnealingOptions& options, const Bounds& bounds, uint64_t seed)
      : o_(options), bounds_(bounds), rng_(seed), n_(bounds.dimension()) {
    if (o_.cooling <= 0) {
      // Auto: the temperature falls by kAutoCoolingSpan over the budget if
      // every evaluation were a processed move.
      const double moves_per_temperature =
          static_cast<double>(o_.steps_per_adjust) * o_.adjusts_per_temperature * n_;
      const double stages =
          std::max(1.0, std::floor((o_.max_evals - o_.warmup) / moves_per_temperature));
      o_.cooling = std::pow(kAutoCoolingSpan, 1.0 / stages);
    }
    step_.assign(n_, o_.initial_step);
    accepted_.assign(n_, 0);
  }

  std::string name() const override { return "annealing"; }

  std::vector<Candidate> Ask(int max_count) override {
    if (batch_.size() == 0 && !Done()) {
      if (!started_) {
        std::vector<std::vector<double>> u(o_.warmup);
        for (auto& p : u) {
          p.resize(n_);
          for (double& v : p) v = rng_.Uniform01();
        }
        StartBatch(std::move(u));
      } else if (evals_ < o_.max_evals) {
        ProposeMoves();
      }
    }
    return batch_.Hand(max_count);
  }

  void Tell(std::span<const Evaluation> results) override {
    for (const Evaluation& e : results) batch_.Record(e);
    if (!batch_.Complete()) return;
    for (int i = 0; i < batch_.size(); ++i) {
      if (batch_.value[i] < best_f_) {
        best_f_ = batch_.value[i];
        best_u_ = batch_u_[i];
      }
    }
    if (!started_) {
      FinishWarmup();
    } else {
      ProcessMoves();
    }
    next_id_ = batch_.first_id + batch_.size();
    batch_.Reset(next_id_, {});
    batch_u_.clear();
  }

  bool Done() const override { return evals_ >= o_.max_evals && batch_.size() == 0; }
  std::string StopReason() const override {
    return Done() ? fmt::format("budget of {} evaluations used", o_.max_evals) : "";
  }

  std::optional<std::vector<int64_t>> AwaitedIds() const override { return batch_.AwaitedIds(); }
  std::optional<IdCounts> Counts() const override {
    return IdCounts{batch_.AskedTotal(), batch_.ToldTotal()};
  }

  nlohmann::json SaveState() const override {
    return {{"rng", rng_.Save()},
            {"started", started_},
            {"next_id", next_id_},
            {"evals", evals_},
            {"batch", batch_.Save()},
            {"batch_u", internal::MatrixToJson(batch_u_)},
            {"current_u", internal::VectorToJson(current_u_)},
            {"current_f", internal::DoubleToJson(current_f_)},
            {"best_u", internal::VectorToJson(best_u_)},
            {"best_f", internal::DoubleToJson(best_f_)},
            {"temperature", internal::DoubleToJson(temperature_)},
            {"step", internal::VectorToJson(step_)},
            {"accepted", accepted_},
            {"coordinate", coordinate_},
            {"moves_since_adjust", moves_since_adjust_},
            {"adjusts_at_temperature", adjusts_at_temperature_}};
  }
  void RestoreState(const nlohmann::json& s) override {
    rng_.Restore(s.at("rng"));
    started_ = s.at("started").get<bool>();
    next_id_ = internal::IntFromJson<int64_t>(s.at("next_id"), "next_id");
    evals_ = internal::IntFromJson<int64_t>(s.at("evals"), "evals");
    const auto n = static_cast<size_t>(n_);
    batch_.Restore(s.at("batch"), bounds_);
    batch_u_ = internal::MatrixFromJson(s.at("batch_u"), n, "batch_u");
    if (batch_u_.size() != static_cast<size_t>(batch_.size())) {
      throw std::invalid_argument("annealing state: batch_u and the batch differ in size");
    }
    // The current and best points are set when the warm-up ends.
    const size_t point_size = started_ ? n : 0;
    current_u_ = internal::VectorFromJson(s.at("current_u"), point_size, "current_u");
    current_f_ = internal::DoubleFromJson(s.at("current_f"));
    best_u_ = internal::VectorFromJson(s.at("best_u"), point_size, "best_u");
    best_f_ = internal::DoubleFromJson(s.at("best_f"));
    temperature_ = internal::DoubleFromJson(s.at("temperature"));
    step_ = internal::VectorFromJson(s.at("step"), n, "step");
    accepted_ = internal::IntVectorFromJson<int>(s.at("accepted"), "accepted");
    coordinate_ = internal::IntFromJson<int>(s.at("coordinate"), "coordinate");
    if (accepted_.size() != static_cast<size_t>(n_) || coordinate_ < 0 || coordinate_ >= n_) {
      throw std::invalid_argument(fmt::format(
          "annealing state: {} acceptance counts and coordinate {} for {} dimensions",
          accepted_.size(), coordinate_, n_));
    }
    moves_since_adjust_ = internal::IntFromJson<int>(s.at("moves_since_adjust"), "moves_since_adjust");
    adjusts_at_temperature_ = internal::IntFromJson<int>(s.at("adjusts_at_temperature"), "adjusts_at_temperature");
  }

 private:
  void StartBatch(std::vector<std::vector<double>> u) {
    std::vector<std::vector<double>> x;
    for (const auto& p : u) x.push_back(internal::FromUnit(bounds_, p));
    evals_ += static_cast<int64_t>(u.size());
    batch_u_ = std::move(u);
    batch_.Reset(next_id_, std::move(x));
  }

  void FinishWarmup() {
    started_ = true;
    double sum = 0, sum2 = 0;
    int finite = 0;
    for (double f : batch_.value) {
      if (f < kInf) {
        sum += f;
        sum2 += f * f;
        ++finite;
      }
    }
    temperature_ = o_.initial_temperature;
    if (temperature_ <= 0) {
      const double mean = finite > 0 ? sum / finite : 0;
      const double var = finite > 1 ? std::max(0.0, (sum2 - finite * mean * mean) / (finite - 1)) : 0;
      temperature_ = var > 0 && std::isfinite(var) ? std::sqrt(var) : 1.0;
    }
    const std::vector<int> order = internal::RankOrder(batch_.value);
    current_u_ = batch_u_[order[0]];
    current_f_ = batch_.value[order[0]];
    if (best_u_.empty()) best_u_ = current_u_;
  }

  // Moves from the current point on consecutive coordinates, never past the
  // next step adjustment or the budget.
  void ProposeMoves() {
    const int64_t until_adjust = static_cast<int64_t>(o_.steps_per_adjust) * n_ - moves_since_adjust_;
    const int64_t count =
        std::min<int64_t>({o_.batch_size, until_adjust, o_.max_evals - evals_});
    std::vector<std::vector<double>> u;
    for (int64_t k = 0; k < count; ++k) {
      const int h = static_cast<int>((coordinate_ + k) % n_);
      std::vector<double> p = current_u_;
      const double moved = p[h] + rng_.Uniform(-1.0, 1.0) * step_[h];
      p[h] = (moved >= 0.0 && moved <= 1.0) ? moved : rng_.Uniform01();
      u.push_back(std::move(p));
    }
    StartBatch(std::move(u));
  }

  // Serial annealing over the batch, in id order, up to the first accepted
  // move; later moves are discarded.
  void ProcessMoves() {
    for (int k = 0; k < batch_.size(); ++k) {
      const int h = coordinate_;
      const double f = batch_.value[k];
      bool accept = false;
      if (f < kInf) {
        accept = f <= current_f_ ||
                 rng_.Uniform01() < std::exp(-(f - current_f_) / temperature_);
      }
      coordinate_ = (coordinate_ + 1) % n_;
      ++moves_since_adjust_;
      if (accept) {
        current_u_ = batch_u_[k];
        current_f_ = f;
        ++accepted_[h];
      }
      if (moves_since_adjust_ == o_.steps_per_adjust * n_) AdjustSteps();
      if (accept) break;
    }
  }

  void AdjustSteps() {
    for (int h = 0; h < n_; ++h) {
      const double rho = static_cast<double>(accepted_[h]) / o_.steps_per_adjust;
      if (rho > 0.6) {
        step_[h] *= 1.0 + o_.step_factor * (rho - 0.6) / 0.4;
      } else if (rho < 0.4) {
        step_[h] /= 1.0 + o_.step_factor * (0.4 - rho) / 0.4;
      }
      step_[h] = std::clamp(step_[h], 1e-9, 1.0);
      accepted_[h] = 0;
    }
    moves_since_adjust_ = 0;
    if (++adjusts_at_temperature_ == o_.adjusts_per_temperature) {
      adjusts_at_temperature_ = 0;
      temperature_ *= o_.cooling;
      current_u_ = best_u_;
      current_f_ = best_f_;
    }
  }

  AnnealingOptions o_;
  Bounds bounds_;
  Rng rng_;
  int n_;
  bool started_ = false;
  int64_t next_id_ = 0;
  int64_t evals_ = 0;  // asked so far
  internal::Batch batch_;
  std::vector<std::vector<double>> batch_u_;  // the batch, box-normalised
  std::vector<double> current_u_;
  double current_f_ = kInf;
  std::vector<double> best_u_;
  double best_f_ = kInf;
  double temperature_ = 1.0;
  std::vector<double> step_;    // per coordinate, fraction of width
  std::vector<int> accepted_;   // accepted moves per coordinate since adjust
  int coordinate_ = 0;
  int moves_since_adjust_ = 0;
  int adjusts_at_temperature_ = 0;
};

}  // namespace

std::unique_ptr<Optimizer> MakeAnnealing(const AnnealingOptions& options, const Bounds& bounds,
                                         uint64_t seed) {
  return std::make_unique<Annealing>(options, bounds, seed);
}

}  // namespace calib::search
