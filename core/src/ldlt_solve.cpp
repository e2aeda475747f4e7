#include "calib/core/ldlt_solve.h"

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace calib::ldlt {

void SolveInPlace(const FactorView& factor, double* x) {
  const int n = factor.n;
  const int* outer = factor.outer;
  const int* inner = factor.inner;
  const double* value = factor.value;
  for (int k = 0; k < n; ++k) {
    const double t = x[k];
    if (t == 0.0) continue;
    for (int p = outer[k]; p < outer[k + 1]; ++p) x[inner[p]] -= t * value[p];
  }
  for (int k = 0; k < n; ++k) x[k] = factor.inverse_d[k] * x[k];
  for (int k = n - 1; k >= 0; --k) {
    double t = x[k];
    for (int p = outer[k]; p < outer[k + 1]; ++p) t -= value[p] * x[inner[p]];
    x[k] = t;
  }
}

void SolveInPlace2(const FactorView& factor, double* x, double* y, double* scratch) {
  const int n = factor.n;
  const int* outer = factor.outer;
  const int* inner = factor.inner;
  const double* value = factor.value;
  // The two right-hand sides interleaved: an entry's two values share a
  // cache line.
  double* xy = scratch;
  for (int k = 0; k < n; ++k) {
    xy[2 * k] = x[k];
    xy[2 * k + 1] = y[k];
  }
  for (int k = 0; k < n; ++k) {
    const double s = xy[2 * k], t = xy[2 * k + 1];
    const int begin = outer[k], end = outer[k + 1];
    if (s != 0.0 && t != 0.0) {
#ifdef __SSE2__
      // Both lanes at once: the same multiply and subtract per lane.
      const __m128d st = _mm_set_pd(t, s);
      for (int p = begin; p < end; ++p) {
        double* row = xy + 2 * inner[p];
        _mm_storeu_pd(row, _mm_sub_pd(_mm_loadu_pd(row), _mm_mul_pd(st, _mm_set1_pd(value[p]))));
      }
#else
      for (int p = begin; p < end; ++p) {
        double* row = xy + 2 * inner[p];
        row[0] -= s * value[p];
        row[1] -= t * value[p];
      }
#endif
    } else if (s != 0.0) {
      for (int p = begin; p < end; ++p) xy[2 * inner[p]] -= s * value[p];
    } else if (t != 0.0) {
      for (int p = begin; p < end; ++p) xy[2 * inner[p] + 1] -= t * value[p];
    }
  }
  for (int k = 0; k < n; ++k) {
    xy[2 * k] = factor.inverse_d[k] * xy[2 * k];
    xy[2 * k + 1] = factor.inverse_d[k] * xy[2 * k + 1];
  }
  for (int k = n - 1; k >= 0; --k) {
    double s = xy[2 * k], t = xy[2 * k + 1];
    for (int p = outer[k]; p < outer[k + 1]; ++p) {
      const double* row = xy + 2 * inner[p];
      s -= value[p] * row[0];
      t -= value[p] * row[1];
    }
    xy[2 * k] = s;
    xy[2 * k + 1] = t;
  }
  for (int k = 0; k < n; ++k) {
    x[k] = xy[2 * k];
    y[k] = xy[2 * k + 1];
  }
}

}  // namespace calib::ldlt
