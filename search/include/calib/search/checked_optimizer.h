// CheckedOptimizer: what the job runner holds. Wraps a plug-in (pagmo style)
// and checks everything that crosses the interface, once:
//  - Ask: at most max_count candidates, ids consecutive from the previous
//    ones, dimension n, every coordinate finite and within the bounds.
//    A plug-in that breaks this is a bug: std::logic_error naming the
//    optimiser, the candidate id, the coordinate and the value.
//  - Tell: every id asked and not yet told, no id twice, x of size n and
//    equal to the asked x. Bad input throws std::invalid_argument naming the
//    id and leaves the state unchanged. NaN or infinite values are folded
//    into failed = true before the plug-in sees them; results reach the
//    plug-in sorted by id.
// It also keeps what the runner needs whatever the plug-in: the best
// evaluation so far (ties: lowest id, so arrival order never matters), the
// outstanding (asked, untold) candidates and the counts. Its saved state
// wraps the plug-in's.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"
#include "calib/search/types.h"

namespace calib::search {

class CheckedOptimizer {
 public:
  // bounds must be the plug-in's bounds; validated here.
  CheckedOptimizer(std::unique_ptr<Optimizer> plugin, Bounds bounds);

  std::string name() const { return plugin_->name(); }
  int dimension() const { return bounds_.dimension(); }
  const Bounds& bounds() const { return bounds_; }

  // max_count >= 1 (std::invalid_argument otherwise).
  std::vector<Candidate> Ask(int max_count);
  void Tell(std::span<const Evaluation> results);
  void Tell(const Evaluation& result) { Tell(std::span<const Evaluation>(&result, 1)); }

  // The plug-in is done and nothing is outstanding.
  bool Done() const;
  std::string StopReason() const { return plugin_->StopReason(); }

  // Asked and not yet told, by id (after a restore: what to re-evaluate).
  std::vector<Candidate> Outstanding() const;
  // Lowest value among told, non-failed evaluations; nullopt if none.
  const std::optional<Evaluation>& Best() const { return best_; }
  int64_t asked_count() const { return next_id_; }
  int64_t told_count() const { return told_count_; }
  int64_t failed_count() const { return failed_count_; }

  // {"optimizer", "dimension", "next_id", "told", "failed", "best",
  //  "outstanding", "plugin"}: plain JSON; dump/parse round-trips exactly.
  nlohmann::json SaveState() const;
  // On a fresh CheckedOptimizer made with the same arguments. Throws
  // std::invalid_argument if the state belongs to another optimiser or
  // dimension, or is malformed (NLopt: or does not replay); after a throw
  // the optimiser is in an unspecified state and must be discarded.
  void RestoreState(const nlohmann::json& state);

 private:
  // Throws std::invalid_argument when a restored state's counts, outstanding
  // ids and points disagree with each other, the bounds or the plug-in.
  void CheckRestoredCounts() const;

  std::unique_ptr<Optimizer> plugin_;
  Bounds bounds_;
  int64_t next_id_ = 0;
  int64_t told_count_ = 0;
  int64_t failed_count_ = 0;
  std::map<int64_t, std::vector<double>> outstanding_;
  std::optional<Evaluation> best_;
};

}  // namespace calib::search
