// Signal helpers of the residual analysis: oscillation (autocorrelation by
// cv::dft), exponential decay fit, slope and correlation.

#include "calib/discovery/signals.h"

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace calib {
namespace {

// Replaces NaN samples by linear interpolation between their finite
// neighbours (constant extension at the ends); all-NaN gives zeros.
std::vector<double> FillGaps(std::span<const double> y) {
  std::vector<double> out(y.begin(), y.end());
  const int n = static_cast<int>(out.size());
  int prev = -1;
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(out[i])) continue;
    if (prev < 0) {
      for (int k = 0; k < i; ++k) out[k] = out[i];
    } else if (i - prev > 1) {
      for (int k = prev + 1; k < i; ++k) {
        const double t = static_cast<double>(k - prev) / (i - prev);
        out[k] = out[prev] + t * (out[i] - out[prev]);
      }
    }
    prev = i;
  }
  if (prev < 0) {
    std::fill(out.begin(), out.end(), 0.0);
  } else {
    for (int k = prev + 1; k < n; ++k) out[k] = out[prev];
  }
  return out;
}

// Removes the least-squares line through (i, y[i]).
void Detrend(std::vector<double>& y) {
  const int n = static_cast<int>(y.size());
  if (n < 2) return;
  double st = 0, sy = 0, stt = 0, sty = 0;
  for (int i = 0; i < n; ++i) {
    st += i;
    sy += y[i];
    stt += static_cast<double>(i) * i;
    sty += i * y[i];
  }
  const double den = n * stt - st * st;
  const double slope = den != 0.0 ? (n * sty - st * sy) / den : 0.0;
  const double icpt = (sy - slope * st) / n;
  for (int i = 0; i < n; ++i) y[i] -= icpt + slope * i;
}

// Biased autocorrelation r[k] = sum_i y[i] y[i + k], k = 0..n-1, via the
// power spectrum of the zero-padded signal.
std::vector<double> Autocorrelation(const std::vector<double>& y) {
  const int n = static_cast<int>(y.size());
  const int m = cv::getOptimalDFTSize(2 * n);
  cv::Mat padded = cv::Mat::zeros(1, m, CV_64F);
  for (int i = 0; i < n; ++i) padded.at<double>(0, i) = y[i];
  cv::Mat spectrum;
  cv::dft(padded, spectrum, cv::DFT_COMPLEX_OUTPUT);
  for (int k = 0; k < m; ++k) {
    cv::Vec2d& c = spectrum.at<cv::Vec2d>(0, k);
    c = cv::Vec2d(c[0] * c[0] + c[1] * c[1], 0.0);
  }
  cv::Mat acf;
  cv::dft(spectrum, acf, cv::DFT_INVERSE | cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  std::vector<double> r(n);
  for (int k = 0; k < n; ++k) r[k] = acf.at<double>(0, k);
  return r;
}

}  // namespace

Oscillation DetectOscillation(std::span<const double> signal, double fps,
                              const OscillationOptions& options) {
  Oscillation out;
  const int n = static_cast<int>(signal.size());
  if (n < 8 || !(fps > 0.0)) return out;
  std::vector<double> y = FillGaps(signal);
  Detrend(y);
  double ss = 0.0;
  for (double v : y) ss += v * v;
  const double rms = std::sqrt(ss / n);
  out.amplitude = std::sqrt(2.0) * rms;
  if (!(ss > 1e-12)) return out;

  const std::vector<double> r = Autocorrelation(y);
  // Overlap-corrected, normalised autocorrelation.
  auto rho = [&](int k) { return r[k] / r[0] * static_cast<double>(n) / (n - k); };
  const int max_lag = std::min(n - 2, static_cast<int>(std::floor(n / options.min_cycles)));
  int k = 1;
  while (k <= max_lag && rho(k) > 0.0) ++k;  // first zero crossing
  if (k > max_lag) return out;
  // The first local maximum after it that is positive; its value decides.
  int best = -1;
  for (int j = std::max(k, 2); j < max_lag; ++j) {
    if (rho(j) > 0.0 && rho(j) >= rho(j - 1) && rho(j) >= rho(j + 1)) {
      best = j;
      break;
    }
  }
  if (best < 0) return out;
  // Parabolic interpolation of the peak.
  const double a = rho(best - 1), b = rho(best), c = rho(best + 1);
  const double den = a - 2.0 * b + c;
  double shift = den < 0.0 ? 0.5 * (a - c) / den : 0.0;
  shift = std::clamp(shift, -0.5, 0.5);
  const double period = best + shift;
  if (period < options.min_period_frames) return out;
  out.strength = std::clamp(b, 0.0, 1.0);
  out.period_frames = period;
  out.period_s = period / fps;
  out.cycles = n / period;
  if (out.strength < options.min_strength) return out;
  out.found = true;

  // Envelope decay: RMS per whole period, log-linear fit.
  const int window = std::max(1, static_cast<int>(std::lround(period)));
  std::vector<double> log_rms;
  for (int s = 0; s + window <= n; s += window) {
    double w = 0.0;
    for (int i = s; i < s + window; ++i) w += y[i] * y[i];
    log_rms.push_back(std::log(std::sqrt(w / window) + 1e-12));
  }
  if (log_rms.size() >= 3) out.decay_per_s = -LinearSlope(log_rms, window / fps);
  return out;
}

