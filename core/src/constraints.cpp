#include "calib/core/constraints.h"

#include <cmath>

namespace calib {

int ProjectOutOfDiscs(std::span<const Disc> discs, std::span<const double> inverse_weight,
                      std::span<Vec2> x) {
  int moved = 0;
  for (const Disc& disc : discs) {
    // A node projected onto the circle may land a rounding error inside it;
    // that counts as on the boundary.
    const double inner = disc.radius_px * (1.0 - 1e-12);
    const double inner_sq = inner * inner;
    for (size_t i = 0; i < x.size(); ++i) {
      const Vec2 d = x[i] - disc.centre;
      const double dist_sq = d.squaredNorm();
      if (dist_sq >= inner_sq || inverse_weight[i] == 0.0) continue;
      const double dist = std::sqrt(dist_sq);
      x[i] = dist > 0.0 ? Vec2(disc.centre + d * (disc.radius_px / dist))
                        : Vec2(disc.centre + Vec2(disc.radius_px, 0.0));
      ++moved;
    }
  }
  return moved;
}

int RepairInvertedTriangles(const Mesh& mesh, double min_area_fraction,
                            std::span<const double> inverse_weight, std::span<Vec2> x) {
  int repaired = 0;
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
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
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    if (!(SignedArea(x[a], x[b], x[c]) > 0.0)) return static_cast<int>(t);
  }
  return -1;
}

int FindNodeInsideDisc(std::span<const Disc> discs, std::span<const Vec2> x, double tolerance_px) {
  for (const Disc& disc : discs) {
    const double limit = disc.radius_px - tolerance_px;
    if (limit <= 0.0) continue;
    for (size_t i = 0; i < x.size(); ++i) {
      if ((x[i] - disc.centre).squaredNorm() < limit * limit) return static_cast<int>(i);
    }
  }
  return -1;
}

}  // namespace calib
