// External optimisers: a program that speaks ask/tell as JSON lines on its
// standard input and output (the protocol: docs/compare.md, "External
// optimisers"), behind the Optimizer interface. search/optuna_bridge.py
// is one, for Optuna's TPE and CMA-ES samplers.
//
// This plug-in's maths runs in another process, so unlike the others it
// starts one (lazily, at the first Ask or RestoreState, so that reading a
// spec never does) and talks to it; it still never prints or touches
// files. The program's standard error is the caller's. SIGPIPE is ignored
// process-wide once a program is started (a program that exits must be an
// error, not the end of calib).
//
// Exchanges, one request line and one reply line each:
//   start    {"op":"start","dimension":n,"lower":[...],"upper":[...],"seed":S,"options":{...}}
//            -> {"ok":true}
//   ask      {"op":"ask","count":k}  -> {"points":[[x...],...]}   1..k points; [] = done
//   tell     {"op":"tell","results":[{"x":[...],"value":v},...]} -> {"ok":true}
//            (the asked batch in ask order; value null for a failed evaluation)
//   save     {"op":"save"}            -> {"state":<any JSON>}
//   restore  {"op":"restore","state":<what save gave>} -> {"ok":true}
// Any reply may be {"error":"why"} instead. The program is asked `batch`
// points at a time (never more than the budget leaves), and told them all
// at once when every one is evaluated, so what it sees never depends on the
// number of threads. Its saved state must restore it exactly (random state
// included): a resumed job re-asks and compares the points bit for bit.
//
// Settings (JSON object):
//   command    array of >= 1 strings (required): the program and its
//              arguments, run directly (no shell), from the current folder
//   options    object                         default {}: passed in "start"
//   batch      integer >= 1                   default 1
//   max_evals  integer >= 1                   default 200
//   timeout_s  number > 0                     default 60: each reply's limit
#pragma once

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "calib/search/optimizer.h"

namespace calib::search {

// A misbehaving external program; what() names the command, what it did
// (the kind's words) and, for garbage, the line it printed.
class ExternalOptimizerError : public std::runtime_error {
 public:
  enum class Kind {
    kCannotStart,  // the program cannot be run
    kExited,       // it exited (or was killed) while a reply was awaited
    kTimedOut,     // no reply within timeout_s; it is killed
    kGarbage,      // a reply that is not the protocol's JSON
    kOutOfBox,     // a point outside the box (or of the wrong size, not finite)
    kRefused,      // it replied {"error": ...}
  };
  ExternalOptimizerError(Kind kind, const std::string& message)
      : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

struct ExternalOptions {
  std::vector<std::string> command;
  nlohmann::json options = nlohmann::json::object();
  int batch = 1;
  int64_t max_evals = 200;
  double timeout_s = 60.0;

  // Throws std::invalid_argument naming "external", the key, value and rule.
  static ExternalOptions FromJson(const nlohmann::json& settings);
};

std::unique_ptr<Optimizer> MakeExternal(const ExternalOptions& options, const Bounds& bounds,
                                        uint64_t seed);

}  // namespace calib::search