ExponentialFit FitExponentialDecay(std::span<const double> y, double dt_s) {
  ExponentialFit fit;
  const int n = static_cast<int>(y.size());
  if (n < 4 || !(dt_s > 0.0)) return fit;
  double mean = 0.0;
  for (double v : y) mean += v;
  mean /= n;
  double sst = 0.0;
  for (double v : y) sst += (v - mean) * (v - mean);

  // For a given tau, floor and amplitude by linear least squares.
  auto solve = [&](double tau, double* floor, double* amp) {
    double s1 = n, se = 0, see = 0, sy = 0, sey = 0;
    for (int i = 0; i < n; ++i) {
      const double e = std::exp(-i * dt_s / tau);
      se += e;
      see += e * e;
      sy += y[i];
      sey += e * y[i];
    }
    const double det = s1 * see - se * se;
    if (std::abs(det) < 1e-12 * s1 * see) {
      *amp = 0.0;
      *floor = sy / s1;
    } else {
      *floor = (see * sy - se * sey) / det;
      *amp = (s1 * sey - se * sy) / det;
    }
    double sse = 0.0;
    for (int i = 0; i < n; ++i) {
      const double d = y[i] - (*floor + *amp * std::exp(-i * dt_s / tau));
      sse += d * d;
    }
    return sse;
  };

  // Coarse log grid, then golden-section refinement around the best.
  const double lo = std::log(0.5 * dt_s), hi = std::log(20.0 * n * dt_s);
  const int grid = 60;
  int best = 0;
  double best_sse = std::numeric_limits<double>::infinity();
  double f, a;
  for (int g = 0; g <= grid; ++g) {
    const double sse = solve(std::exp(lo + (hi - lo) * g / grid), &f, &a);
    if (sse < best_sse) {
      best_sse = sse;
      best = g;
    }
  }
  double l = lo + (hi - lo) * std::max(0, best - 1) / grid;
  double h = lo + (hi - lo) * std::min(grid, best + 1) / grid;
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  double x1 = h - golden * (h - l), x2 = l + golden * (h - l);
  double f1 = solve(std::exp(x1), &f, &a), f2 = solve(std::exp(x2), &f, &a);
  for (int it = 0; it < 40; ++it) {
    if (f1 < f2) {
      h = x2;
      x2 = x1;
      f2 = f1;
      x1 = h - golden * (h - l);
      f1 = solve(std::exp(x1), &f, &a);
    } else {
      l = x1;
      x1 = x2;
      f1 = f2;
      x2 = l + golden * (h - l);
      f2 = solve(std::exp(x2), &f, &a);
    }
  }
  const double tau = std::exp(0.5 * (l + h));
  const double sse = solve(tau, &fit.floor, &fit.amplitude);
  fit.tau_s = tau;
  fit.r2 = sst > 0.0 ? 1.0 - sse / sst : (sse < 1e-12 ? 1.0 : 0.0);
  fit.ok = true;
  return fit;
}

double LinearSlope(std::span<const double> y, double dt_s) {
  double n = 0, st = 0, sy = 0, stt = 0, sty = 0;
  for (size_t i = 0; i < y.size(); ++i) {
    if (!std::isfinite(y[i])) continue;
    const double t = static_cast<double>(i) * dt_s;
    n += 1;
    st += t;
    sy += y[i];
    stt += t * t;
    sty += t * y[i];
  }
  if (n < 2) return 0.0;
  const double den = n * stt - st * st;
  return den > 0.0 ? (n * sty - st * sy) / den : 0.0;
}

double Correlation(std::span<const double> x, std::span<const double> y) {
  const size_t n = std::min(x.size(), y.size());
  double k = 0, sx = 0, sy = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    k += 1;
    sx += x[i];
    sy += y[i];
  }
  if (k < 3) return 0.0;
  const double mx = sx / k, my = sy / k;
  double sxx = 0, syy = 0, sxy = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  if (sxx <= 1e-300 || syy <= 1e-300) return 0.0;
  return sxy / std::sqrt(sxx * syy);
}

}  // namespace calib
