#include "calib/search/external_optimizer.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "line_process.h"
#include "settings.h"
#include "state_util.h"

namespace calib::search {

ExternalOptions ExternalOptions::FromJson(const nlohmann::json& settings) {
  internal::SettingsReader reader("external", settings);
  ExternalOptions o;
  if (!reader.Has("command")) {
    reader.Fail("command", nullptr, "required: the program and its arguments, a list of strings");
  }
  const nlohmann::json& command = reader.Raw("command");
  if (!command.is_array() || command.empty() ||
      !std::all_of(command.begin(), command.end(), [](const nlohmann::json& a) { return a.is_string(); })) {
    reader.Fail("command", command, "must be a non-empty list of strings (the program and its arguments)");
  }
  o.command = command.get<std::vector<std::string>>();
  if (o.command.front().empty()) reader.Fail("command", command, "the program must not be empty");
  if (reader.Has("options")) {
    o.options = reader.Raw("options");
    if (!o.options.is_object()) reader.Fail("options", o.options, "must be an object");
  }
  o.batch = static_cast<int>(reader.Int("batch", o.batch, 1, 100000));
  o.max_evals = reader.Int("max_evals", o.max_evals, 1, INT64_MAX);
  o.timeout_s = reader.Number("timeout_s", o.timeout_s, 0.0, true, 86400.0, false);
  reader.Finish();
  return o;
}

namespace {

using Kind = ExternalOptimizerError::Kind;

class ExternalOptimizer final : public Optimizer {
 public:
  ExternalOptimizer(ExternalOptions options, const Bounds& bounds, uint64_t seed)
      : options_(std::move(options)), bounds_(bounds), seed_(seed) {}

  std::string name() const override { return "external"; }

  std::vector<Candidate> Ask(int max_count) override {
    if (handed_ == pending_.size()) {
      if (!pending_.empty() || done_) return {};  // results first, or nothing more
      if (asked_ >= options_.max_evals) {
        done_ = true;
        stop_reason_ = fmt::format("budget of {} evaluations used", options_.max_evals);
        return {};
      }
      RequestBatch();
      if (pending_.empty()) return {};
    }
    std::vector<Candidate> out;
    while (handed_ < pending_.size() && static_cast<int>(out.size()) < max_count) out.push_back(pending_[handed_++]);
    return out;
  }

  void Tell(std::span<const Evaluation> results) override {
    for (const Evaluation& e : results) told_[e.id] = e;
    if (pending_.empty() || told_.size() < pending_.size()) return;
    nlohmann::json list = nlohmann::json::array();
    for (const Candidate& c : pending_) {
      const Evaluation& e = told_.at(c.id);
      list.push_back({{"x", c.x}, {"value", e.failed ? nlohmann::json(nullptr) : nlohmann::json(e.value)}});
    }
    Exchange({{"op", "tell"}, {"results", list}});
    pending_.clear();
    told_.clear();
    handed_ = 0;
    if (asked_ >= options_.max_evals) {
      done_ = true;
      stop_reason_ = fmt::format("budget of {} evaluations used", options_.max_evals);
    }
  }

  bool Done() const override { return done_ && pending_.empty(); }
  std::string StopReason() const override { return Done() ? stop_reason_ : ""; }

  nlohmann::json SaveState() const override {
    nlohmann::json pending = nlohmann::json::array();
    for (const Candidate& c : pending_) pending.push_back({{"id", c.id}, {"x", c.x}});
    nlohmann::json told = nlohmann::json::array();
    for (const auto& [id, e] : told_) {
      told.push_back({{"id", id}, {"value", internal::DoubleToJson(e.value)}, {"failed", e.failed}});
    }
    const nlohmann::json reply = const_cast<ExternalOptimizer*>(this)->Exchange({{"op", "save"}});
    if (!reply.contains("state")) Garbage(reply.dump(), "a save reply holds \"state\"");
    return {{"asked", asked_},   {"done", done_}, {"stop_reason", stop_reason_}, {"pending", pending},
            {"handed", handed_}, {"told", told},  {"process", reply["state"]}};
  }

