#include "calib/evaluator/nearest_segment.h"

#include <algorithm>
#include <cmath>

namespace calib {
namespace {

// Fewer segments than this are scanned: a grid query costs about as much
// as scanning eight segments (2.6 cells and 3.7 segments a query on the
// real strips' tracking).
constexpr int kMinSegmentsForGrid = 16;
// Cells per side at most (the cell grows for a sparse or far-flung set).
constexpr double kMaxCellsPerSide = 128.0;
// A segment left unseen is at least the scanned rings' half-width away;
// this much of it is kept back for the rounding of the computed distances.
constexpr double kBoundMarginPx = 1e-6;

// a replaces best: nearer, or as near with a lower index (the plain scan
// keeps the first of equal distances).
bool Better(const SegmentPoint& a, const SegmentPoint& best) {
  return a.distance2 < best.distance2 ||
         (a.distance2 == best.distance2 && best.segment >= 0 && a.segment < best.segment);
}

}  // namespace

double NearestShare(const Vec2& a, const Vec2& b, const Vec2& p) {
  const Vec2 d = b - a;
  const double length2 = d.squaredNorm();
  if (length2 <= 0.0) return 0.0;
  return std::clamp((p - a).dot(d) / length2, 0.0, 1.0);
}

SegmentPoint NearestSegment::Candidate(int k, const Vec2& p) const {
  const Vec2& a = a_[k];
  const Vec2& b = b_[k];
  const double s = NearestShare(a, b, p);
  const Vec2 q = a + s * (b - a);
  return {(q - p).squaredNorm(), k, s, q};
}

SegmentPoint NearestSegment::NearestByScan(const Vec2& p) const {
  SegmentPoint best;
  for (int k = 0; k < size(); ++k) {
    const SegmentPoint c = Candidate(k, p);
    if (c.distance2 < best.distance2) best = c;
  }
  return best;
}

void NearestSegment::Index() {
  nx_ = ny_ = 0;
  const int n = size();
  if (n < kMinSegmentsForGrid) return;  // scanned
  Vec2 lo = a_[0], hi = a_[0];
  double total_length = 0.0;
  for (int k = 0; k < n; ++k) {
    if (!a_[k].allFinite() || !b_[k].allFinite()) return;  // scanned
    lo = lo.cwiseMin(a_[k]).cwiseMin(b_[k]);
    hi = hi.cwiseMax(a_[k]).cwiseMax(b_[k]);
    total_length += (b_[k] - a_[k]).norm();
  }
  if (!std::isfinite(total_length)) return;  // scanned
  const double extent = (hi - lo).maxCoeff();
  if (!(extent < 1e12) || !(hi.cwiseAbs().maxCoeff() < 1e12) || !(lo.cwiseAbs().maxCoeff() < 1e12)) {
    return;  // beyond any image: scanned
  }
  // About a segment's length a cell: a point near the segments finds the
  // nearest in its own cell or the ring around it.
  cell_ = std::max({total_length / n, extent / kMaxCellsPerSide, 1e-3});
  origin_ = lo - Vec2(cell_, cell_);  // a cell's margin on every side
  nx_ = static_cast<int>((hi.x() - origin_.x()) / cell_) + 2;
  ny_ = static_cast<int>((hi.y() - origin_.y()) / cell_) + 2;
  const auto cell_range = [&](int k, int* i0, int* i1, int* j0, int* j1) {
    const Vec2 a = a_[k], b = b_[k];
    *i0 = static_cast<int>((std::min(a.x(), b.x()) - origin_.x()) / cell_);
    *i1 = static_cast<int>((std::max(a.x(), b.x()) - origin_.x()) / cell_);
    *j0 = static_cast<int>((std::min(a.y(), b.y()) - origin_.y()) / cell_);
    *j1 = static_cast<int>((std::max(a.y(), b.y()) - origin_.y()) / cell_);
  };
  cell_start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
  for (int k = 0; k < n; ++k) {
    int i0, i1, j0, j1;
    cell_range(k, &i0, &i1, &j0, &j1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) ++cell_start_[j * nx_ + i + 1];
    }
  }
  for (size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  cell_items_.resize(cell_start_.back());
  // Filled in index order, each cell's next free place counted down from
  // its end and the segments taken last to first.
  std::vector<int>& next = cell_start_;
  for (int k = n - 1; k >= 0; --k) {
    int i0, i1, j0, j1;
    cell_range(k, &i0, &i1, &j0, &j1);
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) cell_items_[--next[j * nx_ + i + 1]] = k;
    }
  }
  // next[c + 1] is now cell c's start: shift back.
  for (size_t c = 0; c + 1 < cell_start_.size(); ++c) cell_start_[c] = cell_start_[c + 1];
  cell_start_.back() = static_cast<int>(cell_items_.size());
}

SegmentPoint NearestSegment::Nearest(const Vec2& p) const {
  if (nx_ == 0 || !p.allFinite()) return NearestByScan(p);
  const double fx = (p.x() - origin_.x()) / cell_, fy = (p.y() - origin_.y()) / cell_;
  if (!(fx >= 0.0 && fx < nx_ && fy >= 0.0 && fy < ny_)) return NearestByScan(p);
  const int cx = static_cast<int>(fx), cy = static_cast<int>(fy);
  SegmentPoint best;
  const auto scan_cell = [&](int i, int j) {
    if (i < 0 || i >= nx_ || j < 0 || j >= ny_) return;
    const int c = j * nx_ + i;
    for (int q = cell_start_[c]; q < cell_start_[c + 1]; ++q) {
      const SegmentPoint candidate = Candidate(cell_items_[q], p);
      if (Better(candidate, best)) best = candidate;
    }
  };
  for (int r = 0;; ++r) {
    if (r == 0) {
      scan_cell(cx, cy);
    } else {
      for (int i = cx - r; i <= cx + r; ++i) {
        scan_cell(i, cy - r);
        scan_cell(i, cy + r);
      }
      for (int j = cy - r + 1; j <= cy + r - 1; ++j) {
        scan_cell(cx - r, j);
        scan_cell(cx + r, j);
      }
    }
    if (cx - r <= 0 && cy - r <= 0 && cx + r >= nx_ - 1 && cy + r >= ny_ - 1) break;  // all seen
    // Every segment unseen lies outside the (2 r + 1)-cell square around p's
    // cell: at least as far from p as the square's nearest side.
    const double cells_to_side = std::min(std::min(fx - (cx - r), (cx + r + 1) - fx),
                                          std::min(fy - (cy - r), (cy + r + 1) - fy));
    const double bound = cells_to_side * cell_ - kBoundMarginPx;
    if (bound > 0.0 && best.distance2 < bound * bound) break;
  }
  return best;
}

}  // namespace calib
