#include "calib/search/nlopt_optimizer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>

#include <fmt/format.h>
#include <nlopt.h>

#include "settings.h"
#include "state_util.h"

namespace calib::search {

namespace {

struct AlgorithmEntry {
  const char* name;
  nlopt_algorithm algorithm;
  bool uses_population;
};

constexpr AlgorithmEntry kAlgorithms[] = {
    {"BOBYQA", NLOPT_LN_BOBYQA, false},      {"COBYLA", NLOPT_LN_COBYLA, false},
    {"NELDERMEAD", NLOPT_LN_NELDERMEAD, false}, {"SBPLX", NLOPT_LN_SBPLX, false},
    {"DIRECT", NLOPT_GN_DIRECT, false},      {"DIRECT_L", NLOPT_GN_DIRECT_L, false},
    {"CRS2_LM", NLOPT_GN_CRS2_LM, true},     {"ISRES", NLOPT_GN_ISRES, true},
    {"ESCH", NLOPT_GN_ESCH, true},           {"MLSL", NLOPT_G_MLSL_LDS, true},
};
const std::vector<std::string> kLocalNames = {"BOBYQA", "COBYLA", "NELDERMEAD", "SBPLX"};

const AlgorithmEntry* FindAlgorithm(const std::string& name) {
  for (const auto& a : kAlgorithms) {
    if (name == a.name) return &a;
  }
  return nullptr;
}

// NLopt's RNG (used by CRS2_LM, ISRES, ESCH, MLSL) may be process-wide;
// a replay seeds it and must not interleave with another replay.
std::mutex& ReplayMutex() {
  static std::mutex m;
  return m;
}

// Owns an nlopt_opt.
struct OptHandle {
  nlopt_opt opt = nullptr;
  explicit OptHandle(nlopt_opt o) : opt(o) {}
  ~OptHandle() {
    if (opt) nlopt_destroy(opt);
  }
  OptHandle(const OptHandle&) = delete;
  OptHandle& operator=(const OptHandle&) = delete;
};

struct StoredEvaluation {
  std::vector<double> raw_x;  // the point NLopt asked for, before clipping
  double value = 0;           // +inf when failed
  bool failed = false;
  double nlopt_value = 0;     // what NLopt is told (see ValueForNlopt)
};

}  // namespace

std::vector<std::string> NloptAlgorithmNames() {
  std::vector<std::string> names;
  for (const auto& a : kAlgorithms) names.push_back(a.name);
  return names;
}

NloptOptions NloptOptions::FromJson(const std::string& algorithm, const nlohmann::json& settings,
                                    const Bounds& bounds) {
  const std::string who = "nlopt:" + algorithm;
  const AlgorithmEntry* entry = FindAlgorithm(algorithm);
  if (!entry) {
    throw std::invalid_argument(fmt::format(
        "optimiser '{}' is unknown. Violated: the NLopt algorithm is one of {}", who,
        fmt::join(NloptAlgorithmNames(), ", ")));
  }
  const double inf = std::numeric_limits<double>::infinity();
  internal::SettingsReader reader(who, settings);
  NloptOptions o;
  o.algorithm = algorithm;
  o.maxeval = static_cast<int>(reader.Int("maxeval", o.maxeval, 1, INT32_MAX));
  o.xtol_rel = reader.Number("xtol_rel", o.xtol_rel, 0, false, inf, false);
  o.ftol_rel = reader.Number("ftol_rel", o.ftol_rel, 0, false, inf, false);
  o.x0 = reader.PointInBox("x0", bounds.lower, bounds.upper);
  if (reader.Has("initial_step")) {
    o.initial_step = reader.Number("initial_step", 0, 0, true, inf, false);
  }
  if (entry->uses_population) {
    o.population = static_cast<int>(reader.Int("population", 0, 0, INT32_MAX));
  }
  if (algorithm == "MLSL") {
    o.local_algorithm = reader.OneOf("local_algorithm", o.local_algorithm, kLocalNames);
    o.local_xtol_rel = reader.Number("local_xtol_rel", o.local_xtol_rel, 0, true, inf, false);
    o.local_maxeval = static_cast<int>(reader.Int("local_maxeval", 0, 0, INT32_MAX));
  }
  if (reader.Has("failure_value")) {
    o.failure_value = reader.Number("failure_value", 0, -inf, false, inf, false);
  }
  reader.Finish();
  return o;
}

namespace {

class NloptOptimizer;

// What one replay needs inside the C callback.
struct ReplayContext {
  NloptOptimizer* self = nullptr;
  nlopt_opt opt = nullptr;
  size_t calls = 0;
  bool stopped = false;             // we forced the stop
  std::vector<double> next_raw;     // the first point beyond the stored ones
  std::string mismatch;             // non-empty: replay diverged
  std::exception_ptr error;         // anything else thrown inside
};

extern "C" double NloptReplayCallback(unsigned n, const double* x, double* grad, void* data);

class NloptOptimizer final : public Optimizer {
 public:
  NloptOptimizer(const NloptOptions& options, const Bounds& bounds, uint64_t seed)
      : o_(options), bounds_(bounds), seed_(seed) {
    OptHandle probe(Configure());  // fail at construction on bad settings
  }