  void RestoreState(const nlohmann::json& state) override {
    nlohmann::json process_state;
    try {
      process_state = state.at("process");
      asked_ = internal::IntFromJson<int64_t>(state.at("asked"), "asked");
      done_ = state.at("done").get<bool>();
      stop_reason_ = state.at("stop_reason").get<std::string>();
      pending_.clear();
      for (const auto& c : state.at("pending")) {
        pending_.push_back({internal::IntFromJson<int64_t>(c.at("id"), "id"), c.at("x").get<std::vector<double>>()});
      }
      handed_ = internal::IntFromJson<size_t>(state.at("handed"), "handed");
      if (handed_ > pending_.size()) throw std::invalid_argument("more handed out than asked");
      // The batch holds the last ids asked of the program, in order (Counts
      // relies on it).
      const auto batch_size = static_cast<int64_t>(pending_.size());
      if (asked_ < batch_size) {
        throw std::invalid_argument(
            fmt::format("{} asked but a batch of {} pending", asked_, batch_size));
      }
      for (int64_t k = 0; k < batch_size; ++k) {
        if (pending_[k].id != asked_ - batch_size + k) {
          throw std::invalid_argument(fmt::format("pending id {} is not the asked id {}",
                                                  pending_[k].id, asked_ - batch_size + k));
        }
      }
      told_.clear();
      for (const auto& t : state.at("told")) {
        const int64_t id = internal::IntFromJson<int64_t>(t.at("id"), "id");
        const auto it = std::find_if(pending_.begin(), pending_.end(), [&](const Candidate& c) { return c.id == id; });
        if (it == pending_.end()) throw std::invalid_argument(fmt::format("told id {} was not asked", id));
        told_[id] = {id, it->x, internal::DoubleFromJson(t.at("value")), t.at("failed").get<bool>()};
      }
    } catch (const nlohmann::json::exception& e) {
      throw std::invalid_argument(fmt::format("external: state is not this optimiser's: {}", e.what()));
    }
    Exchange({{"op", "restore"}, {"state", process_state}});
  }

  // Every id before the pending batch was handed out and told (a batch is
  // cleared once all of it is told); of the batch, `handed_` were handed out
  // and told_ holds those told.
  std::optional<IdCounts> Counts() const override {
    const int64_t before = asked_ - static_cast<int64_t>(pending_.size());
    return IdCounts{before + static_cast<int64_t>(handed_),
                    before + static_cast<int64_t>(told_.size())};
  }

  std::optional<std::vector<int64_t>> AwaitedIds() const override {
    std::vector<int64_t> ids;  // handed out by Ask, not yet told
    for (size_t i = 0; i < handed_; ++i) {
      if (!told_.count(pending_[i].id)) ids.push_back(pending_[i].id);
    }
    return ids;
  }

 private:
  std::string Command() const { return fmt::format("external optimiser '{}'", fmt::join(options_.command, " ")); }

  [[noreturn]] void Garbage(const std::string& line, const std::string& rule) const {
    const std::string shown = line.size() > 200 ? line.substr(0, 200) + "..." : line;
    throw ExternalOptimizerError(Kind::kGarbage,
                                 fmt::format("{} printed garbage: '{}': expected {}", Command(), shown, rule));
  }

  // Starts the program and sends "start" (once).
  void EnsureStarted() {
    if (process_) return;
    try {
      process_ = std::make_unique<internal::LineProcess>(options_.command);
    } catch (const std::runtime_error& e) {
      throw ExternalOptimizerError(Kind::kCannotStart, fmt::format("{}: {}", Command(), e.what()));
    }
    Send({{"op", "start"},
          {"dimension", bounds_.dimension()},
          {"lower", bounds_.lower},
          {"upper", bounds_.upper},
          {"seed", seed_},
          {"options", options_.options}});
  }

  // One request and its reply (an object without "error").
  nlohmann::json Exchange(const nlohmann::json& request) {
    EnsureStarted();
    return Send(request);
  }

