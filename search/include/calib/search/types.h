// Value types shared by every optimiser: the search box, a proposed
// candidate and the result of evaluating one.
#pragma once

#include <cstdint>
#include <vector>

namespace calib::search {

// The box the optimisers search: lower[i] < upper[i], both finite, one entry
// per parameter (n >= 1). Optimisers minimise over this box and never
// propose a point outside it (bounds inclusive). The job runner maps
// log-scale parameters into this box; the optimisers do not know units.
struct Bounds {
  std::vector<double> lower;
  std::vector<double> upper;

  int dimension() const { return static_cast<int>(lower.size()); }
};

// Throws std::invalid_argument naming the coordinate, its values and the
// rule (sizes equal and >= 1, finite, lower < upper).
void ValidateBounds(const Bounds& bounds);

// A point to evaluate. Ids are consecutive from 0 in ask order over the
// whole life of an optimiser (across saves and restores).
struct Candidate {
  int64_t id = 0;
  std::vector<double> x;  // size n, within the bounds
};

// The score of an asked candidate; lower is better. failed = true (or a
// value that is NaN or infinite) marks an evaluation that produced no usable
// score (e.g. the simulation blew up): every optimiser treats it as worse
// than any finite value. x must be the candidate's x, unchanged.
struct Evaluation {
  int64_t id = 0;
  std::vector<double> x;
  double value = 0.0;
  bool failed = false;
};

}  // namespace calib::search