  std::string name() const override { return "nlopt:" + o_.algorithm; }

  std::vector<Candidate> Ask(int /*max_count*/) override {
    if (finished_ || pending_) return {};
    if (!next_raw_) Replay();
    if (finished_) return {};
    pending_ = true;
    return {{static_cast<int64_t>(stored_.size()), Clip(*next_raw_)}};
  }

  void Tell(std::span<const Evaluation> results) override {
    for (const Evaluation& e : results) {
      if (!pending_ || e.id != static_cast<int64_t>(stored_.size())) {
        throw std::logic_error(fmt::format("{}: result for id {} was not asked", name(), e.id));
      }
      stored_.push_back({*next_raw_, e.failed ? std::numeric_limits<double>::infinity() : e.value,
                         e.failed, 0.0});
      stored_.back().nlopt_value = ValueForNlopt(stored_.size() - 1);
      pending_ = false;
      next_raw_.reset();
      Replay();  // find the next point now, so Done() is exact
    }
  }

  bool Done() const override { return finished_ && !pending_; }
  std::optional<std::vector<int64_t>> AwaitedIds() const override {
    if (!pending_) return std::vector<int64_t>{};
    return std::vector<int64_t>{static_cast<int64_t>(stored_.size())};
  }
  std::optional<IdCounts> Counts() const override {
    const auto told = static_cast<int64_t>(stored_.size());
    return IdCounts{told + (pending_ ? 1 : 0), told};
  }
  std::string StopReason() const override { return Done() ? stop_reason_ : ""; }

  nlohmann::json SaveState() const override {
    nlohmann::json evals = nlohmann::json::array();
    for (const auto& s : stored_) {
      evals.push_back({{"raw_x", internal::VectorToJson(s.raw_x)},
                       {"value", internal::DoubleToJson(s.value)},
                       {"failed", s.failed}});
    }
    return {{"evaluations", evals}, {"pending", pending_}};
  }

  void RestoreState(const nlohmann::json& state) override {
    stored_.clear();
    for (const auto& e : state.at("evaluations")) {
      // The replay compares NLopt's points with these, dimension by dimension.
      std::vector<double> raw_x = internal::VectorFromJson(e.at("raw_x"));
      if (raw_x.size() != bounds_.lower.size()) {
        throw std::invalid_argument(fmt::format(
            "{} state: evaluation {} has a point of {} coordinates; the search has {}", name(),
            stored_.size(), raw_x.size(), bounds_.lower.size()));
      }
      stored_.push_back({std::move(raw_x),
                         internal::DoubleFromJson(e.at("value")), e.at("failed").get<bool>(),
                         0.0});
      stored_.back().nlopt_value = ValueForNlopt(stored_.size() - 1);
    }
    finished_ = false;
    next_raw_.reset();
    Replay();  // checks the stored points bitwise
    pending_ = state.at("pending").get<bool>();
    if (pending_ && finished_) {
      throw std::invalid_argument(name() + " state: a candidate is pending but NLopt has finished");
    }
  }

