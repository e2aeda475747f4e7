// The plug-in interface every optimiser implements: ask/tell over a box.
//
// Contract (the checked wrapper, checked_optimizer.h, enforces the parts that
// can be checked from outside, so a plug-in holds only its maths):
//  - Minimise f over the construction-time Bounds.
//  - Ask(max_count), max_count >= 1, returns at most max_count new
//    candidates that may be evaluated in parallel. Ids continue
//    consecutively from the previous Ask, starting at 0. It may return fewer
//    (NLopt: at most 1), or none while it needs results first; it returns
//    none when Done().
//  - The candidates proposed never depend on max_count: asking 1 at a time
//    or 100 at a time yields the same sequence (batches are settings, e.g.
//    a population size), so the history is the same for any thread count.
//  - Tell(results) takes results of asked candidates in any order and any
//    grouping; each id is told once. Plug-ins see results sorted by id, with
//    failed == true whenever the score is unusable (the wrapper folds NaN
//    and infinities into failed), and must make the next Ask independent of
//    the order in which one batch's results arrived.
//  - Done() is true once the optimiser will propose nothing more and every
//    asked candidate has been told.
//  - SaveState() captures everything (RNG included), at any moment, also
//    between an Ask and the Tell of its results; RestoreState() on a fresh
//    optimiser built with the same name, settings, bounds and seed continues
//    exactly as the saved one would have. Asked-but-untold candidates stay
//    outstanding after a restore: the caller re-evaluates and tells them.
//  - Never creates threads, prints, or touches files. Throws
//    std::invalid_argument for bad settings (at construction) and for state
//    that does not belong to it (RestoreState).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/search/types.h"

namespace calib::search {

class Optimizer {
 public:
  virtual ~Optimizer() = default;

  // "grid", "random", "genetic", "annealing", "cmaes" or "nlopt:<ALGO>".
  virtual std::string name() const = 0;
  virtual std::vector<Candidate> Ask(int max_count) = 0;
  virtual void Tell(std::span<const Evaluation> results) = 0;
  virtual bool Done() const = 0;
  // Why Done() became true (e.g. "budget of 200 evaluations used",
  // "NLopt: xtol_rel reached"); empty while not done.
  virtual std::string StopReason() const = 0;
  virtual nlohmann::json SaveState() const = 0;
  virtual void RestoreState(const nlohmann::json& state) = 0;
  // The ids this optimiser waits for results of (asked, not yet told),
  // where its state says; nullopt (the default) where it does not. The
  // checked wrapper compares them with the outstanding candidates of a
  // restored state, so that a state whose parts disagree is refused by
  // RestoreState instead of failing at the next Ask or Tell.
  virtual std::optional<std::vector<int64_t>> AwaitedIds() const { return std::nullopt; }

  // How many candidates this optimiser has handed out (its next id) and how
  // many results it has been told, where its state says; nullopt (the
  // default) where it does not. The checked wrapper compares them with its
  // own counts of a restored state, as it does AwaitedIds.
  struct IdCounts {
    int64_t asked = 0;
    int64_t told = 0;
  };
  virtual std::optional<IdCounts> Counts() const { return std::nullopt; }
};

}  // namespace calib::search
