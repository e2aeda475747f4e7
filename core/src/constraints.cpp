#include "calib/core/constraints.h"

#include <cmath>
#include <vector>

// Each constraint is a scalar loop in index order whose step can move nodes
// that later elements read, so it must stay sequential. Most elements need no
// step, though: a scan finds the next element that does, 16 at a time with a
// branch-free test that GCC vectorises (the same IEEE operations as the
// scalar test, so it flags exactly the elements the scalar loop would act
// on), and the scalar step runs from there. The scans are compiled for
// AVX-512, AVX2 and plain x86-64 and picked at load time; this file is built
// with -ffp-contract=off (core/CMakeLists.txt), so no FMA changes a bit.
// tests/core/constraints_test.cpp holds them to the plain loops.

// Not under ThreadSanitizer: the clones' resolver runs while the program is
// relocated, before the sanitizer's runtime is up, and its instrumented
// entry crashes every program that links this file.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && \
    !defined(__SANITIZE_THREAD__)
#define CALIB_SCAN_TARGETS __attribute__((target_clones("avx512f", "avx2", "default")))
#else
#define CALIB_SCAN_TARGETS
#endif

namespace calib {
namespace {

constexpr size_t kScanBlock = 16;

// SignedArea(x[a], x[b], x[c]) of triangle t on interleaved coordinates.
[[gnu::always_inline]] inline double TriangleArea(const std::array<int, 3>* __restrict tri,
                                                  const double* __restrict x, size_t t) {
  const int a = tri[t][0], b = tri[t][1], c = tri[t][2];
  const double ux = x[2 * b] - x[2 * a], uy = x[2 * b + 1] - x[2 * a + 1];
  const double vx = x[2 * c] - x[2 * a], vy = x[2 * c + 1] - x[2 * a + 1];
  return 0.5 * (ux * vy - uy * vx);
}

// First t in [begin, end) with !(area >= min_area_fraction * A0), or end:
// RepairInvertedTriangles' test.
CALIB_SCAN_TARGETS size_t NextTriangleToRepair(const std::array<int, 3>* __restrict tri,
                                               const double* __restrict rest_area,
                                               double min_area_fraction,
                                               const double* __restrict x, size_t begin,
                                               size_t end) {
  size_t t = begin;
  for (; t + kScanBlock <= end; t += kScanBlock) {
    int any = 0;
    for (size_t l = t; l < t + kScanBlock; ++l) {
      any |= !(TriangleArea(tri, x, l) >= min_area_fraction * rest_area[l]);
    }
    if (any) break;
  }
  for (; t < end; ++t) {
    if (!(TriangleArea(tri, x, t) >= min_area_fraction * rest_area[t])) return t;
  }
  return end;
}

// First t in [0, end) with !(area > 0), or end: FindInvertedTriangle's test.
CALIB_SCAN_TARGETS size_t FirstNonPositiveTriangle(const std::array<int, 3>* __restrict tri,
                                                   const double* __restrict x, size_t end) {
  size_t t = 0;
  for (; t + kScanBlock <= end; t += kScanBlock) {
    int any = 0;
    for (size_t l = t; l < t + kScanBlock; ++l) any |= !(TriangleArea(tri, x, l) > 0.0);
    if (any) break;
  }
  for (; t < end; ++t) {
    if (!(TriangleArea(tri, x, t) > 0.0)) return t;
  }
  return end;
}

// First i in [begin, end) with !(|x_i - centre|^2 >= inner_sq) and a nonzero
// inverse weight, or end: ProjectOutOfDiscs' test. With kAnyWeight, the
// weight is ignored and the test is |x_i - centre|^2 < inner_sq
// (FindNodeInsideDisc's).
template <bool kAnyWeight>
[[gnu::always_inline]] inline bool NodeFlagged(const double* __restrict x,
                                               const double* __restrict inverse_weight,
                                               double cx, double cy, double inner_sq, size_t i) {
  const double dx = x[2 * i] - cx, dy = x[2 * i + 1] - cy;
  const double dist_sq = dx * dx + dy * dy;
  if constexpr (kAnyWeight) {
    return dist_sq < inner_sq;
  } else {
    return !(dist_sq >= inner_sq) & !(inverse_weight[i] == 0.0);
  }
}

template <bool kAnyWeight>
[[gnu::always_inline]] inline size_t NextNodeInDisc(const double* __restrict x,
                                                    const double* __restrict inverse_weight,
                                                    double cx, double cy, double inner_sq,
                                                    size_t begin, size_t end) {
  size_t i = begin;
  for (; i + kScanBlock <= end; i += kScanBlock) {
    int any = 0;
    for (size_t l = i; l < i + kScanBlock; ++l) {
      any |= NodeFlagged<kAnyWeight>(x, inverse_weight, cx, cy, inner_sq, l);
    }
    if (any) break;
  }
  for (; i < end; ++i) {
    if (NodeFlagged<kAnyWeight>(x, inverse_weight, cx, cy, inner_sq, i)) return i;
  }
  return end;
}

CALIB_SCAN_TARGETS size_t NextNodeToProject(const double* __restrict x,
                                            const double* __restrict inverse_weight, double cx,
                                            double cy, double inner_sq, size_t begin,
                                            size_t end) {
  return NextNodeInDisc<false>(x, inverse_weight, cx, cy, inner_sq, begin, end);
}

CALIB_SCAN_TARGETS size_t FirstNodeWithin(const double* __restrict x, double cx, double cy,
                                          double limit_sq, size_t end) {
  return NextNodeInDisc<true>(x, nullptr, cx, cy, limit_sq, 0, end);
}

}  // namespace

namespace {

// The part of `motion` along the tangent of `normal`, shortened to at most
// `limit`: what Coulomb friction undoes of a slide.
Vec2 LimitedTangent(const Vec2& motion, const Vec2& normal, double limit) {
  const Vec2 tangent = motion - motion.dot(normal) * normal;
  const double length = tangent.norm();
  return length <= limit ? tangent : Vec2(tangent * (limit / length));
}

}  // namespace

int ProjectOutOfDiscs(std::span<const Disc> discs, std::span<const double> inverse_weight,
                      std::span<Vec2> x, const SubstepStart& start) {
  static_assert(sizeof(Vec2) == 2 * sizeof(double));
  const double* xd = reinterpret_cast<const double*>(x.data());
  const size_t n = x.size();
  const bool start_known = start.x.size() == n && start.discs.size() == discs.size();
  int moved = 0;
  for (size_t k = 0; k < discs.size(); ++k) {
    const Disc& disc = discs[k];
    // A node projected onto the circle may land a rounding error inside it;
    // that counts as on the boundary.
    const double inner = disc.radius_px * (1.0 - 1e-12);
    const double inner_sq = inner * inner;
    for (size_t i = NextNodeToProject(xd, inverse_weight.data(), disc.centre.x(),
                                      disc.centre.y(), inner_sq, 0, n);
         i < n; i = NextNodeToProject(xd, inverse_weight.data(), disc.centre.x(),
                                      disc.centre.y(), inner_sq, i + 1, n)) {
      const Vec2 d = x[i] - disc.centre;
      const double dist_sq = d.squaredNorm();
      if (dist_sq >= inner_sq || inverse_weight[i] == 0.0) continue;
      Vec2 normal;
      double depth;
      const Vec2 from = start_known ? Vec2(start.x[i] - start.discs[k].centre) : Vec2::Zero();
      const double from_norm = from.norm();
      if (start_known && from_norm > 0.0 && !(d.dot(from) > 0.0)) {
        // Where the node was against the disc before the step (both may
        // have moved). Past the centre from there, the nearest way out is
        // the far side: go back the way it came instead.
        normal = from / from_norm;
        depth = disc.radius_px - normal.dot(d);
        x[i] += depth * normal;
      } else {
        const double dist = std::sqrt(dist_sq);
        x[i] = dist > 0.0 ? Vec2(disc.centre + d * (disc.radius_px / dist))
                          : Vec2(disc.centre + Vec2(disc.radius_px, 0.0));
        normal = dist > 0.0 ? Vec2(d / dist) : Vec2(1.0, 0.0);
        depth = disc.radius_px - dist;
      }
      if (start_known && start.friction > 0.0) {
        // The node's slide along the surface relative to the disc since
        // the start, undone up to friction x depth (along the tangent, so
        // it stays outside).
        const Vec2 slide = (x[i] - disc.centre) - from;
        x[i] -= LimitedTangent(slide, normal, start.friction * depth);
      }
      ++moved;
    }
  }
  return moved;
}

namespace {

// Whether p lies inside the outline (crossing parity over every boundary
// loop, so a point in a hole is outside).
bool InsideOutline(const Mesh& mesh, std::span<const Vec2> x, const Vec2& p) {
  bool inside = false;
  for (const std::vector<int>& loop : mesh.boundary_loops) {
    for (size_t k = 0, m = loop.size(); k < m; ++k) {
      const Vec2& a = x[loop[k]];
      const Vec2& b = x[loop[(k + 1) % m]];
      if ((a.y() > p.y()) != (b.y() > p.y()) &&
          p.x() < a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y())) {
        inside = !inside;
      }
    }
  }
  return inside;
}

// Whether disc d's centre lay on the outer side of the line of edge a -> b
// at the substep's start.
bool CentreWasInFront(const SubstepStart& start, int a, int b, size_t d) {
  const Vec2 e = start.x[b] - start.x[a];
  const Vec2 outward(e.y(), -e.x());
  return outward.dot(start.discs[d].centre - start.x[a]) > 0.0;
}

}  // namespace

