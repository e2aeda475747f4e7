// Area coverage by signed-area accumulation (rasterizer.h), as font
// rasterisers do it (font-rs, stb_truetype v2), kept sparse: only the
// (row, column) cells an edge passes through get a delta.
//
// In a row strip [r, r + 1], a straight piece of an edge of height h (signed:
// + for an edge running downwards) contributes to the integral of the
// winding number over pixel square c the area of that square right of the
// piece within the piece's y range: h for a piece wholly left of the square,
// h (1 - m) for a piece inside column c whose mean x lies a fraction m into
// it, 0 for a piece to its right. As deltas: h (1 - m) to column c and h m to
// column c + 1, so that the running sum of a row's deltas from the left is
// each pixel's signed coverage.

#include "calib/evaluator/rasterizer.h"

#include "loop_edges.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

namespace calib {

void Rasterizer::BeginCoverage(const BitMask& interior) {
  coverage_deltas_.clear();
  mask_width_ = interior.width();
  mask_height_ = interior.height();
  origin_x_ = interior.origin_x();
  origin_y_ = interior.origin_y();
  row_lo_ = mask_height_;
  row_hi_ = 0;
  // Deltas per row (row r counted at r + 2), for the counting sort in
  // FinishCoverage.
  if (row_offsets_.size() < static_cast<size_t>(mask_height_) + 2) {
    row_offsets_.resize(static_cast<size_t>(mask_height_) + 2);
  }
  std::fill(row_offsets_.begin(), row_offsets_.begin() + mask_height_ + 2, 0);
}

void Rasterizer::AddCoverageEdge(const Vec2& p, const Vec2& q) {
  if (!(std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(q.x()) &&
        std::isfinite(q.y()))) {
    return;
  }
  if (p.y() == q.y()) return;  // bounds no area of any row
  // In mask coordinates, from the end point of smaller y (a) to b: the same
  // pieces, of opposite sign, whichever way the edge is traversed.
  const bool downwards = p.y() < q.y();
  const Vec2& a = downwards ? p : q;
  const Vec2& b = downwards ? q : p;
  const double ax = a.x() - origin_x_, ay = a.y() - origin_y_;
  const double bx = b.x() - origin_x_, by = b.y() - origin_y_;
  const double height = static_cast<double>(mask_height_);
  if (!(by > 0.0 && ay < height)) return;
  double dx_dy = (bx - ax) / (by - ay);
  // Only for a sub-normal height can the slope overflow: taken as vertical.
  if (!std::isfinite(dx_dy)) dx_dy = 0.0;
  const double sign = downwards ? 1.0 : -1.0;
  const int row_begin = static_cast<int>(std::max(std::floor(ay), 0.0));
  const int row_end = static_cast<int>(std::min(std::ceil(by), height));
  for (int r = row_begin; r < row_end; ++r) {
    const double y_top = std::max(ay, static_cast<double>(r));
    const double y_bottom = std::min(by, r + 1.0);
    if (!(y_top < y_bottom)) continue;
    const double x_top = y_top == ay ? ax : ax + (y_top - ay) * dx_dy;
    const double x_bottom = y_bottom == by ? bx : ax + (y_bottom - ay) * dx_dy;
    const size_t before = coverage_deltas_.size();
    AddCoveragePiece(r, std::min(x_top, x_bottom), std::max(x_top, x_bottom),
                     sign * (y_bottom - y_top));
    row_offsets_[r + 2] += static_cast<int>(coverage_deltas_.size() - before);
  }
  row_lo_ = std::min(row_lo_, row_begin);
  row_hi_ = std::max(row_hi_, row_end);
}

void Rasterizer::AddCoveragePiece(int row, double x0, double x1, double height) {
  const auto add = [&](int column, double delta) {
    if (delta != 0.0) coverage_deltas_.push_back({row, column, delta});
  };
  const double width = static_cast<double>(mask_width_);
  // Left of the mask: every pixel of the row lies right of it (column 0
  // carries the running sum's start). Right of it: no pixel does.
  if (x1 <= 0.0) {
    add(0, height);
    return;
  }
  if (x0 >= width) return;
  if (x1 <= std::floor(x0) + 1.0) {  // within one column (x0 >= 0 here)
    const int c = static_cast<int>(std::floor(x0));
    const double m = 0.5 * (x0 + x1) - c;  // mean x fraction of the pixel left of the piece
    add(c, height * (1.0 - m));
    if (c + 1 < mask_width_) add(c + 1, height * m);
    return;
  }
  // Across columns: a straight piece's height splits between the columns in
  // proportion to its x extent in each. The part left of the mask goes to
  // column 0; columns right of it are dropped.
  const double height_per_x = height / (x1 - x0);
  double carry = 0.0;  // the previous column's share for this one
  double left = x0;
  int c = 0;
  if (x0 < 0.0) {
    carry = height_per_x * -x0;
    left = 0.0;
  } else {
    c = static_cast<int>(std::floor(x0));
  }
  const int last = static_cast<int>(std::min(std::ceil(x1) - 1.0, width - 1.0));
  for (; c <= last; ++c) {
    const double right = std::min(x1, c + 1.0);
    const double h = height_per_x * (right - left);
    const double m = 0.5 * (left + right) - c;
    add(c, carry + h * (1.0 - m));
    carry = h * m;
    left = right;
  }
  if (c < mask_width_) add(c, carry);
}

void Rasterizer::FinishCoverage(BitMask& interior, std::vector<PixelCoverage>& boundary) {
  if (row_lo_ >= row_hi_ || coverage_deltas_.empty()) return;
  // Counting sort by row: offsets[r + 2] counts row r (AddCoverageEdge),
  // then (prefix sums) offsets[r + 1] starts it, then (as the write cursor)
  // ends it, which leaves row r in [offsets[r], offsets[r + 1]).
  int* offsets = row_offsets_.data();
  for (int k = row_lo_ + 2; k <= row_hi_ + 1; ++k) offsets[k] += offsets[k - 1];
  if (coverage_sorted_.size() < coverage_deltas_.size()) {
    coverage_sorted_.resize(coverage_deltas_.size() + coverage_deltas_.size() / 2 + 64);
  }
  CoverageDelta* sorted = coverage_sorted_.data();
  // An edge's piece in a row adds its deltas one after another: moved as a
  // run, with one update of the row's cursor.
  const CoverageDelta* deltas = coverage_deltas_.data();
  const size_t num_deltas = coverage_deltas_.size();
  for (size_t i = 0; i < num_deltas;) {
    const int row = deltas[i].row;
    size_t j = i + 1;
    while (j < num_deltas && deltas[j].row == row) ++j;
    std::copy(deltas + i, deltas + j, sorted + offsets[row + 1]);
    offsets[row + 1] += static_cast<int>(j - i);
    i = j;
  }

  // Each row's deltas are summed per column in a dense row (kept zero
  // between rows), the columns that got one marked in a bit set, which then
  // yields them in order: no sort.
  const size_t row_words = (static_cast<size_t>(mask_width_) + 63) / 64;
  if (row_sums_.size() < static_cast<size_t>(mask_width_)) row_sums_.resize(mask_width_, 0.0);
  if (row_touched_.size() < row_words) row_touched_.resize(row_words, 0);
  double* sums = row_sums_.data();
  uint64_t* touched = row_touched_.data();
  for (int y = row_lo_; y < row_hi_; ++y) {
    const CoverageDelta* begin = sorted + offsets[y];
    const CoverageDelta* end = sorted + offsets[y + 1];
    if (begin == end) continue;
    int first_word = static_cast<int>(row_words), last_word = 0;
    for (const CoverageDelta* d = begin; d < end; ++d) {
      sums[d->column] += d->delta;
      touched[d->column >> 6] |= uint64_t{1} << (d->column & 63);
      first_word = std::min(first_word, d->column >> 6);
      last_word = std::max(last_word, d->column >> 6);
    }
    double sum = 0.0;  // signed coverage of the columns reached
    // Columns [from, to) all have coverage min(|sum|, 1): between touched
    // columns a winding number (up to rounding), or a fraction where an
    // exactly horizontal edge runs through the row.
    const auto assign = [&](int from, int to) {
      if (from >= to) return;
      const double coverage = std::min(std::abs(sum), 1.0);
      if (coverage >= 1.0 - kCoverageTolerance) {
        interior.SetSpan(y, from, to);
      } else if (coverage > kCoverageTolerance) {
        if (to - from == 1) {
          boundary.push_back({from, y, coverage});
        } else {
          const size_t n = boundary.size();
          boundary.resize(n + static_cast<size_t>(to - from));
          for (int x = from; x < to; ++x) boundary[n + (x - from)] = {x, y, coverage};
        }
      }
    };
    int next = 0;  // first column not yet assigned
    for (int w = first_word; w <= last_word; ++w) {
      for (uint64_t bits = touched[w]; bits != 0; bits &= bits - 1) {
        const int column = w * 64 + std::countr_zero(bits);
        assign(next, column);
        sum += sums[column];
        sums[column] = 0.0;
        assign(column, column + 1);
        next = column + 1;
      }
      touched[w] = 0;
    }
    assign(next, mask_width_);
  }
}

void Rasterizer::RasterizeMeshCoverage(const Mesh& mesh, const std::vector<Vec2>& positions,
                                       BitMask& interior, std::vector<PixelCoverage>& boundary) {
  RasterizeMeshCoverage(mesh, positions.data(), interior, boundary);
}

void Rasterizer::RasterizeMeshCoverage(const Mesh& mesh, const Vec2* positions, BitMask& interior,
                                       std::vector<PixelCoverage>& boundary) {
  interior.Clear();
  boundary.clear();
  BeginCoverage(interior);
  detail::ForEachBoundaryEdge(mesh, positions,
                              [this](const Vec2& p, const Vec2& q) { AddCoverageEdge(p, q); });
  FinishCoverage(interior, boundary);
}

void Rasterizer::FillPolygonsCoverage(const std::vector<std::vector<Vec2>>& loops,
                                      BitMask& interior, std::vector<PixelCoverage>& boundary) {
  interior.Clear();
  boundary.clear();
  BeginCoverage(interior);
  detail::ForEachLoopEdge(loops, [this](const Vec2& p, const Vec2& q) { AddCoverageEdge(p, q); });
  FinishCoverage(interior, boundary);
}

}  // namespace calib
