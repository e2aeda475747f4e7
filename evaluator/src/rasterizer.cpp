#include "calib/evaluator/rasterizer.h"

#include "loop_edges.h"

#include <algorithm>
#include <cmath>

namespace calib {
namespace {

// First index i in [0, limit] with `start + i >= t`, i.e. ceil(t - start),
// clamped; t - start may be far outside the int range.
int FirstIndexAtOrAfter(double t, double start, int limit) {
  return static_cast<int>(std::clamp(std::ceil(t - start), 0.0, static_cast<double>(limit)));
}

}  // namespace

void Rasterizer::BeginEdges(const BitMask& mask) {
  edges_.clear();
  mask_width_ = mask.width();
  mask_height_ = mask.height();
  centre_x0_ = mask.origin_x() + 0.5;
  centre_y0_ = mask.origin_y() + 0.5;
  row_lo_ = mask_height_;
  row_hi_ = 0;
}

void Rasterizer::AddEdge(const Vec2& p, const Vec2& q) {
  if (!(std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(q.x()) &&
        std::isfinite(q.y()))) {
    return;
  }
  if (p.y() == q.y()) return;
  const bool downwards = p.y() < q.y();
  const Vec2& a = downwards ? p : q;
  const Vec2& b = downwards ? q : p;
  Edge e;
  e.row_begin = FirstIndexAtOrAfter(a.y(), centre_y0_, mask_height_);
  e.row_end = FirstIndexAtOrAfter(b.y(), centre_y0_, mask_height_);
  if (e.row_begin >= e.row_end) return;
  e.ax = a.x();
  e.ay = a.y();
  e.dx_dy = (b.x() - a.x()) / (b.y() - a.y());
  // Only for a sub-normal height can the slope overflow; such an edge crosses
  // at most one row, where it is taken as vertical through a.
  if (!std::isfinite(e.dx_dy)) e.dx_dy = 0.0;
  e.winding = downwards ? 1 : -1;
  edges_.push_back(e);
  row_lo_ = std::min(row_lo_, e.row_begin);
  row_hi_ = std::max(row_hi_, e.row_end);
}

void Rasterizer::FillEdges(BitMask& mask) {
  if (row_lo_ >= row_hi_) return;
  const int num_rows = row_hi_ - row_lo_;

  // Counting sort of the crossings by row (r counted from row_lo_), in
  // offsets[0, num_rows + 2): the difference pass and prefix sum leave
  // offsets[r + 1] = number of crossings in rows < r (the start of row r); the
  // fill pass uses offsets[r + 1] as row r's write cursor, which leaves row
  // r's crossings in [offsets[r], offsets[r + 1]).
  //
  // Buffers are sized for the whole mask (offsets) or grown with slack
  // (crossings), so frames of a moving object do not reallocate.
  if (row_offsets_.size() < static_cast<size_t>(mask_height_) + 2) {
    row_offsets_.resize(static_cast<size_t>(mask_height_) + 2);
  }
  int* offsets = row_offsets_.data();
  std::fill(offsets, offsets + num_rows + 2, 0);
  for (const Edge& e : edges_) {
    ++offsets[e.row_begin - row_lo_ + 1];
    --offsets[e.row_end - row_lo_ + 1];
  }
  int active = 0;  // edges crossing the row
  int total = 0;
  for (int r = 0; r < num_rows; ++r) {
    active += offsets[r + 1];
    offsets[r + 1] = total;
    total += active;
  }
  if (crossings_.size() < static_cast<size_t>(total)) {
    crossings_.resize(static_cast<size_t>(total) + static_cast<size_t>(total) / 2 + 64);
  }
  Crossing* crossings = crossings_.data();
  for (const Edge& e : edges_) {
    for (int r = e.row_begin; r < e.row_end; ++r) {
      const double x = e.ax + ((centre_y0_ + r) - e.ay) * e.dx_dy;
      crossings[offsets[r - row_lo_ + 1]++] = {FirstIndexAtOrAfter(x, centre_x0_, mask_width_),
                                               e.winding};
    }
  }

  for (int r = 0; r < num_rows; ++r) {
    Crossing* begin = crossings + offsets[r];
    Crossing* end = crossings + offsets[r + 1];
    // Rows hold a handful of crossings: insertion sort.
    for (Crossing* i = begin + 1; i < end; ++i) {
      const Crossing c = *i;
      Crossing* j = i;
      for (; j > begin && (j - 1)->column > c.column; --j) *j = *(j - 1);
      *j = c;
    }
    // Columns between consecutive crossings share one winding number; equal
    // columns bound an empty run, so the order of ties does not matter.
    int winding = 0;
    int span_begin = 0;
    for (const Crossing* c = begin; c < end; ++c) {
      const int before = winding;
      winding += c->winding;
      if (before == 0 && winding != 0) {
        span_begin = c->column;
      } else if (before != 0 && winding == 0) {
        mask.SetSpan(row_lo_ + r, span_begin, c->column);
      }
    }
  }
}

void Rasterizer::RasterizeMesh(const Mesh& mesh, const std::vector<Vec2>& positions,
                               BitMask& mask) {
  RasterizeMesh(mesh, positions.data(), mask);
}

void Rasterizer::RasterizeMesh(const Mesh& mesh, const Vec2* positions, BitMask& mask) {
  mask.Clear();
  BeginEdges(mask);
  detail::ForEachBoundaryEdge(mesh, positions,
                              [this](const Vec2& p, const Vec2& q) { AddEdge(p, q); });
  FillEdges(mask);
}

void Rasterizer::RasterizeTriangles(const Mesh& mesh, const std::vector<Vec2>& positions,
                                    BitMask& mask) {
  RasterizeTriangles(mesh, positions.data(), mask);
}

void Rasterizer::RasterizeTriangles(const Mesh& mesh, const Vec2* positions, BitMask& mask) {
  mask.Clear();
  for (const auto& tri : mesh.triangles) {
    BeginEdges(mask);
    for (int k = 0; k < 3; ++k) AddEdge(positions[tri[k]], positions[tri[(k + 1) % 3]]);
    FillEdges(mask);
  }
}

void Rasterizer::FillPolygons(const std::vector<std::vector<Vec2>>& loops, BitMask& mask) {
  mask.Clear();
  BeginEdges(mask);
  detail::ForEachLoopEdge(loops, [this](const Vec2& p, const Vec2& q) { AddEdge(p, q); });
  FillEdges(mask);
}

}  // namespace calib