bool NearestInteriorEdgePoint(const Vec2& a, const Vec2& b, const Vec2& centre, EdgePoint* edge_point) {
  const Vec2 e = b - a;
  const double len_sq = e.squaredNorm();
  if (!(len_sq > 0.0)) return false;
  const double t = (centre - a).dot(e) / len_sq;
  if (!(t > 0.0 && t < 1.0)) return false;
  // The interior lies to the left of a -> b (positive triangles).
  edge_point->t = t;
  edge_point->inward = Vec2(-e.y(), e.x()) / std::sqrt(len_sq);
  edge_point->s = edge_point->inward.dot(a - centre);
  return true;
}

int ProjectBoundaryOutOfDiscs(const Mesh& mesh, std::span<const Disc> discs,
                              std::span<const double> inverse_weight, std::span<Vec2> x,
                              const SubstepStart& start) {
  const bool start_known = start.x.size() == x.size() && start.discs.size() == discs.size();
  int moved = 0;
  for (size_t d = 0; d < discs.size(); ++d) {
    const Disc& disc = discs[d];
    const double r = disc.radius_px;
    // Edges are moved only when they lie inside by more than a hundredth of
    // a pixel (invisible to the rasteriser), then onto the circle itself:
    // the tilt that leaves an edge slightly inside after its step is
    // second order, so the simulator's rounds stop after one or two instead
    // of chasing it to rounding error.
    const double inner = r - kEdgeContactTolerancePx;
    // A centre that got inside the outline (the disc went through an edge
    // between two substeps, or a tilting edge swept over it) is pushed back
    // out through the edges it overlaps; otherwise an edge with the centre
    // on its inner side is a convex corner's other edge, not in contact.
    const bool centre_inside = InsideOutline(mesh, x, disc.centre);
    for (const std::vector<int>& loop : mesh.boundary_loops) {
      const size_t m = loop.size();
      for (size_t k = 0; k < m; ++k) {
        const int a = loop[k], b = loop[(k + 1) % m];
        // With the centre outside, an edge is moved only within r of it
        // (0 < s < inner below): one whose bounding box lies farther (and a
        // pixel) is skipped without a division.
        if (!centre_inside && !BoxWithin(x[a], x[b], disc.centre, r + 1.0)) continue;
        // Nearest an end node: ProjectOutOfDiscs' case. s > 0: the centre
        // is in front of the edge, outside.
        EdgePoint nearest;
        if (!NearestInteriorEdgePoint(x[a], x[b], disc.centre, &nearest)) continue;
        const double t = nearest.t, s = nearest.s;
        const Vec2& n = nearest.inward;
        if (!(s < inner)) continue;
        if (!(s > (centre_inside ? -r : 0.0)) &&
            !(centre_inside && start_known && CentreWasInFront(start, a, b, d))) {
          continue;
        }
        const double wa = inverse_weight[a] * (1.0 - t), wb = inverse_weight[b] * t;
        const double denom = wa * (1.0 - t) + wb * t;
        if (!(denom > 0.0)) continue;  // both ends clamped
        const double lambda = (r - s) / denom;
        x[a] += (lambda * wa) * n;
        x[b] += (lambda * wb) * n;
        if (start_known && start.friction > 0.0) {
          // The contact point's slide along the edge relative to the disc
          // since the start, undone up to friction x depth, shared as the
          // push was.
          const Vec2 point = (1.0 - t) * x[a] + t * x[b];
          const Vec2 point_start = (1.0 - t) * start.x[a] + t * start.x[b];
          const Vec2 slide = (point - disc.centre) - (point_start - start.discs[d].centre);
          const Vec2 undo = LimitedTangent(slide, n, start.friction * (r - s));
          x[a] -= (wa / denom) * undo;
          x[b] -= (wb / denom) * undo;
        }
        ++moved;
      }
    }
  }
  return moved;
}

