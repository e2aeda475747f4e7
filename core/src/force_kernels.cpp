#include "force_kernels.h"

#include "calib/core/energy_terms.h"

#include <cmath>

// AVX2 without FMA: the AVX2 kernel must round exactly as the baseline one,
// so it may not contract a * b + c whatever -ffp-contract says.
// The AVX-512 kernel enables FMA instructions (AVX-512F implies them in GCC);
// -ffp-contract=off, set for this file in core/CMakeLists.txt, keeps GCC
// from contracting. tests/core/model_test.cpp holds every kernel to the bits
// of the scalar sums.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__AVX2__)
#define CALIB_AVX2_KERNEL 1
#define CALIB_TARGET_AVX2 __attribute__((target("avx2")))
#else
#define CALIB_AVX2_KERNEL 0
#define CALIB_TARGET_AVX2
#endif
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__AVX512F__)
#define CALIB_AVX512_KERNEL 1
#define CALIB_TARGET_AVX512 \
  __attribute__((target("avx512f,avx512vl,avx512dq,prefer-vector-width=512")))
#else
#define CALIB_AVX512_KERNEL 0
#define CALIB_TARGET_AVX512
#endif

namespace calib::force_kernels {
namespace {

using energy_terms_detail::Atan2Series;
using energy_terms_detail::Atan2SeriesApplies;

// One triangle's area and angle springs, the operations of
// TriangleAngleEnergy / AreaEnergy arranged as the model's old sums had them
// (edge vectors shared, inverse squared lengths from the edge pass). With
// kSeriesOnly the atan is the series on any input, and needs_atan2 says
// whether that was out of its range; otherwise it is energy_terms' Atan2.
struct TriangleResult {
  double fax, fay, fbx, fby, fcx, fcy;
  double energy;
  bool needs_atan2;
};

// energy_terms_detail::Wrap with both candidates computed up front.
[[gnu::always_inline]] inline double WrapBranchFree(double angle) {
  constexpr double kPi = 3.141592653589793238462643383279502884;
  const double down = angle - 2.0 * kPi, up = angle + 2.0 * kPi;
  return angle > kPi ? down : (angle <= -kPi ? up : angle);
}

template <bool kSeriesOnly>
[[gnu::always_inline]] inline TriangleResult TriangleForces(
    double ax, double ay, double bx, double by, double cx, double cy, double i_ab, double i_bc,
    double i_ca, double rest_area, double inv_rest_area, double cos_a, double sin_a, double cos_b,
    double sin_b, const Stiffness& k) {
  // b - a, c - b, a - c: the same bits as the edge vector p_j - p_i times the
  // triangle's sign, since round-to-nearest is symmetric.
  const double abx = bx - ax, aby = by - ay;
  const double bcx = cx - bx, bcy = cy - by;
  const double cax = ax - cx, cay = ay - cy;

  // Area: A = 1/2 cross(ab, -ca); dA/dp_k = 1/2 perp_ccw(opposite edge),
  // perp_ccw(x, y) = (-y, x).
  const double area = -0.5 * (abx * cay - aby * cax);
  const double rel = (area - rest_area) * inv_rest_area;
  const double area_energy = 0.5 * k.area * rel * rel;
  const double s = -0.5 * k.area * rel * inv_rest_area;
  const double area_fax = s * -bcy, area_fay = s * bcx;
  const double area_fbx = s * -cay, area_fby = s * cax;
  const double area_fcx = s * -aby, area_fcy = s * abx;

  // Angles, as TriangleAngleEnergy: deviations at a and b from one atan2
  // each, the third from the angle sum.
  const double rax = cos_a * abx - sin_a * aby, ray = sin_a * abx + cos_a * aby;
  const double rbx = cos_b * bcx - sin_b * bcy, rby = sin_b * bcx + cos_b * bcy;
  const double ya = -(rax * cay - ray * cax), xa = -(rax * cax + ray * cay);
  const double yb = -(rbx * aby - rby * abx), xb = -(rbx * abx + rby * aby);
  double d_a, d_b;
  bool in_range = true;
  if constexpr (kSeriesOnly) {
    d_a = Atan2Series(ya, xa);
    d_b = Atan2Series(yb, xb);
    in_range = Atan2SeriesApplies(ya, xa) & Atan2SeriesApplies(yb, xb);
  } else {
    d_a = energy_terms_detail::Atan2(ya, xa);
    d_b = energy_terms_detail::Atan2(yb, xb);
  }
  const double d_c = WrapBranchFree(-(d_a + d_b));
  const double angle_energy = 0.5 * k.angle * (d_a * d_a + d_b * d_b + d_c * d_c);
  const double pabx = i_ab * aby, paby = i_ab * -abx;
  const double pbcx = i_bc * bcy, pbcy = i_bc * -bcx;
  const double pcax = i_ca * cay, pcay = i_ca * -cax;
  const double w_a = -k.angle * (d_a - d_c);
  const double w_b = -k.angle * (d_b - d_c);
  const double angle_fax = (w_b - w_a) * pabx - w_a * pcax;
  const double angle_fay = (w_b - w_a) * paby - w_a * pcay;
  const double angle_fbx = (w_a - w_b) * pabx - w_b * pbcx;
  const double angle_fby = (w_a - w_b) * paby - w_b * pbcy;
  const double angle_fcx = w_a * pcax + w_b * pbcx;
  const double angle_fcy = w_a * pcay + w_b * pbcy;

  // A zero-length edge leaves the angles undefined: area spring only. The
  // angle values are computed regardless (possibly NaN) and dropped here.
  const bool angles_on = (k.angle != 0.0) & (i_ab > 0.0) & (i_bc > 0.0) & (i_ca > 0.0);
  // Every operand of a select is computed unconditionally: under GCC's
  // default -ftrapping-math a conditional operation is not if-converted, and
  // the loop would not vectorise.
  const double both_fax = area_fax + angle_fax, both_fay = area_fay + angle_fay;
  const double both_fbx = area_fbx + angle_fbx, both_fby = area_fby + angle_fby;
  const double both_fcx = area_fcx + angle_fcx, both_fcy = area_fcy + angle_fcy;
  const double both_energy = area_energy + angle_energy;
  TriangleResult r;
  r.fax = angles_on ? both_fax : area_fax;
  r.fay = angles_on ? both_fay : area_fay;
  r.fbx = angles_on ? both_fbx : area_fbx;
  r.fby = angles_on ? both_fby : area_fby;
  r.fcx = angles_on ? both_fcx : area_fcx;
  r.fcy = angles_on ? both_fcy : area_fcy;
  r.energy = angles_on ? both_energy : area_energy;
  r.needs_atan2 = angles_on & !in_range;
  return r;
}

// Pass (1): each edge's distance spring E = 1/2 k_D ((L - D0) / D0)^2 and
// Teschner damping -k_d / D0^2 ((v_i - v_j).u) u (see energy_terms.h): the
// force on node j (node i gets minus it), 1 / L^2 for the angle springs, and
// the energy. The arrays are parameters so that __restrict holds (GCC keeps
// it through inlining, not for block-scope pointers).
// With kScaled, edge e's k_D and k_d are times edge_scale[e].
template <bool kScaled>
[[gnu::always_inline]] inline void EdgePass(
    int num_edges, const int* __restrict edge_i, const int* __restrict edge_j,
    const double* __restrict rest_length, const double* __restrict inv_rest_length,
    const double* __restrict edge_scale, const double* __restrict x,
    const double* __restrict v, double k_d_all, double c_d_all, double* __restrict out_force,
    double* __restrict out_force_neg, double* __restrict out_inv_sq,
    double* __restrict out_energy) {
  for (int e = 0; e < num_edges; ++e) {
    const double k_d = kScaled ? k_d_all * edge_scale[e] : k_d_all;
    const double c_d = kScaled ? c_d_all * edge_scale[e] : c_d_all;
    const int i = edge_i[e], j = edge_j[e];
    const double dx = x[2 * j] - x[2 * i], dy = x[2 * j + 1] - x[2 * i + 1];
    const double dvx = v[2 * j] - v[2 * i], dvy = v[2 * j + 1] - v[2 * i + 1];
    const double length_sq = dx * dx + dy * dy;
    const bool ok = length_sq > 0.0;
    const double length = std::sqrt(length_sq);
    // A zero-length spring has no direction: 1/L taken as 0 gives it no
    // force (an exact zero, which leaves the node sums unchanged) and no
    // angle springs. Every value is computed on every lane, and the force is
    // stored without a select, so that no load sinks under a condition.
    const double inv_length_if_ok = 1.0 / length;
    const double inv_length = ok ? inv_length_if_ok : 0.0;
    const double inv_rest = inv_rest_length[e];
    const double inv_length_sq = inv_length * inv_length;
    const double strain = (length - rest_length[e]) * inv_rest;
    // Force on j along d: -k_D strain / D0 / L; damping adds
    // -k_d / D0^2 ((v_j - v_i).d) / L^2.
    const double along = -k_d * strain * inv_rest * inv_length -
                         c_d * inv_rest * inv_rest * (dvx * dx + dvy * dy) * inv_length_sq;
    const double energy = 0.5 * k_d * strain * strain;
    out_inv_sq[e] = inv_length_sq;
    const double fx = along * dx, fy = along * dy;
    out_force[2 * e] = fx;
    out_force[2 * e + 1] = fy;
    out_force_neg[2 * e] = -fx;
    out_force_neg[2 * e + 1] = -fy;
    // A zero-length spring has strain -1.
    out_energy[e] = ok ? energy : 0.5 * k_d;
  }
}

// Pass (2): each triangle's forces and energy with the atan series on every
// lane; needs_atan2 marks the triangles pass (3) redoes. Returns their count.
// Triangle t's stiffnesses: k's, with kScaled its k_A times
// triangle_scale[t] and its k_phi times angle_scale[t].
template <bool kScaled>
[[gnu::always_inline]] inline Stiffness TriangleStiffness(const Stiffness& k,
                                                          const double* __restrict triangle_scale,
                                                          const double* __restrict angle_scale,
                                                          int t) {
  if constexpr (!kScaled) {
    return k;
  } else {
    Stiffness scaled = k;
    scaled.area = k.area * triangle_scale[t];
    scaled.angle = k.angle * angle_scale[t];
    return scaled;
  }
}

template <bool kScaled>
[[gnu::always_inline]] inline int TrianglePass(
    int num_triangles, const int* __restrict tri_a, const int* __restrict tri_b,
    const int* __restrict tri_c, const int* __restrict edge_ab, const int* __restrict edge_bc,
    const int* __restrict edge_ca, const double* __restrict rest_area,
    const double* __restrict inv_rest_area, const double* __restrict cos_a,
    const double* __restrict sin_a, const double* __restrict cos_b,
    const double* __restrict sin_b, const double* __restrict triangle_scale,
    const double* __restrict angle_scale, const double* __restrict x,
    const double* __restrict inv_sq, const Stiffness k,
    double* __restrict fa, double* __restrict fb, double* __restrict fc,
    double* __restrict energy, int* __restrict needs_atan2) {
  int num_needing_atan2 = 0;
  for (int t = 0; t < num_triangles; ++t) {
    const int a = tri_a[t], b = tri_b[t], c = tri_c[t];
    const TriangleResult r = TriangleForces<true>(
        x[2 * a], x[2 * a + 1], x[2 * b], x[2 * b + 1], x[2 * c], x[2 * c + 1],
        inv_sq[edge_ab[t]], inv_sq[edge_bc[t]], inv_sq[edge_ca[t]], rest_area[t],
        inv_rest_area[t], cos_a[t], sin_a[t], cos_b[t], sin_b[t],
        TriangleStiffness<kScaled>(k, triangle_scale, angle_scale, t));
    fa[2 * t] = r.fax;
    fa[2 * t + 1] = r.fay;
    fb[2 * t] = r.fbx;
    fb[2 * t + 1] = r.fby;
    fc[2 * t] = r.fcx;
    fc[2 * t + 1] = r.fcy;
    energy[t] = r.energy;
    needs_atan2[t] = r.needs_atan2;
    num_needing_atan2 += r.needs_atan2;
  }
  return num_needing_atan2;
}

// Pass (4): forces[n] = +0 + contribution[pair 0] + contribution[pair 1] +
// ... in its list's order, per (x, y) pair, kNodeGroup nodes side by side:
// their chains of additions are independent, so the CPU overlaps them. A
// list shorter than its group's is padded with the zero pair: x + (+0) is x
// for every sum here (one that starts at +0 is never -0).
[[gnu::always_inline]] inline void NodePass(int num_groups, const int* __restrict group_start,
                                            const int* __restrict group_nodes,
                                            const int* __restrict group_pairs,
                                            const double* __restrict contribution,
                                            double* __restrict forces) {
  for (int g = 0; g < num_groups; ++g) {
    double sx[kNodeGroup], sy[kNodeGroup];
    for (int j = 0; j < kNodeGroup; ++j) sx[j] = sy[j] = 0.0;
    for (int p = group_start[g], end = group_start[g + 1]; p < end; p += kNodeGroup) {
      for (int j = 0; j < kNodeGroup; ++j) {
        const int k = group_pairs[p + j];
        sx[j] += contribution[2 * k];
        sy[j] += contribution[2 * k + 1];
      }
    }
    for (int j = 0; j < kNodeGroup; ++j) {
      const int n = group_nodes[kNodeGroup * g + j];
      if (n < 0) continue;
      forces[2 * n] = sx[j];
      forces[2 * n + 1] = sy[j];
    }
  }
}

// Sum of values[0..n) in eight interleaved partial sums combined pairwise:
// a fixed order that vectorises at any width.
[[gnu::always_inline]] inline double FixedOrderSum(const double* __restrict values, int n) {
  double acc[8] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  int k = 0;
  for (; k + 8 <= n; k += 8) {
    for (int l = 0; l < 8; ++l) acc[l] += values[k + l];
  }
  for (int l = 0; k + l < n; ++l) acc[l] += values[k + l];
  return ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
}

template <bool kScaled>
[[gnu::always_inline]] inline double ComputeForcesImpl(const Arrays& m, const Stiffness& k,
                                                       const double* __restrict x,
                                                       const double* __restrict v,
                                                       double* __restrict forces) {
  ForceWorkspace& ws = *m.workspace;
  double* const edge_force = ws.contribution.data();
  double* const edge_force_neg = edge_force + 2 * m.num_edges;
  double* const triangle_force_a = edge_force_neg + 2 * m.num_edges;
  double* const triangle_force_b = triangle_force_a + 2 * m.num_triangles;
  double* const triangle_force_c = triangle_force_b + 2 * m.num_triangles;

  // (1) Edges: distance springs and damping.
  EdgePass<kScaled>(m.num_edges, m.edge_i, m.edge_j, m.rest_length, m.inv_rest_length,
                    m.edge_scale, x, v, k.distance, k.damping, edge_force, edge_force_neg,
                    ws.edge_inv_length_sq.data(), ws.edge_energy.data());

  // (2) Triangles, every atan by the series.
  const int num_needing_atan2 = TrianglePass<kScaled>(
      m.num_triangles, m.triangle_a, m.triangle_b, m.triangle_c, m.triangle_edge_ab,
      m.triangle_edge_bc, m.triangle_edge_ca, m.rest_area, m.inv_rest_area, m.rest_cos_a,
      m.rest_sin_a, m.rest_cos_b, m.rest_sin_b, m.triangle_scale, m.angle_scale, x,
      ws.edge_inv_length_sq.data(), k,
      triangle_force_a, triangle_force_b, triangle_force_c, ws.triangle_energy.data(), ws.triangle_needs_atan2.data());

  // (3) The triangles with an angle outside the series' range, again with
  // std::atan2 (the series' lanes give the same bits as before).
  if (num_needing_atan2 > 0) {
    const double* inv_sq = ws.edge_inv_length_sq.data();
    for (int t = 0; t < m.num_triangles; ++t) {
      if (!ws.triangle_needs_atan2[t]) continue;
      const int a = m.triangle_a[t], b = m.triangle_b[t], c = m.triangle_c[t];
      const TriangleResult r = TriangleForces<false>(
          x[2 * a], x[2 * a + 1], x[2 * b], x[2 * b + 1], x[2 * c], x[2 * c + 1],
          inv_sq[m.triangle_edge_ab[t]], inv_sq[m.triangle_edge_bc[t]],
          inv_sq[m.triangle_edge_ca[t]], m.rest_area[t], m.inv_rest_area[t], m.rest_cos_a[t],
          m.rest_sin_a[t], m.rest_cos_b[t], m.rest_sin_b[t],
          TriangleStiffness<kScaled>(k, m.triangle_scale, m.angle_scale, t));
      triangle_force_a[2 * t] = r.fax;
      triangle_force_a[2 * t + 1] = r.fay;
      triangle_force_b[2 * t] = r.fbx;
      triangle_force_b[2 * t + 1] = r.fby;
      triangle_force_c[2 * t] = r.fcx;
      triangle_force_c[2 * t + 1] = r.fcy;
      ws.triangle_energy[t] = r.energy;
    }
  }

  // (4) Into the nodes: each node's forces summed from +0 in the order of
  // the plain scatter (edges, then triangles, each in index order), as
  // (x, y) pairs. The scatter's f_i -= f is here f_i + (-f): the same IEEE
  // operation (for finite values; a NaN's sign may differ). Four nodes at a
  // time, as independent chains.
  NodePass(m.num_node_groups, m.node_group_start, m.node_group_nodes, m.node_group_pairs,
           ws.contribution.data(), forces);

  // (5) Energy.
  return FixedOrderSum(ws.edge_energy.data(), m.num_edges) +
         FixedOrderSum(ws.triangle_energy.data(), m.num_triangles);
}

}  // namespace

double ComputeForcesBaseline(const Arrays& arrays, const Stiffness& k, const double* x,
                             const double* v, double* forces) {
  return arrays.edge_scale != nullptr ? ComputeForcesImpl<true>(arrays, k, x, v, forces)
                                      : ComputeForcesImpl<false>(arrays, k, x, v, forces);
}

#if CALIB_AVX2_KERNEL
CALIB_TARGET_AVX2 double ComputeForcesAvx2(const Arrays& arrays, const Stiffness& k,
                                           const double* x, const double* v, double* forces) {
  return arrays.edge_scale != nullptr ? ComputeForcesImpl<true>(arrays, k, x, v, forces)
                                      : ComputeForcesImpl<false>(arrays, k, x, v, forces);
}

bool CpuHasAvx2() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") != 0;
  }();
  return has;
}
#endif