  // Called from the C callback for the k-th objective call of a replay.
  double Answer(ReplayContext& ctx, const double* x) {
    const size_t k = ctx.calls++;
    const size_t n = bounds_.lower.size();
    if (ctx.stopped || !ctx.mismatch.empty()) {
      nlopt_force_stop(ctx.opt);
      return std::numeric_limits<double>::max();
    }
    if (k < stored_.size()) {
      if (std::memcmp(x, stored_[k].raw_x.data(), n * sizeof(double)) != 0) {
        ctx.mismatch = fmt::format("{}: replay diverged at evaluation {}: NLopt asked for a "
                                   "different point than the stored one",
                                   name(), k);
        nlopt_force_stop(ctx.opt);
        return std::numeric_limits<double>::max();
      }
      return stored_[k].nlopt_value;
    }
    ctx.next_raw.assign(x, x + n);
    ctx.stopped = true;
    nlopt_force_stop(ctx.opt);
    return std::numeric_limits<double>::max();
  }

 private:
  nlopt_opt Configure() const {
    const unsigned n = static_cast<unsigned>(bounds_.lower.size());
    const AlgorithmEntry* entry = FindAlgorithm(o_.algorithm);
    nlopt_opt opt = nlopt_create(entry->algorithm, n);
    if (!opt) throw std::invalid_argument(name() + ": NLopt could not create the optimiser");
    OptHandle guard(opt);
    const auto check = [&](nlopt_result r, const char* what) {
      if (r < 0) {
        throw std::invalid_argument(fmt::format("optimiser '{}': NLopt rejected {} (code {})",
                                                name(), what, static_cast<int>(r)));
      }
    };
    check(nlopt_set_lower_bounds(opt, bounds_.lower.data()), "the lower bounds");
    check(nlopt_set_upper_bounds(opt, bounds_.upper.data()), "the upper bounds");
    check(nlopt_set_maxeval(opt, o_.maxeval), "maxeval");
    check(nlopt_set_xtol_rel(opt, o_.xtol_rel), "xtol_rel");
    check(nlopt_set_ftol_rel(opt, o_.ftol_rel), "ftol_rel");
    if (o_.initial_step) {
      std::vector<double> dx(n);
      for (unsigned i = 0; i < n; ++i) dx[i] = *o_.initial_step * (bounds_.upper[i] - bounds_.lower[i]);
      check(nlopt_set_initial_step(opt, dx.data()), "initial_step");
    }
    if (entry->uses_population && o_.population > 0) {
      check(nlopt_set_population(opt, static_cast<unsigned>(o_.population)), "population");
    }
    if (o_.algorithm == "MLSL") {
      nlopt_opt local = nlopt_create(FindAlgorithm(o_.local_algorithm)->algorithm, n);
      OptHandle local_guard(local);
      check(nlopt_set_xtol_rel(local, o_.local_xtol_rel), "local_xtol_rel");
      if (o_.local_maxeval > 0) check(nlopt_set_maxeval(local, o_.local_maxeval), "local_maxeval");
      check(nlopt_set_local_optimizer(opt, local), "local_algorithm");  // NLopt copies it
    }
    guard.opt = nullptr;
    return opt;
  }

  std::vector<double> Clip(const std::vector<double>& raw) const {
    std::vector<double> x(raw.size());
    for (size_t i = 0; i < raw.size(); ++i) {
      x[i] = std::clamp(raw[i], bounds_.lower[i], bounds_.upper[i]);
      if (std::isnan(raw[i])) x[i] = 0.5 * (bounds_.lower[i] + bounds_.upper[i]);
    }
    return x;
  }

  // What NLopt is told for stored evaluation k; depends on evaluations
  // 0..k only, so a replay reproduces it.
  double ValueForNlopt(size_t k) const {
    if (!stored_[k].failed) return stored_[k].value;
    if (o_.failure_value) return *o_.failure_value;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (size_t i = 0; i < k; ++i) {
      if (!stored_[i].failed) {
        lo = std::min(lo, stored_[i].value);
        hi = std::max(hi, stored_[i].value);
      }
    }
    if (hi < lo) return 1e10;
    return hi + std::max(1.0, hi - lo);
  }

