#pragma once
// Scan conversion of the simulated mesh (and of plain polygons), the hot loop
// of every candidate evaluation, by two rules:
//  - area coverage (RasterizeMeshCoverage, FillPolygonsCoverage): the exact
//    area of each pixel square that the shape covers (pixel_coverage.h); the
//    score's rule, continuous in the node positions;
//  - pixel centres (RasterizeMesh, RasterizeTriangles, FillPolygons): a
//    BitMask, for the synthetic renderer, masks of the rest shape, the
//    reference scene's object and tests.
//
// Area coverage: a pixel's coverage is the area of its square where the
// winding number of the shape's closed loops is non-zero, taken as
// min(1, |integral of the winding number over the square|): exact wherever
// the winding number is 0 or of one sign and at most 1 in magnitude over the
// square (a mesh whose triangles are all positive, a simple polygon of
// either orientation, disjoint loops), and an approximation only on the
// pixels where parts of a folded-over mesh or of self-intersecting loops
// overlap. Computed as font rasterisers do (signed-area accumulation): each
// edge is cut into pieces per pixel row and column; each piece adds its
// signed height (+ downwards) times the share of its pixel right of it (on
// average over the piece) to its column and the rest of its height to the
// next column; the running sum along the row is each pixel's signed
// coverage. Only the columns the outline touches are visited;
// between them the sum is constant: a winding number, a span of interior
// (or empty) pixels, or along an exactly horizontal edge a run of equal
// fractions. Shapes may lie partly or wholly outside the mask; edges with a
// non-finite end point are ignored. The same input gives bit-identical
// output (another order of the same edges may differ in the last bits).
//
// Pixel-centre rule (the other three entry points): mask pixel (x, y) is on
// iff its centre, frame point (origin_x + x + 0.5, origin_y + y + 0.5), has a
// non-zero winding number with respect to the shape's closed loops. Centres
// exactly on an edge are decided by a half-open rule, the same everywhere:
//   - rows: an edge from y_a to y_b (y_a < y_b) crosses the rows whose centre
//     yc satisfies y_a <= yc < y_b; exactly horizontal edges cross no row;
//   - columns: a crossing at x counts for the centres xc >= x.
// So a 1 x 1 square [x, x + 1] x [y, y + 1] sets exactly frame pixel (x, y),
// and shapes sharing an edge never both claim, nor both miss, a centre on it.
// Pixels outside the mask are clipped; shapes may lie partly or wholly
// outside it. Edges with a non-finite end point are ignored (a simulator
// state that has blown up is reported as a failure before it is scored).
//
// The crossing x of an edge is computed from its end point of smaller y, so
// an edge shared by two triangles, or by a triangle and a boundary loop, gives
// bit-identical crossings whichever way it is traversed. That is what makes
// RasterizeMesh (boundary loops) and RasterizeTriangles (union of triangles)
// agree bit for bit on an orientation-preserving mesh.

#include "calib/core/mesh.h"
#include "calib/evaluator/bit_mask.h"
#include "calib/evaluator/pixel_coverage.h"

#include <cstdint>
#include <utility>
#include <vector>

namespace calib {

class Rasterizer {
 public:
  /// The score's path. Clears `interior` and sets in it the pixels wholly
  /// covered by the region enclosed by `mesh.boundary_loops` (coverage
  /// >= 1 - kCoverageTolerance), with node positions `positions` (#N, frame
  /// pixels); replaces `boundary` with the pixels covered in part (coverage
  /// in (kCoverageTolerance, 1 - kCoverageTolerance)), row by row, columns
  /// ascending, none of them in `interior`. Allocates only while its
  /// buffers (and `boundary`) grow, never in steady state. Cost ~ boundary
  /// edges x (rows + columns) crossed + rows x words of the covered rows.
  void RasterizeMeshCoverage(const Mesh& mesh, const std::vector<Vec2>& positions,
                             BitMask& interior, std::vector<PixelCoverage>& boundary);
  void RasterizeMeshCoverage(const Mesh& mesh, const Vec2* positions, BitMask& interior,
                             std::vector<PixelCoverage>& boundary);

  /// As RasterizeMeshCoverage for `loops` as FillPolygons takes them.
  void FillPolygonsCoverage(const std::vector<std::vector<Vec2>>& loops, BitMask& interior,
                            std::vector<PixelCoverage>& boundary);

  /// The mask rows [first, second) that the last of the calls above
  /// touched: `interior` has no pixel outside them (CompareCoverageInRows).
  std::pair<int, int> covered_rows() const {
    return row_lo_ < row_hi_ ? std::pair<int, int>(row_lo_, row_hi_) : std::pair<int, int>(0, 0);
  }

