#include "calib/discovery/paired_test.h"

#include "calib/search/rng.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace calib {
namespace {

// TestBlockLength: at least this many blocks per recording.
constexpr int kMinBlocks = 10;

// Autocovariance at lag k (divided by n) of the centred series.
double Autocovariance(std::span<const double> c, size_t k) {
  double s = 0.0;
  for (size_t i = 0; i + k < c.size(); ++i) s += c[i] * c[i + k];
  return s / static_cast<double>(c.size());
}

// The flat-top lag window of Politis & Romano.
double FlatTop(double t) {
  t = std::abs(t);
  if (t <= 0.5) return 1.0;
  if (t <= 1.0) return 2.0 * (1.0 - t);
  return 0.0;
}

}  // namespace

int AutomaticBlockLength(std::span<const double> x) {
  const size_t n = x.size();
  if (n < 8) return 1;
  const double mean = std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(n);
  std::vector<double> c(x.begin(), x.end());
  for (double& v : c) v -= mean;
  const double r0 = Autocovariance(c, 0);
  if (!(r0 > 0.0)) return 1;
  const double nd = static_cast<double>(n);
  const double b_max = std::max(1.0, std::ceil(std::min(3.0 * std::sqrt(nd), nd / 3.0)));
  const size_t k_n = static_cast<size_t>(std::max(5.0, std::ceil(std::sqrt(std::log10(nd)))));
  const size_t m_max =
      std::min(n - 1, static_cast<size_t>(std::ceil(std::sqrt(nd))) + k_n);
  const double threshold = 2.0 * std::sqrt(std::log10(nd) / nd);
  std::vector<double> rho(m_max + 1, 0.0);
  for (size_t k = 1; k <= m_max; ++k) rho[k] = Autocovariance(c, k) / r0;
  // The first lag m after which k_n autocorrelations in a row are
  // insignificant.
  size_t m_hat = m_max;
  for (size_t m = 0; m + 1 <= m_max; ++m) {
    bool quiet = true;
    for (size_t j = 1; j <= k_n && m + j <= m_max; ++j) {
      if (std::abs(rho[m + j]) >= threshold) {
        quiet = false;
        break;
      }
    }
    if (quiet && m + k_n <= m_max) {
      m_hat = m;
      break;
    }
  }
  const size_t big_m = std::min(2 * std::max<size_t>(m_hat, 1), m_max);
  double g = 0.0;
  double g0 = r0;
  for (size_t k = 1; k <= big_m; ++k) {
    const double w = FlatTop(static_cast<double>(k) / static_cast<double>(big_m));
    const double r = Autocovariance(c, k);
    g += 2.0 * w * static_cast<double>(k) * r;
    g0 += 2.0 * w * r;
  }
  const double d_cb = 4.0 / 3.0 * g0 * g0;
  if (!(d_cb > 0.0)) return static_cast<int>(b_max);
  const double b = std::cbrt(2.0 * g * g / d_cb) * std::cbrt(nd);
  return static_cast<int>(std::clamp(std::round(b), 1.0, b_max));
}

int TestBlockLength(std::span<const double> x) {
  const int n = static_cast<int>(x.size());
  return std::clamp(2 * AutomaticBlockLength(x), 1, std::max(1, n / kMinBlocks));
}