int RepairInvertedTriangles(const Mesh& mesh, double min_area_fraction,
                            std::span<const double> inverse_weight, std::span<Vec2> x) {
  const double* xd = reinterpret_cast<const double*>(x.data());
  const size_t num_triangles = mesh.triangles.size();
  auto next = [&](size_t begin) {
    return NextTriangleToRepair(mesh.triangles.data(), mesh.rest_area_px2.data(),
                                min_area_fraction, xd, begin, num_triangles);
  };
  int repaired = 0;
  for (size_t t = next(0); t < num_triangles; t = next(t + 1)) {
    const auto [a, b, c] = mesh.triangles[t];
    const double target = min_area_fraction * mesh.rest_area_px2[t];
    const double area = SignedArea(x[a], x[b], x[c]);
    if (area >= target) continue;
    // dA/dp_k = 1/2 perp(p_{k+1} - p_{k+2}), perp(x, y) = (y, -x): moving a
    // node along it moves the node away from the line of the opposite edge.
    const Vec2 ga = 0.5 * Vec2(x[b].y() - x[c].y(), x[c].x() - x[b].x());
    const Vec2 gb = 0.5 * Vec2(x[c].y() - x[a].y(), x[a].x() - x[c].x());
    const Vec2 gc = 0.5 * Vec2(x[a].y() - x[b].y(), x[b].x() - x[a].x());
    const double wa = inverse_weight[a], wb = inverse_weight[b], wc = inverse_weight[c];
    const double denom = wa * ga.squaredNorm() + wb * gb.squaredNorm() + wc * gc.squaredNorm();
    if (!(denom > 0.0)) continue;  // all nodes fixed or collapsed to a point
    // Aim past the trigger (at twice it) so that the repaired triangle does
    // not sit on the threshold: area is quadratic in the positions, so one
    // linearised step lands near, not exactly on, its aim.
    const double lambda = (2.0 * target - area) / denom;
    x[a] += lambda * wa * ga;
    x[b] += lambda * wb * gb;
    x[c] += lambda * wc * gc;
    ++repaired;
  }
  return repaired;
}

int FindInvertedTriangle(const Mesh& mesh, std::span<const Vec2> x) {
  const size_t num_triangles = mesh.triangles.size();
  const size_t t = FirstNonPositiveTriangle(mesh.triangles.data(), reinterpret_cast<const double*>(x.data()), num_triangles);
  return t < num_triangles ? static_cast<int>(t) : -1;
}

int FindNodeInsideDisc(std::span<const Disc> discs, std::span<const Vec2> x, double tolerance_px) {
  for (const Disc& disc : discs) {
    const double limit = disc.radius_px - tolerance_px;
    if (limit <= 0.0) continue;
    const size_t i =
        FirstNodeWithin(reinterpret_cast<const double*>(x.data()), disc.centre.x(), disc.centre.y(), limit * limit, x.size());
    if (i < x.size()) return static_cast<int>(i);
  }
  return -1;
}

}  // namespace calib
