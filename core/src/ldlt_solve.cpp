#include "calib/core/ldlt_solve.h"

#include <algorithm>
#include <type_traits>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

namespace calib::ldlt {
namespace {

// K independent lines of a sweep (lines[0..K)): x[l] minus value * x[index]
// over line l's entries in storage order, the K running differences side
// by side over their common length, then each line's remaining entries.
template <int K>
inline void SweepLines(const Sweep& s, double* x, const int* lines) {
  const auto term = [&](int q) { return s.value[q] * x[s.index[q]]; };
  int p[K], end[K];
  double t[K];
  int common = s.begin[lines[0] + 1] - s.begin[lines[0]];
  for (int j = 0; j < K; ++j) {
    p[j] = s.begin[lines[j]];
    end[j] = s.begin[lines[j] + 1];
    t[j] = x[lines[j]];
    common = std::min(common, end[j] - p[j]);
  }
  for (int i = 0; i < common; ++i) {
    for (int j = 0; j < K; ++j) t[j] -= term(p[j] + i);
  }
  for (int j = 0; j < K; ++j) {
    for (int q = p[j] + common; q < end[j]; ++q) t[j] -= term(q);
    x[lines[j]] = t[j];
  }
}

// As SweepLines for two right-hand sides interleaved in xy (entry k's pair
// at 2 k): each lane its own running difference.
template <int K>
inline void SweepLinePairs(const Sweep& s, double* xy, const int* lines) {
  int p[K], end[K];
  int common = s.begin[lines[0] + 1] - s.begin[lines[0]];
  for (int j = 0; j < K; ++j) {
    p[j] = s.begin[lines[j]];
    end[j] = s.begin[lines[j] + 1];
    common = std::min(common, end[j] - p[j]);
  }
#ifdef __SSE2__
  // Both lanes in one register: lane-wise the same multiply and subtract.
  const auto term = [&](int q) {
    return _mm_mul_pd(_mm_set1_pd(s.value[q]), _mm_loadu_pd(xy + 2 * s.index[q]));
  };
  __m128d t[K];
  for (int j = 0; j < K; ++j) t[j] = _mm_loadu_pd(xy + 2 * lines[j]);
  for (int i = 0; i < common; ++i) {
    for (int j = 0; j < K; ++j) t[j] = _mm_sub_pd(t[j], term(p[j] + i));
  }
  for (int j = 0; j < K; ++j) {
    for (int q = p[j] + common; q < end[j]; ++q) t[j] = _mm_sub_pd(t[j], term(q));
    _mm_storeu_pd(xy + 2 * lines[j], t[j]);
  }
#else
  const auto term = [&](int q, int lane) { return s.value[q] * xy[2 * s.index[q] + lane]; };
  double t0[K], t1[K];
  for (int j = 0; j < K; ++j) {
    t0[j] = xy[2 * lines[j]];
    t1[j] = xy[2 * lines[j] + 1];
  }
  for (int i = 0; i < common; ++i) {
    for (int j = 0; j < K; ++j) {
      t0[j] -= term(p[j] + i, 0);
      t1[j] -= term(p[j] + i, 1);
    }
  }
  for (int j = 0; j < K; ++j) {
    for (int q = p[j] + common; q < end[j]; ++q) {
      t0[j] -= term(q, 0);
      t1[j] -= term(q, 1);
    }
    xy[2 * lines[j]] = t0[j];
    xy[2 * lines[j] + 1] = t1[j];
  }
#endif
}

// Every level of the sweep, its lines four at a time.
template <bool kPairs>
void Run(const Sweep& s, double* x) {
  const auto lines = [&](auto k, const int* first) {
    if constexpr (kPairs) {
      SweepLinePairs<decltype(k)::value>(s, x, first);
    } else {
      SweepLines<decltype(k)::value>(s, x, first);
    }
  };
  for (int level = 0; level < s.num_levels; ++level) {
    const int* first = s.lines + s.level_begin[level];
    const int* const end = s.lines + s.level_begin[level + 1];
    for (; end - first >= 4; first += 4) lines(std::integral_constant<int, 4>(), first);
    switch (end - first) {
      case 3: lines(std::integral_constant<int, 3>(), first); break;
      case 2: lines(std::integral_constant<int, 2>(), first); break;
      case 1: lines(std::integral_constant<int, 1>(), first); break;
      default: break;
    }
  }
}

// Lines by level (a counting sort), and within a level by length, so that
// each four advance together for most of their entries.
void Levels(int n, const int* begin, const std::vector<int>& level, std::vector<int>* lines,
            std::vector<int>* level_begin) {
  const int num_levels = n == 0 ? 0 : *std::max_element(level.begin(), level.end()) + 1;
  level_begin->assign(static_cast<size_t>(num_levels) + 1, 0);
  for (int k = 0; k < n; ++k) ++(*level_begin)[level[k] + 1];
  for (int v = 0; v < num_levels; ++v) (*level_begin)[v + 1] += (*level_begin)[v];
  lines->resize(static_cast<size_t>(n));
  std::vector<int>& next = *level_begin;  // each level's next free slot, then shifted back
  for (int k = 0; k < n; ++k) (*lines)[next[level[k]]++] = k;
  for (int v = num_levels; v > 0; --v) next[v] = next[v - 1];
  next[0] = 0;
  const auto length = [begin](int k) { return begin[k + 1] - begin[k]; };
  for (int v = 0; v < num_levels; ++v) {
    std::sort(lines->begin() + next[v], lines->begin() + next[v + 1], [&](int a, int b) {
      return length(a) != length(b) ? length(a) < length(b) : a < b;
    });
  }
}

}  // namespace

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
  Run</*kPairs=*/false>(factor.backward, x);
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
  Run</*kPairs=*/true>(factor.backward, xy);
  for (int k = 0; k < n; ++k) {
    x[k] = xy[2 * k];
    y[k] = xy[2 * k + 1];
  }
}

