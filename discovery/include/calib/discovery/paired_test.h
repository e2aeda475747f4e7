#pragma once
// The statistics of the loop's keep rule (docs/loop.md, "The keep rule"):
// a one-sided paired test of "the new model lowers the held-out error" on
// per-frame differences, by a sign-flip randomisation test over blocks of
// consecutive frames (blocks keep the frames' autocorrelation), and the
// Benjamini-Hochberg correction for the number of hypotheses tried.
//
// Why blocks that flip rather than a block bootstrap: on autocorrelated
// series of a push's length (330 frames, AR(1) with phi = 0.9) a circular
// block bootstrap of the total rejected a true null 9 % of the time at the
// 5 % level, the block sign-flip 4 % (tests/discovery/paired_test_test.cpp).
//
// Everything here is deterministic: the signs come from the test's own seeded
// generator (the same seed gives the same p-value on every machine).

#include <cstdint>
#include <span>
#include <vector>

namespace calib {

/// Block length of the circular block bootstrap for the series `x`, by the
/// automatic rule of Politis & White (2004) with the correction of Patton,
/// Politis & White (2009): the flat-top lag window's bandwidth from the
/// first run of insignificant autocorrelations, then
/// b = (2 G^2 / D)^(1/3) n^(1/3), clamped to [1, min(3 sqrt(n), n / 3)].
/// 1 for fewer than 8 values or a constant series.
int AutomaticBlockLength(std::span<const double> x);

/// The block length of the paired test for the series `x`: twice the
/// automatic length, so that neighbouring blocks' sums are nearly
/// independent, and at most n / 10 so that there are at least 10 blocks
/// (the smallest p-value is about 2^-blocks).
int TestBlockLength(std::span<const double> x);

/// The paired comparison of two models over frames of one or more
/// recordings: `differences[r][f]` = the old model's error minus the new
/// one's on frame f of recording r (positive: the new model is better).
struct PairedTestOptions {
  int resamples = 9999;
  uint64_t seed = 1;
};

struct PairedTestResult {
  double total = 0.0;          ///< sum of the differences (the drop of the summed error)
  int frames = 0;
  std::vector<int> block_lengths;  ///< per recording (TestBlockLength)
  int blocks = 0;                  ///< over all recordings
  int resamples = 0;
  /// One-sided p-value of H0 "the new model does not lower the error",
  /// by a block sign-flip randomisation test: each recording's frames are
  /// cut into consecutive blocks (never across recordings), and under H0 a
  /// block's summed difference is as likely to be negative as positive;
  /// p = (1 + #{T* >= T}) / (resamples + 1) over the totals T* with random
  /// signs. 1 when every difference is 0.
  double p_value = 1.0;
  /// 95 % interval of the total drop from the randomisation distribution.
  double total_low = 0.0;
  double total_high = 0.0;
};

/// Throws std::invalid_argument for no frames, a non-finite difference or
/// resamples < 1.
PairedTestResult PairedBlockTest(const std::vector<std::vector<double>>& differences,
                                 const PairedTestOptions& options);

/// The keep rule's test of a model's per-frame errors `after[r][f]` against
/// a reference's `before[r][f]` (same shapes): H0 "the new model lowers the
/// summed error by at most `min_relative_drop` of the reference's". Each
/// frame's difference before - after less that share of `before` goes to
/// PairedBlockTest; `total` and its interval are the drop itself (the share
/// added back). Throws std::invalid_argument for recordings or frames that
/// do not pair up, a share outside [0, 1) and PairedBlockTest's errors.
PairedTestResult PairedDropTest(const std::vector<std::vector<double>>& before,
                                const std::vector<std::vector<double>>& after,
                                double min_relative_drop, const PairedTestOptions& options);

/// Benjamini-Hochberg step-up at false-discovery rate `q` over `p_values`:
/// rejected[i] is true for the hypotheses it rejects (p_(i) <= k q / m for
/// the largest such rank k). Throws std::invalid_argument for q outside
/// (0, 1) or a p-value outside [0, 1].
std::vector<bool> BenjaminiHochberg(const std::vector<double>& p_values, double q);

}  // namespace calib