  nlohmann::json Send(const nlohmann::json& request) {
    const std::string op = request.at("op").get<std::string>();
    if (!process_->WriteLine(request.dump())) {
      throw ExternalOptimizerError(Kind::kExited, fmt::format("{} {} before the '{}' request", Command(),
                                                              process_->HowItEnded(), op));
    }
    std::string line;
    switch (process_->ReadLine(options_.timeout_s, &line)) {
      case internal::LineProcess::ReadStatus::kEnded:
        throw ExternalOptimizerError(Kind::kExited, fmt::format("{} {} without replying to '{}'", Command(),
                                                                process_->HowItEnded(), op));
      case internal::LineProcess::ReadStatus::kTimedOut:
        process_->Kill();
        throw ExternalOptimizerError(
            Kind::kTimedOut, fmt::format("{} did not reply to '{}' within {} s (timeout_s); it was stopped",
                                         Command(), op, options_.timeout_s));
      case internal::LineProcess::ReadStatus::kLine:
        break;
    }
    nlohmann::json reply;
    try {
      reply = nlohmann::json::parse(line);
    } catch (const nlohmann::json::parse_error&) {
      Garbage(line, fmt::format("one JSON object replying to '{}'", op));
    }
    if (!reply.is_object()) Garbage(line, fmt::format("one JSON object replying to '{}'", op));
    if (reply.contains("error")) {
      throw ExternalOptimizerError(Kind::kRefused,
                                   fmt::format("{} refused '{}': {}", Command(), op, reply["error"].dump()));
    }
    return reply;
  }

  void RequestBatch() {
    const int64_t count = std::min<int64_t>(options_.batch, options_.max_evals - asked_);
    const nlohmann::json reply = Exchange({{"op", "ask"}, {"count", count}});
    const auto it = reply.find("points");
    if (it == reply.end() || !it->is_array()) Garbage(reply.dump(), "{\"points\": [[x...], ...]} replying to 'ask'");
    if (it->empty()) {
      done_ = true;
      stop_reason_ = "the external optimiser is done";
      return;
    }
    if (static_cast<int64_t>(it->size()) > count) {
      Garbage(reply.dump(), fmt::format("at most {} points (asked for {})", count, count));
    }
    for (const auto& p : *it) {
      const int n = bounds_.dimension();
      if (!p.is_array() || static_cast<int>(p.size()) != n ||
          !std::all_of(p.begin(), p.end(), [](const nlohmann::json& v) { return v.is_number(); })) {
        throw ExternalOptimizerError(Kind::kOutOfBox, fmt::format("{} proposed {}: expected {} finite numbers",
                                                                  Command(), p.dump(), n));
      }
      std::vector<double> x = p.get<std::vector<double>>();
      for (int i = 0; i < n; ++i) {
        if (!std::isfinite(x[i]) || x[i] < bounds_.lower[i] || x[i] > bounds_.upper[i]) {
          throw ExternalOptimizerError(
              Kind::kOutOfBox, fmt::format("{} proposed a point outside the box: x[{}] = {} not in [{}, {}]",
                                           Command(), i, x[i], bounds_.lower[i], bounds_.upper[i]));
        }
      }
      pending_.push_back({asked_++, std::move(x)});
    }
    handed_ = 0;
  }

  ExternalOptions options_;
  Bounds bounds_;
  uint64_t seed_;
  std::unique_ptr<internal::LineProcess> process_;
  int64_t asked_ = 0;
  bool done_ = false;
  std::string stop_reason_;
  std::vector<Candidate> pending_;  // the batch asked of the program, ask order
  size_t handed_ = 0;               // of pending_, handed out by Ask
  std::map<int64_t, Evaluation> told_;  // results of pending_ so far
};

}  // namespace

std::unique_ptr<Optimizer> MakeExternal(const ExternalOptions& options, const Bounds& bounds, uint64_t seed) {
  return std::make_unique<ExternalOptimizer>(options, bounds, seed);
}

}  // namespace calib::search
