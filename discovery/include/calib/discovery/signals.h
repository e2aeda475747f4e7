#pragma once
// Signal helpers of the residual analysis (residual.h): periods, decays,
// slopes and correlations of sampled signals. Public for tests and reports.

#include <span>

namespace calib {

/// A periodic component of a sampled signal.
struct Oscillation {
  bool found = false;
  double period_frames = 0.0;  ///< sub-frame (parabolic peak interpolation)
  double period_s = 0.0;
  /// Autocorrelation at the period, corrected for the overlap (N / (N - lag)),
  /// in [0, 1]: 1 for a pure sinusoid.
  double strength = 0.0;
  /// sqrt(2) x RMS of the linearly detrended signal (a sinusoid's amplitude).
  double amplitude = 0.0;
  /// Exponential decay rate of the per-period RMS envelope, 1/s (> 0:
  /// decaying, < 0: growing); 0 with fewer than 3 whole periods.
  double decay_per_s = 0.0;
  double cycles = 0.0;  ///< signal length / period
};

struct OscillationOptions {
  double min_period_frames = 3.0;
  /// Periods longer than N / min_cycles are not searched (below ~2.5 a
  /// single step or bump passes for a period).
  double min_cycles = 2.5;
  double min_strength = 0.2;
};

/// The dominant period of `signal` (sampled at `fps`): the first
/// autocorrelation peak after its first zero crossing, the autocorrelation
/// computed with cv::dft on the detrended, zero-padded signal. NaN samples
/// are replaced by linear interpolation. found = false for fewer than 8
/// samples, no zero crossing or a peak weaker than min_strength.
Oscillation DetectOscillation(std::span<const double> signal, double fps,
                              const OscillationOptions& options = {});

/// y(t) = floor + amplitude exp(-t / tau) fitted to samples y[i] at
/// t = i dt (least squares; tau by golden-section search on log tau between
/// dt / 2 and 20 x the span, floor and amplitude linear).
struct ExponentialFit {
  bool ok = false;  ///< false with fewer than 4 samples
  double floor = 0.0;
  double amplitude = 0.0;
  double tau_s = 0.0;
  double r2 = 0.0;  ///< 1 - SSE / SST (1 for a constant signal fitted exactly)
};
ExponentialFit FitExponentialDecay(std::span<const double> y, double dt_s);

/// Least-squares slope of y[i] against t = i dt (units of y per second); 0
/// with fewer than 2 finite samples (NaN samples are skipped).
double LinearSlope(std::span<const double> y, double dt_s);

/// Pearson correlation of x and y over the pairs where both are finite; 0
/// when either is constant or fewer than 3 pairs.
double Correlation(std::span<const double> x, std::span<const double> y);

}  // namespace calib