  void Replay() {
    std::lock_guard<std::mutex> lock(ReplayMutex());
    OptHandle handle(Configure());
    ReplayContext ctx;
    ctx.self = this;
    ctx.opt = handle.opt;
    if (nlopt_set_min_objective(handle.opt, &NloptReplayCallback, &ctx) < 0) {
      throw std::logic_error(name() + ": NLopt rejected the objective");
    }
    std::vector<double> x(bounds_.lower.size());
    for (size_t i = 0; i < x.size(); ++i) {
      x[i] = o_.x0 ? (*o_.x0)[i] : 0.5 * (bounds_.lower[i] + bounds_.upper[i]);
    }
    nlopt_srand(static_cast<unsigned long>(seed_));
    double f = 0;
    const nlopt_result result = nlopt_optimize(handle.opt, x.data(), &f);
    if (ctx.error) std::rethrow_exception(ctx.error);
    if (!ctx.mismatch.empty()) throw std::logic_error(ctx.mismatch);
    if (ctx.stopped && static_cast<int64_t>(stored_.size()) >= o_.maxeval) {
      // Some algorithms (CRS2_LM's initial population) evaluate past
      // maxeval; the budget is a hard limit here.
      finished_ = true;
      stop_reason_ = fmt::format("maxeval = {} reached (NLopt asked for more)", o_.maxeval);
      return;
    }
    if (ctx.stopped) {
      next_raw_ = std::move(ctx.next_raw);
      return;
    }
    if (ctx.calls < stored_.size()) {
      throw std::logic_error(fmt::format(
          "{}: replay diverged: NLopt finished after {} evaluations, {} are stored", name(),
          ctx.calls, stored_.size()));
    }
    finished_ = true;
    stop_reason_ = fmt::format("NLopt returned {} after {} evaluations", ResultName(result),
                               stored_.size());
  }

  static const char* ResultName(nlopt_result r) {
    switch (r) {
      case NLOPT_SUCCESS: return "SUCCESS";
      case NLOPT_STOPVAL_REACHED: return "STOPVAL_REACHED";
      case NLOPT_FTOL_REACHED: return "FTOL_REACHED";
      case NLOPT_XTOL_REACHED: return "XTOL_REACHED";
      case NLOPT_MAXEVAL_REACHED: return "MAXEVAL_REACHED";
      case NLOPT_MAXTIME_REACHED: return "MAXTIME_REACHED";
      case NLOPT_FAILURE: return "FAILURE";
      case NLOPT_INVALID_ARGS: return "INVALID_ARGS";
      case NLOPT_OUT_OF_MEMORY: return "OUT_OF_MEMORY";
      case NLOPT_ROUNDOFF_LIMITED: return "ROUNDOFF_LIMITED";
      case NLOPT_FORCED_STOP: return "FORCED_STOP";
      default: break;
    }
    return "an unknown code";
  }

  NloptOptions o_;
  Bounds bounds_;
  uint64_t seed_;
  std::vector<StoredEvaluation> stored_;
  std::optional<std::vector<double>> next_raw_;  // next candidate, not yet asked
  bool pending_ = false;                         // next_raw_ asked, not told
  bool finished_ = false;
  std::string stop_reason_;
};

// No exception may cross NLopt's C frames: everything is caught here and
// rethrown by Replay() after nlopt_optimize returns.
extern "C" double NloptReplayCallback(unsigned /*n*/, const double* x, double* /*grad*/,
                                      void* data) {
  auto* ctx = static_cast<ReplayContext*>(data);
  try {
    return ctx->self->Answer(*ctx, x);
  } catch (...) {
    ctx->error = std::current_exception();
    nlopt_force_stop(ctx->opt);
    return std::numeric_limits<double>::max();
  }
}

}  // namespace

std::unique_ptr<Optimizer> MakeNlopt(const NloptOptions& options, const Bounds& bounds,
                                     uint64_t seed) {
  return std::make_unique<NloptOptimizer>(options, bounds, seed);
}

}  // namespace calib::search