FactorView MakeView(int n, const int* outer, const int* inner, const double* value,
                    const double* d, FactorExtras* extras) {
  FactorExtras& e = *extras;
  e.inverse_d.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) e.inverse_d[i] = 1.0 / d[i];

  // Columns by depth in the elimination tree: a column's parent is its
  // first (least) row, and its entries are its ancestors, all shallower.
  e.depth.resize(static_cast<size_t>(n));
  for (int k = n - 1; k >= 0; --k) {
    e.depth[k] = outer[k] == outer[k + 1] ? 0 : e.depth[inner[outer[k]]] + 1;
  }
  Levels(n, outer, e.depth, &e.backward_lines, &e.backward_levels);

  FactorView view;
  view.n = n;
  view.outer = outer;
  view.inner = inner;
  view.value = value;
  view.backward = {outer, inner, value, e.backward_lines.data(), e.backward_levels.data(),
                   static_cast<int>(e.backward_levels.size()) - 1};
  view.inverse_d = e.inverse_d.data();
  return view;
}

void Factorization::Analyse(const SparseMatrix& upper) {
  const int n = static_cast<int>(upper.cols());
  n_ = n;
  // The elimination tree and L's column counts, as SimplicialLDLT's
  // analyzePattern_preordered finds them.
  std::vector<int> parent(n, -1), tags(n, -1), count(n, 0);
  for (int k = 0; k < n; ++k) {
    tags[k] = k;
    for (SparseMatrix::InnerIterator it(upper, k); it; ++it) {
      for (int i = static_cast<int>(it.index()); i < k && tags[i] != k; i = parent[i]) {
        if (parent[i] == -1) parent[i] = k;
        ++count[i];
        tags[i] = k;
      }
    }
  }
  outer_.assign(n + 1, 0);
  for (int k = 0; k < n; ++k) outer_[k + 1] = outer_[k] + count[k];
  inner_.assign(outer_[n], 0);
  value_.assign(outer_[n], 0.0);
  d_.assign(n, 0.0);
  y_.assign(n, 0.0);

  // Each row's pattern in factorize_preordered's order: the paths from the
  // row's entries up the tree, each path pushed on a stack that is then read
  // from its top.
  row_begin_.assign(n + 1, 0);
  row_column_.clear();
  row_position_.clear();
  std::vector<int> pattern(n), filled(n, 0);
  std::fill(tags.begin(), tags.end(), -1);
  for (int k = 0; k < n; ++k) {
    int top = n;
    tags[k] = k;
    for (SparseMatrix::InnerIterator it(upper, k); it; ++it) {
      int i = static_cast<int>(it.index());
      if (i > k) continue;
      int len = 0;
      for (; tags[i] != k; i = parent[i]) {
        pattern[len++] = i;
        tags[i] = k;
      }
      while (len > 0) pattern[--top] = pattern[--len];
    }
    for (; top < n; ++top) {
      const int i = pattern[top];
      const int p = outer_[i] + filled[i]++;
      inner_[p] = k;
      row_column_.push_back(i);
      row_position_.push_back(p);
    }
    row_begin_[k + 1] = static_cast<int>(row_column_.size());
  }

  // The solve's order depends on the pattern only.
  view_ = MakeView(n, outer_.data(), inner_.data(), value_.data(), d_.data(), &extras_);
}

bool Factorization::Factorize(const SparseMatrix& upper) {
  const int* a_outer = upper.outerIndexPtr();
  const int* a_inner = upper.innerIndexPtr();
  const double* a_value = upper.valuePtr();
  const int* a_count = upper.innerNonZeroPtr();  // null when compressed
  const int* outer = outer_.data();
  const int* inner = inner_.data();
  double* value = value_.data();
  double* y = y_.data();
  bool ok = true;
  for (int k = 0; k < n_; ++k) {
    const int a_end = a_count == nullptr ? a_outer[k + 1] : a_outer[k] + a_count[k];
    for (int q = a_outer[k]; q < a_end; ++q) {
      if (a_inner[q] <= k) y[a_inner[q]] += a_value[q];
    }
    double d = y[k];
    y[k] = 0.0;
    for (int r = row_begin_[k]; r < row_begin_[k + 1]; ++r) {
      const int i = row_column_[r];
      const int end = row_position_[r];
      const double yi = y[i];
      y[i] = 0.0;
      const double l_ki = yi / d_[i];
      for (int p = outer[i]; p < end; ++p) y[inner[p]] -= value[p] * yi;
      d -= l_ki * yi;
      value[end] = l_ki;
    }
    d_[k] = d;
    if (!(d > 0.0)) {
      ok = false;  // Eigen stops at a zero pivot; a negative one fails its caller's test
      break;
    }
  }
  if (!ok) {
    std::fill(y_.begin(), y_.end(), 0.0);
    return false;
  }
  for (int i = 0; i < n_; ++i) extras_.inverse_d[i] = 1.0 / d_[i];
  return true;
}

}  // namespace calib::ldlt