#if CALIB_AVX512_KERNEL
CALIB_TARGET_AVX512 double ComputeForcesAvx512(const Arrays& arrays, const Stiffness& k,
                                               const double* x, const double* v,
                                               double* forces) {
  return arrays.edge_scale != nullptr ? ComputeForcesImpl<true>(arrays, k, x, v, forces)
                                      : ComputeForcesImpl<false>(arrays, k, x, v, forces);
}

bool CpuHasAvx512() {
  static const bool has = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx512f") != 0 && __builtin_cpu_supports("avx512vl") != 0 &&
           __builtin_cpu_supports("avx512dq") != 0;
  }();
  return has;
}
#else
// The build already targets AVX-512 (or this is not GCC on x86-64): the
// baseline kernel covers it.
double ComputeForcesAvx512(const Arrays& arrays, const Stiffness& k, const double* x,
                           const double* v, double* forces) {
  return arrays.edge_scale != nullptr ? ComputeForcesImpl<true>(arrays, k, x, v, forces)
                                      : ComputeForcesImpl<false>(arrays, k, x, v, forces);
}

bool CpuHasAvx512() { return false; }
#endif

#if !CALIB_AVX2_KERNEL
// The build already targets AVX2 (or this is not x86-64 with GCC/Clang): the
// baseline kernel is the only one.
double ComputeForcesAvx2(const Arrays& arrays, const Stiffness& k, const double* x,
                         const double* v, double* forces) {
  return arrays.edge_scale != nullptr ? ComputeForcesImpl<true>(arrays, k, x, v, forces)
                                      : ComputeForcesImpl<false>(arrays, k, x, v, forces);
}

bool CpuHasAvx2() { return false; }
#endif

}  // namespace calib::force_kernels
