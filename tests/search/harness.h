// Test harness for calib::search: standard functions (shifted so that no
// optimum sits at the box centre, where a grid or DIRECT would find it by
// construction) and an ask/tell cycle like the job runner's.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <vector>

#include "calib/search/checked_optimizer.h"
#include "calib/search/factory.h"

namespace calib::search::testing {

using Objective = std::function<double(const std::vector<double>&)>;

// Sphere on [-5, 5]^n, minimum 0 at x_i = 1.3.
inline double Sphere(const std::vector<double>& x) {
  double f = 0;
  for (double v : x) f += (v - 1.3) * (v - 1.3);
  return f;
}

// Rosenbrock on [-2, 2]^n, minimum 0 at x_i = 1.
inline double Rosenbrock(const std::vector<double>& x) {
  double f = 0;
  for (size_t i = 0; i + 1 < x.size(); ++i) {
    f += 100 * std::pow(x[i + 1] - x[i] * x[i], 2) + std::pow(1 - x[i], 2);
  }
  return f;
}

// Rastrigin on [-5.12, 5.12]^n shifted, minimum 0 at x_i = 1.1. (Not 1.7:
// that sits exactly on a boundary of DIRECT's trisection, (1.7 + 5.12) /
// 10.24 = 2/3, which DIRECT, sampling cell centres, approaches only slowly.)
inline double Rastrigin(const std::vector<double>& x) {
  double f = 10.0 * x.size();
  for (double v : x) {
    const double z = v - 1.1;
    f += z * z - 10 * std::cos(2 * std::numbers::pi * z);
  }
  return f;
}

inline Bounds Box(int n, double lo, double hi) {
  return {std::vector<double>(n, lo), std::vector<double>(n, hi)};
}

struct History {
  std::vector<Candidate> asked;  // in ask order
  double best = std::numeric_limits<double>::infinity();
  int64_t failed = 0;
  bool stuck = false;  // Ask returned nothing while not done and nothing outstanding
};

// How results of one Ask are told back.
enum class TellOrder { kInOrder, kReversed, kOneByOneShuffled };

inline Evaluation Evaluate(const Objective& f, const Candidate& c) {
  const double v = f(c.x);
  return {c.id, c.x, v, !std::isfinite(v)};
}

// Asks up to max_count, evaluates, tells; until done or `limit` asked.
inline History RunOptimizer(CheckedOptimizer& opt, const Objective& f, int max_count,
                   TellOrder order = TellOrder::kInOrder, int64_t limit = 1000000) {
  History h;
  uint64_t shuffle_state = 12345;
  while (!opt.Done() && opt.asked_count() < limit) {
    std::vector<Candidate> batch = opt.Ask(max_count);
    if (batch.empty()) {
      h.stuck = true;
      break;
    }
    std::vector<Evaluation> results;
    for (const Candidate& c : batch) {
      h.asked.push_back(c);
      results.push_back(Evaluate(f, c));
    }
    if (order == TellOrder::kInOrder) {
      opt.Tell(results);
    } else if (order == TellOrder::kReversed) {
      std::reverse(results.begin(), results.end());
      opt.Tell(results);
    } else {
      for (size_t i = results.size(); i > 1; --i) {  // Fisher-Yates, own LCG
        shuffle_state = shuffle_state * 6364136223846793005ULL + 1442695040888963407ULL;
        std::swap(results[i - 1], results[(shuffle_state >> 33) % i]);
      }
      for (const Evaluation& e : results) opt.Tell(e);
    }
  }
  if (opt.Best()) h.best = opt.Best()->value;
  h.failed = opt.failed_count();
  return h;
}

inline bool SameCandidates(const std::vector<Candidate>& a, const std::vector<Candidate>& b,
                           std::string* why) {
  if (a.size() != b.size()) {
    *why = "lengths " + std::to_string(a.size()) + " and " + std::to_string(b.size());
    return false;
  }
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].id != b[i].id || a[i].x != b[i].x) {
      *why = "first difference at candidate " + std::to_string(i);
      return false;
    }
  }
  return true;
}

}  // namespace calib::search::testing
