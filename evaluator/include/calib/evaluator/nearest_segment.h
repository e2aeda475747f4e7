#pragma once
// The nearest point of a set of segments, for many query points: the mesh
// registration's matches of mesh nodes to the object's outline and of
// outline samples to the mesh's boundary (shape_tracking.h), each query
// against a few hundred segments.
//
// The segments' bounding boxes are binned in a uniform grid, and a query
// scans the cells in square rings around its own until no segment left
// unseen can be nearer than the nearest found (every point of such a
// segment lies outside the rings scanned). Each candidate's point and
// squared distance are computed as the plain scan computes them, and ties
// go to the lowest index, so the answer is the plain scan's bit for bit
// (NearestByScan, which a query outside the grid uses).

#include "calib/core/types.h"

#include <limits>
#include <span>
#include <utility>
#include <vector>

namespace calib {

struct SegmentPoint {
  double distance2 = std::numeric_limits<double>::infinity();
  int segment = -1;
  double share = 0.0;  ///< 0 at the segment's first end, 1 at its second
  Vec2 point = Vec2::Zero();
};

/// The point of segment [a, b] nearest p, as the share along it.
double NearestShare(const Vec2& a, const Vec2& b, const Vec2& p);

class NearestSegment {
 public:
  /// Indexes `num_segments` segments, segment k from ends(k).first to
  /// ends(k).second. Reuses its buffers: no allocation once they are as
  /// large as a build needs.
  template <class Ends>
  void Build(int num_segments, Ends&& ends) {
    a_.resize(num_segments);
    b_.resize(num_segments);
    for (int k = 0; k < num_segments; ++k) {
      const std::pair<Vec2, Vec2> e = ends(k);
      a_[k] = e.first;
      b_[k] = e.second;
    }
    Index();
  }

  int size() const { return static_cast<int>(a_.size()); }

  /// The segments' point nearest p: the least squared distance, the lowest
  /// segment index among equal ones (segment -1 when there is none).
  SegmentPoint Nearest(const Vec2& p) const;
  /// The same by scanning every segment in index order.
  SegmentPoint NearestByScan(const Vec2& p) const;

 private:
  std::vector<Vec2> a_, b_;
  // The grid: cell (i, j) covers origin_ + [i, i + 1) x [j, j + 1) cells of
  // side cell_; its segments are cell_items_[cell_start_[c] ..
  // cell_start_[c + 1]), c = j nx_ + i. nx_ = 0: no grid (every query scans).
  Vec2 origin_ = Vec2::Zero();
  double cell_ = 0.0;
  int nx_ = 0, ny_ = 0;
  std::vector<int> cell_start_, cell_items_;
  void Index();
  SegmentPoint Candidate(int k, const Vec2& p) const;
};

}  // namespace calib
