#include "calib/search/cmaes.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "calib/search/rng.h"
#include "settings.h"
#include "state_util.h"

namespace calib::search {

CmaesOptions CmaesOptions::FromJson(const nlohmann::json& settings, const Bounds& bounds) {
  internal::SettingsReader reader("cmaes", settings);
  const double inf = std::numeric_limits<double>::infinity();
  CmaesOptions o;
  const int n = bounds.dimension();
  const int default_lambda = 4 + static_cast<int>(std::floor(3.0 * std::log(n)));
  o.population = static_cast<int>(reader.Int("population", default_lambda, 2, 1000000));
  o.initial_sigma = reader.Number("initial_sigma", o.initial_sigma, 0, true, inf, false);
  o.x0 = reader.PointInBox("x0", bounds.lower, bounds.upper);
  o.max_evals = reader.Int("max_evals", std::max<int64_t>(o.max_evals, o.population),
                           o.population, INT64_MAX);
  o.tol_x = reader.Number("tol_x", o.tol_x, 0, false, inf, false);
  reader.Finish();
  return o;
}

namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;

nlohmann::json ToJson(const MatrixXd& m) {
  std::vector<double> v(m.data(), m.data() + m.size());
  return {{"rows", m.rows()}, {"cols", m.cols()}, {"data", internal::VectorToJson(v)}};
}

MatrixXd MatrixFrom(const nlohmann::json& j) {
  const auto v = internal::VectorFromJson(j.at("data"));
  const auto rows = internal::IntFromJson<int64_t>(j.at("rows"), "rows"), cols = internal::IntFromJson<int64_t>(j.at("cols"), "cols");
  // Checked before anything is allocated for them.
  if (rows < 0 || cols < 0 || (rows > 0 && cols != static_cast<int64_t>(v.size()) / rows) ||
      static_cast<size_t>(rows) * static_cast<size_t>(cols) != v.size()) {
    throw std::invalid_argument(fmt::format(
        "cmaes state: a {} x {} matrix with {} values", rows, cols, v.size()));
  }
  MatrixXd m(rows, cols);
  std::copy(v.begin(), v.end(), m.data());
  return m;
}

// Whether m is rows x cols.
bool Shaped(const MatrixXd& m, int rows, int cols) { return m.rows() == rows && m.cols() == cols; }

class Cmaes final : public Optimizer {
 public:
  Cmaes(const CmaesOptions& options, const Bounds& bounds, uint64_t seed)
      : o_(options), bounds_(bounds), rng_(seed), n_(bounds.dimension()) {
    lambda_ = o_.population > 0 ? o_.population
                                : 4 + static_cast<int>(std::floor(3.0 * std::log(n_)));
    mu_ = lambda_ / 2;
    weights_.resize(mu_);
    for (int i = 0; i < mu_; ++i) weights_[i] = std::log((lambda_ + 1) / 2.0) - std::log(i + 1.0);
    weights_ /= weights_.sum();
    mu_eff_ = 1.0 / weights_.squaredNorm();
    const double n = n_;
    cs_ = (mu_eff_ + 2) / (n + mu_eff_ + 5);
    ds_ = 1 + 2 * std::max(0.0, std::sqrt((mu_eff_ - 1) / (n + 1)) - 1) + cs_;
    cc_ = (4 + mu_eff_ / n) / (n + 4 + 2 * mu_eff_ / n);
    c1_ = 2 / ((n + 1.3) * (n + 1.3) + mu_eff_);
    cmu_ = std::min(1 - c1_, 2 * (mu_eff_ - 2 + 1 / mu_eff_) / ((n + 2) * (n + 2) + mu_eff_));
    chi_n_ = std::sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n));