  /// Fast path. Clears `mask` and fills the region enclosed by
  /// `mesh.boundary_loops`, with node positions `positions` (#N, frame
  /// pixels), by the non-zero winding rule. While every triangle has positive
  /// signed area this equals the union of the triangles (RasterizeTriangles);
  /// with inverted triangles, folded-over parts may cancel, so use
  /// RasterizeTriangles there. Allocates only while its buffers grow (the
  /// first calls), never in steady state. Cost ~ boundary edges x rows
  /// crossed + rows x words of the covered row range.
  void RasterizeMesh(const Mesh& mesh, const std::vector<Vec2>& positions, BitMask& mask);
  /// As above with `positions` pointing at #N nodes.
  void RasterizeMesh(const Mesh& mesh, const Vec2* positions, BitMask& mask);

  /// Reference path: clears `mask` and ORs in every triangle of `mesh`, each
  /// scan-converted on its own with the rule above, whatever its orientation.
  /// Slower (every interior edge is visited twice); used by tests and for
  /// states with inverted triangles.
  void RasterizeTriangles(const Mesh& mesh, const std::vector<Vec2>& positions, BitMask& mask);
  void RasterizeTriangles(const Mesh& mesh, const Vec2* positions, BitMask& mask);

  /// Clears `mask` and fills the non-zero-winding region of `loops`: each a
  /// closed polygon (last vertex joins the first) in frame pixels, either
  /// orientation; loops with fewer than 3 vertices add nothing.
  void FillPolygons(const std::vector<std::vector<Vec2>>& loops, BitMask& mask);

 private:
  // One non-horizontal edge, from its end point of smaller y (a) to b.
  struct Edge {
    double ax = 0.0;
    double ay = 0.0;
    double dx_dy = 0.0;  // (b.x - a.x) / (b.y - a.y)
    int row_begin = 0;   // mask rows [row_begin, row_end) it crosses
    int row_end = 0;
    int winding = 0;     // +1 when traversed downwards (y increasing), else -1
  };
  // An edge crossing a row, as the first mask column whose centre lies at or
  // right of the crossing (clamped to [0, width]).
  struct Crossing {
    int column = 0;
    int winding = 0;
  };

  // A piece of the outline's signed area for one pixel of one row (mask
  // coordinates; column 0 also gathers what lies left of the mask).
  struct CoverageDelta {
    int row = 0;
    int column = 0;
    double delta = 0.0;
  };

  // Empties the coverage deltas for a fill of `interior`.
  void BeginCoverage(const BitMask& interior);
  // Adds the directed edge p -> q (frame pixels) to the coverage deltas.
  void AddCoverageEdge(const Vec2& p, const Vec2& q);
  // Adds the piece of an edge in mask row `row` spanning x0 <= x1 (mask
  // columns), of signed height `height` (+ downwards).
  void AddCoveragePiece(int row, double x0, double x1, double height);
  // Sums the collected deltas row by row into `interior` and `boundary`.
  void FinishCoverage(BitMask& interior, std::vector<PixelCoverage>& boundary);

  // Empties the edge list for a fill of `mask`.
  void BeginEdges(const BitMask& mask);
  // Adds the directed edge p -> q (no-op when horizontal, non-finite or
  // outside the mask's rows).
  void AddEdge(const Vec2& p, const Vec2& q);
  // ORs the non-zero-winding region of the collected edges into `mask`.
  void FillEdges(BitMask& mask);

  std::vector<Edge> edges_;
  std::vector<int> row_offsets_;  // per-row crossing counts, then offsets
  std::vector<Crossing> crossings_;
  int row_lo_ = 0;  // rows crossed by some edge: [row_lo_, row_hi_)
  int row_hi_ = 0;
  int mask_height_ = 0;
  int mask_width_ = 0;
  double centre_x0_ = 0.0;  // frame x of mask column 0's centre
  double centre_y0_ = 0.0;  // frame y of mask row 0's centre

  std::vector<CoverageDelta> coverage_deltas_;  // as added, rows in [row_lo_, row_hi_)
  std::vector<CoverageDelta> coverage_sorted_;  // the same by row (stable)
  std::vector<double> row_sums_;       // per column, a row's deltas summed; 0 between rows
  std::vector<uint64_t> row_touched_;  // per column, a bit: row_sums_ got a delta; 0 between rows
  double origin_x_ = 0.0;  // frame position of the mask's corner
  double origin_y_ = 0.0;
};

}  // namespace calib
