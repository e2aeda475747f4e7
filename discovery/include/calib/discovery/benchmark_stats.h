#pragma once
// The statistics of the loop benchmark (loop_benchmark.h, docs/loop.md "Loop
// benchmark"): a proportion with its Wilson score interval, quartiles of a
// sample, and the confusion table of effects present against effects kept.
// Pure functions of their arguments.

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace calib {

/// A proportion `successes / trials` with its confidence interval. With no
/// trials the rate is NaN and the interval is [0, 1] (nothing is known).
struct Proportion {
  int64_t successes = 0;
  int64_t trials = 0;
  double rate = NAN;
  double lower = 0.0;
  double upper = 1.0;
};

/// z of a two-sided 95 % interval of the normal distribution.
inline constexpr double kZ95 = 1.959963984540054;

/// The Wilson score interval (Wilson 1927; Newcombe 1998, method 3):
///   centre = (p + z^2 / 2n) / (1 + z^2 / n)
///   half   = z / (1 + z^2 / n) * sqrt(p (1 - p) / n + z^2 / 4n^2)
/// with p = successes / trials, n = trials; clamped to [0, 1]. Throws
/// std::invalid_argument unless 0 <= successes <= trials and z > 0.
Proportion WilsonInterval(int64_t successes, int64_t trials, double z = kZ95);

/// The quartiles of a sample, linearly interpolated between order
/// statistics (Hyndman & Fan type 7: R's and numpy's default): the quantile
/// p of n sorted values is at rank (n - 1) p. NaN for an empty sample;
/// NaN values are left out.
struct Quartiles {
  int count = 0;
  double min = NAN;
  double q1 = NAN;
  double median = NAN;
  double q3 = NAN;
  double max = NAN;
};
Quartiles QuartilesOf(std::vector<double> values);

/// The type-7 quantile p in [0, 1] of `sorted` (ascending, no NaN); NaN
/// when empty.
double SortedQuantile(const std::vector<double>& sorted, double p);

/// Row label of objects with no effect; column label of objects where the
/// loop kept nothing.
inline constexpr const char* kNoEffect = "none";
inline constexpr const char* kNothingKept = "nothing";

/// What one object had and what the loop kept on it.
struct PresentKept {
  std::string present;            ///< a loop effect name; empty: none
  std::vector<std::string> kept;  ///< effects kept; empty: nothing
};

/// Counts of objects by effect present (rows) and effect kept (columns).
/// An object that kept two effects counts once in each of their columns,
/// so a row's counts can sum to more than its objects (`row_objects`).
struct ConfusionTable {
  std::vector<std::string> rows;             ///< effects, then kNoEffect
  std::vector<std::string> columns;          ///< effects, then kNothingKept
  std::vector<std::vector<int64_t>> counts;  ///< [row][column]
  std::vector<int64_t> row_objects;          ///< objects per row

  /// The count at (row label, column label); 0 for an unknown label.
  int64_t At(const std::string& row, const std::string& column) const;
};

/// The confusion table of `objects`. Rows and columns are `effects` in
/// their order, then any other effect the objects name (sorted), then
/// "none" / "nothing".
ConfusionTable CountConfusion(const std::vector<std::string>& effects,
                              const std::vector<PresentKept>& objects);

}  // namespace calib