PairedTestResult PairedBlockTest(const std::vector<std::vector<double>>& differences,
                                 const PairedTestOptions& options) {
  if (options.resamples < 1) {
    throw std::invalid_argument(
        fmt::format("paired test: resamples = {}: must be >= 1", options.resamples));
  }
  PairedTestResult result;
  result.resamples = options.resamples;
  bool any_nonzero = false;
  std::vector<double> block_sums;  // every recording's blocks, in order
  for (size_t r = 0; r < differences.size(); ++r) {
    const std::vector<double>& d = differences[r];
    for (size_t f = 0; f < d.size(); ++f) {
      if (!std::isfinite(d[f])) {
        throw std::invalid_argument(fmt::format(
            "paired test: recording {} frame {}: the difference {} is not finite", r, f, d[f]));
      }
      result.total += d[f];
      any_nonzero = any_nonzero || d[f] != 0.0;
    }
    result.frames += static_cast<int>(d.size());
    const int b = TestBlockLength(d);
    result.block_lengths.push_back(b);
    for (size_t i = 0; i < d.size(); i += static_cast<size_t>(b)) {
      const size_t end = std::min(d.size(), i + static_cast<size_t>(b));
      block_sums.push_back(std::accumulate(d.begin() + static_cast<std::ptrdiff_t>(i),
                                           d.begin() + static_cast<std::ptrdiff_t>(end), 0.0));
    }
  }
  if (result.frames == 0) throw std::invalid_argument("paired test: no frames to compare");
  result.blocks = static_cast<int>(block_sums.size());
  if (!any_nonzero) return result;

  // Under H0 each block's sum is as likely to have either sign: the totals
  // with random signs are its randomisation distribution.
  search::Rng rng(options.seed);
  std::vector<double> flipped(static_cast<size_t>(options.resamples));
  for (double& t : flipped) {
    double total = 0.0;
    for (double s : block_sums) total += (rng.NextU64() >> 63) != 0 ? s : -s;
    t = total;
  }
  const auto exceed =
      std::count_if(flipped.begin(), flipped.end(), [&](double t) { return t >= result.total; });
  result.p_value = static_cast<double>(1 + exceed) / static_cast<double>(options.resamples + 1);
  std::sort(flipped.begin(), flipped.end());
  auto quantile = [&](double q) {
    const double pos = q * static_cast<double>(flipped.size() - 1);
    const size_t i = static_cast<size_t>(std::floor(pos));
    const size_t j = std::min(i + 1, flipped.size() - 1);
    return flipped[i] + (pos - static_cast<double>(i)) * (flipped[j] - flipped[i]);
  };
  result.total_low = result.total - quantile(0.975);
  result.total_high = result.total - quantile(0.025);
  return result;
}

PairedTestResult PairedDropTest(const std::vector<std::vector<double>>& before,
                                const std::vector<std::vector<double>>& after,
                                double min_relative_drop, const PairedTestOptions& options) {
  if (!(min_relative_drop >= 0.0 && min_relative_drop < 1.0)) {
    throw std::invalid_argument(fmt::format(
        "paired drop test: smallest relevant drop {}: must be in [0, 1)", min_relative_drop));
  }
  if (before.size() != after.size()) {
    throw std::invalid_argument(fmt::format(
        "paired drop test: {} recordings before, {} after", before.size(), after.size()));
  }
  std::vector<std::vector<double>> differences(before.size());
  double margin = 0.0;
  for (size_t r = 0; r < before.size(); ++r) {
    if (before[r].size() != after[r].size()) {
      throw std::invalid_argument(fmt::format("paired drop test: recording {}: {} frames before, {} after",
                                              r, before[r].size(), after[r].size()));
    }
    differences[r].reserve(before[r].size());
    for (size_t f = 0; f < before[r].size(); ++f) {
      const double share = min_relative_drop * before[r][f];
      differences[r].push_back(before[r][f] - after[r][f] - share);
      margin += share;
    }
  }
  PairedTestResult result = PairedBlockTest(differences, options);
  result.total += margin;
  result.total_low += margin;
  result.total_high += margin;
  return result;
}

std::vector<bool> BenjaminiHochberg(const std::vector<double>& p_values, double q) {
  if (!(q > 0.0 && q < 1.0)) {
    throw std::invalid_argument(
        fmt::format("Benjamini-Hochberg: false-discovery rate {}: must be in (0, 1)", q));
  }
  const size_t m = p_values.size();
  std::vector<size_t> order(m);
  std::iota(order.begin(), order.end(), size_t{0});
  for (size_t i = 0; i < m; ++i) {
    if (!(p_values[i] >= 0.0 && p_values[i] <= 1.0)) {
      throw std::invalid_argument(
          fmt::format("Benjamini-Hochberg: p-value {} = {}: must be in [0, 1]", i, p_values[i]));
    }
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return p_values[a] < p_values[b]; });
  size_t last = 0;  // the largest rank k (1-based) with p_(k) <= k q / m; 0: none
  for (size_t k = 1; k <= m; ++k) {
    if (p_values[order[k - 1]] <= static_cast<double>(k) * q / static_cast<double>(m)) last = k;
  }
  std::vector<bool> rejected(m, false);
  for (size_t k = 0; k < last; ++k) rejected[order[k]] = true;
  return rejected;
}

}  // namespace calib