    mean_ = VectorXd::Constant(n_, 0.5);
    if (o_.x0) {
      for (int i = 0; i < n_; ++i) {
        mean_[i] = ((*o_.x0)[i] - bounds.lower[i]) / (bounds.upper[i] - bounds.lower[i]);
      }
    }
    sigma_ = o_.initial_sigma;
    C_ = MatrixXd::Identity(n_, n_);
    B_ = MatrixXd::Identity(n_, n_);
    D_ = VectorXd::Ones(n_);
    ps_ = VectorXd::Zero(n_);
    pc_ = VectorXd::Zero(n_);
  }

  std::string name() const override { return "cmaes"; }

  std::vector<Candidate> Ask(int max_count) override {
    if (batch_.size() == 0 && !Done()) Sample();
    return batch_.Hand(max_count);
  }

  void Tell(std::span<const Evaluation> results) override {
    for (const Evaluation& e : results) batch_.Record(e);
    if (!batch_.Complete()) return;
    Update();
    batch_.Reset(batch_.first_id + batch_.size(), {});
  }

  // The budget is checked here, not kept in the state: a job whose budget
  // is extended (calib resume --budget) continues from a state that used
  // the old one, as a run with the larger budget would have.
  bool BudgetUsed() const { return evals_ + lambda_ > o_.max_evals; }
  bool Done() const override {
    return (BudgetUsed() || !stop_reason_.empty()) && batch_.size() == 0;
  }
  std::string StopReason() const override {
    if (!Done()) return "";
    if (BudgetUsed()) {
      return fmt::format("budget: {} of max_evals = {} used (whole generations of {})", evals_,
                         o_.max_evals, lambda_);
    }
    return stop_reason_;
  }

  std::optional<std::vector<int64_t>> AwaitedIds() const override { return batch_.AwaitedIds(); }
  std::optional<IdCounts> Counts() const override {
    return IdCounts{batch_.AskedTotal(), batch_.ToldTotal()};
  }

  nlohmann::json SaveState() const override {
    return {{"rng", rng_.Save()},     {"generation", generation_}, {"evals", evals_},
            {"mean", ToJson(mean_)},  {"sigma", internal::DoubleToJson(sigma_)},
            {"C", ToJson(C_)},        {"B", ToJson(B_)},           {"D", ToJson(D_)},
            {"ps", ToJson(ps_)},      {"pc", ToJson(pc_)},         {"samples", ToJson(samples_)},
            {"batch", batch_.Save()}, {"stop_reason", stop_reason_}};
  }
  void RestoreState(const nlohmann::json& s) override {
    rng_.Restore(s.at("rng"));
    generation_ = internal::IntFromJson<int64_t>(s.at("generation"), "generation");
    evals_ = internal::IntFromJson<int64_t>(s.at("evals"), "evals");
    const MatrixXd mean = MatrixFrom(s.at("mean")), C = MatrixFrom(s.at("C")),
                   B = MatrixFrom(s.at("B")), D = MatrixFrom(s.at("D")),
                   ps = MatrixFrom(s.at("ps")), pc = MatrixFrom(s.at("pc")),
                   samples = MatrixFrom(s.at("samples"));
    batch_.Restore(s.at("batch"), bounds_);
    // The vectors n x 1, the matrices n x n, the samples one column per
    // candidate of the batch in progress (between generations they are the
    // last one's, unused until the next is sampled).
    if (!Shaped(mean, n_, 1) || !Shaped(C, n_, n_) || !Shaped(B, n_, n_) || !Shaped(D, n_, 1) ||
        !Shaped(ps, n_, 1) || !Shaped(pc, n_, 1) ||
        !(batch_.size() == 0 || Shaped(samples, n_, batch_.size()))) {
      throw std::invalid_argument(fmt::format(
          "cmaes state: its vectors and matrices are not those of {} dimensions and a batch of {}",
          n_, batch_.size()));
    }
    mean_ = mean;
    C_ = C;
    B_ = B;
    D_ = D;
    ps_ = ps;
    pc_ = pc;
    samples_ = samples;
    sigma_ = internal::DoubleFromJson(s.at("sigma"));
    stop_reason_ = s.at("stop_reason").get<std::string>();
    // A state saved when the budget was kept in it.
    if (stop_reason_.rfind("budget:", 0) == 0) stop_reason_.clear();
  }

 private:
  // One generation: u_k = m + sigma B D z_k, z_k ~ N(0, I); the candidate is
  // clip(u_k) mapped to the box.
  void Sample() {
    samples_.resize(n_, lambda_);
    std::vector<std::vector<double>> x;
    for (int k = 0; k < lambda_; ++k) {
      VectorXd z(n_);
      for (int i = 0; i < n_; ++i) z[i] = rng_.Normal();
      samples_.col(k) = mean_ + sigma_ * (B_ * D_.cwiseProduct(z));
      std::vector<double> u(n_);
      for (int i = 0; i < n_; ++i) u[i] = std::clamp(samples_(i, k), 0.0, 1.0);
      x.push_back(internal::FromUnit(bounds_, u));
    }
    evals_ += lambda_;
    batch_.Reset(batch_.first_id, std::move(x));
  }

  void Update() {
    // Penalised fitness of the unrepaired samples.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (double f : batch_.value) {
      if (std::isfinite(f)) {
        lo = std::min(lo, f);
        hi = std::max(hi, f);
      }
    }
    const double spread = hi > lo ? hi - lo : 1.0;
    std::vector<double> fitness(lambda_);
    for (int k = 0; k < lambda_; ++k) {
      const VectorXd u = samples_.col(k);
      const double d2 = (u - u.cwiseMax(0.0).cwiseMin(1.0)).squaredNorm();
      fitness[k] = batch_.value[k] + spread * d2 / (sigma_ * sigma_);
    }
    const std::vector<int> order = internal::RankOrder(fitness);

    const VectorXd old_mean = mean_;
    MatrixXd y(n_, mu_);
    for (int i = 0; i < mu_; ++i) y.col(i) = (samples_.col(order[i]) - old_mean) / sigma_;
    const VectorXd y_w = y * weights_;
    mean_ = old_mean + sigma_ * y_w;

    // C^{-1/2} y_w = B D^{-1} B^T y_w.
    const VectorXd c_inv_sqrt_yw = B_ * (B_.transpose() * y_w).cwiseQuotient(D_);
    ps_ = (1 - cs_) * ps_ + std::sqrt(cs_ * (2 - cs_) * mu_eff_) * c_inv_sqrt_yw;
    ++generation_;
    const double ps_norm = ps_.norm();
    const bool hsig = ps_norm / std::sqrt(1 - std::pow(1 - cs_, 2.0 * generation_)) / chi_n_ <
                      1.4 + 2.0 / (n_ + 1);
    pc_ = (1 - cc_) * pc_ + (hsig ? std::sqrt(cc_ * (2 - cc_) * mu_eff_) : 0.0) * y_w;
    MatrixXd rank_mu = MatrixXd::Zero(n_, n_);
    for (int i = 0; i < mu_; ++i) rank_mu += weights_[i] * y.col(i) * y.col(i).transpose();
    C_ = (1 - c1_ - cmu_) * C_ +
         c1_ * (pc_ * pc_.transpose() + (hsig ? 0.0 : cc_ * (2 - cc_)) * C_) + cmu_ * rank_mu;
    C_ = 0.5 * (C_ + C_.transpose()).eval();
    sigma_ *= std::exp((cs_ / ds_) * (ps_norm / chi_n_ - 1));

    Eigen::SelfAdjointEigenSolver<MatrixXd> eig(C_);
    B_ = eig.eigenvectors();
    const VectorXd ev = eig.eigenvalues().cwiseMax(1e-300);
    D_ = ev.cwiseSqrt();

    if (sigma_ * D_.maxCoeff() < o_.tol_x) {
      stop_reason_ = fmt::format("sigma * sqrt(max eig C) = {} < tol_x = {}",
                                 sigma_ * D_.maxCoeff(), o_.tol_x);
    } else if (ev.maxCoeff() > 1e14 * ev.minCoeff()) {
      stop_reason_ = "condition number of C exceeds 1e14";
    } else if (!std::isfinite(sigma_) || !mean_.allFinite()) {
      stop_reason_ = "numerical breakdown (sigma or mean not finite)";
    }
  }

  CmaesOptions o_;
  Bounds bounds_;
  Rng rng_;
  int n_;
  int lambda_ = 0, mu_ = 0;
  VectorXd weights_;
  double mu_eff_ = 0, cs_ = 0, ds_ = 0, cc_ = 0, c1_ = 0, cmu_ = 0, chi_n_ = 0;

  int64_t generation_ = 0;
  int64_t evals_ = 0;  // asked so far
  VectorXd mean_;      // box-normalised
  double sigma_ = 0;
  MatrixXd C_, B_;
  VectorXd D_;  // sqrt of C's eigenvalues
  VectorXd ps_, pc_;
  MatrixXd samples_;  // n x lambda, unrepaired, of the current generation
  internal::Batch batch_;
  std::string stop_reason_;
};

}  // namespace

std::unique_ptr<Optimizer> MakeCmaes(const CmaesOptions& options, const Bounds& bounds,
                                     uint64_t seed) {
  return std::make_unique<Cmaes>(options, bounds, seed);
}

}  // namespace calib::search
