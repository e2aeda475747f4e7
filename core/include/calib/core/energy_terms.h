#pragma once
// Energy-term kernels of the mass-spring-like model of Arriola-Rios & Wyatt.
//
// Each kernel is a pure function of a few node positions: it returns the
// term's energy and ADDS the term's forces (the exact negative gradient of
// that energy) to the given force slots. The model loops over the mesh and
// calls them; the tests check each against central differences.
//
// Units: positions in pixels; stiffnesses in force x pixels (strains are
// dimensionless), so forces come out in the force unit of the calibration.

#include "calib/core/types.h"

#include <array>
#include <cmath>

namespace calib {


/// Distance spring between nodes i and j:
///   E_D = 1/2 k_D ((|p_j - p_i| - D0) / D0)^2.
/// Adds -dE/dp_i to f_i and -dE/dp_j to f_j. Returns E_D. A zero-length
/// spring has no direction: no force, energy 1/2 k_D.
double DistanceEnergy(const Vec2& p_i, const Vec2& p_j, double rest_length, double k_distance,
                      Vec2& f_i, Vec2& f_j);

/// Teschner's damping along the edge (paper eq. 12): with u the unit vector
/// from i to j, the force on i is -k_d / D0^2 ((v_i - v_j) . u) u and the force
/// on j its opposite. Its power f_i.v_i + f_j.v_j is never positive. Adds the
/// forces; returns nothing (damping has no energy).
void DistanceDamping(const Vec2& p_i, const Vec2& p_j, const Vec2& v_i, const Vec2& v_j,
                     double rest_length, double k_damping, Vec2& f_i, Vec2& f_j);

/// Area spring of triangle (a, b, c) with SIGNED area A = 1/2 cross(b-a, c-a):
///   E_A = 1/2 k_A ((A - A0) / A0)^2,
/// so an inverted triangle (A < 0) is pushed back to positive orientation.
double AreaEnergy(const Vec2& a, const Vec2& b, const Vec2& c, double rest_area, double k_area,
                  Vec2& f_a, Vec2& f_b, Vec2& f_c);

/// Angle spring at the corner p between the edge to `next` and the edge to
/// `prev`: phi = atan2(cross(e1, e2), dot(e1, e2)), e1 = next - p,
/// e2 = prev - p (the signed angle from e1 to e2), and
///   E_phi = 1/2 k_phi (phi - phi0)^2,
/// with phi - phi0 taken in (-pi, pi] so an inverted corner recovers its
/// orientation along the shorter way. rest_cos / rest_sin are cos and sin of
/// phi0 (precomputed by the model). A corner with a zero-length edge has no
/// defined angle: no force, zero energy.
double AngleEnergy(const Vec2& prev, const Vec2& p, const Vec2& next, double rest_cos,
                   double rest_sin, double k_angle, Vec2& f_prev, Vec2& f_p, Vec2& f_next);

/// All three angle springs of triangle (a, b, c) at once, the same energy
/// and forces as three AngleEnergy calls (corner a: prev c, next b; b: prev a,
/// next c; c: prev b, next a) for half the cost: the signed corner angles of
/// a triangle sum to +pi or -pi, so the third deviation is minus the sum of
/// the other two (wrapped), and so is its gradient. rest_cos_sin holds cos
/// and sin of the rest angles at a, b, c, which must sum to pi.
double TriangleAngleEnergy(const Vec2& a, const Vec2& b, const Vec2& c,
                           const std::array<double, 6>& rest_cos_sin, double k_angle, Vec2& f_a,
                           Vec2& f_b, Vec2& f_c);


// ---- definitions (inline: the model's loops must inline them) ----

namespace energy_terms_detail {


// atan2(y, x) to full double precision, fast for the common case of a small
// angle (x > 0, |y| <= x / 10: a spring near its rest angle): the series
// z - z^3/3 + ... + z^15/15 of atan(z), z = y/x, whose first omitted term is
// below |z|^17 / 17 < 6e-19. Other angles go to std::atan2.
//
// The series and its range test are separate so that the model's vectorised
// loops can evaluate the series on every lane and send only the lanes out of
// range to std::atan2; Atan2 is the one definition of how they combine.
//
// The coefficients are constexpr: the project compiles with -frounding-math,
// under which GCC leaves an inexact constant quotient such as 1.0 / 13.0 as a
// division at run time (seven per call). Folded at compile time they take
// the values the run-time divisions give in the default rounding mode.
inline bool Atan2SeriesApplies(double y, double x) { return (x > 0.0) & (std::abs(y) <= 0.1 * x); }

inline double Atan2Series(double y, double x) {
  constexpr double k3 = 1.0 / 3.0, k5 = 1.0 / 5.0, k7 = 1.0 / 7.0, k9 = 1.0 / 9.0;
  constexpr double k11 = 1.0 / 11.0, k13 = 1.0 / 13.0, k15 = 1.0 / 15.0;
  const double z = y / x;
  const double z2 = z * z;
  double s = -k15;
  s = s * z2 + k13;
  s = s * z2 - k11;
  s = s * z2 + k9;
  s = s * z2 - k7;
  s = s * z2 + k5;
  s = s * z2 - k3;
  s = s * z2 + 1.0;
  return z * s;
}

inline double Atan2(double y, double x) {
  return Atan2SeriesApplies(y, x) ? Atan2Series(y, x) : std::atan2(y, x);
}

// The signed angle from e1 rotated by the rest angle (cos, sin) to e2, in
// (-pi, pi]: phi - phi0 of the corner spanned by e1 and e2.
inline double AngleDeviation(const Vec2& e1, const Vec2& e2, double rest_cos, double rest_sin) {
  const Vec2 r1(rest_cos * e1.x() - rest_sin * e1.y(), rest_sin * e1.x() + rest_cos * e1.y());
  return Atan2(Cross(r1, e2), r1.dot(e2));
}

// Wraps an angle in (-3pi, 3pi) into (-pi, pi].
inline double Wrap(double angle) {
  constexpr double kPi = 3.141592653589793238462643383279502884;
  if (angle > kPi) return angle - 2.0 * kPi;
  if (angle <= -kPi) return angle + 2.0 * kPi;
  return angle;
}

}  // namespace energy_terms_detail

inline double DistanceEnergy(const Vec2& p_i, const Vec2& p_j, double rest_length, double k_distance,
                      Vec2& f_i, Vec2& f_j) {
  const Vec2 d = p_j - p_i;
  const double length = d.norm();
  const double strain = (length - rest_length) / rest_length;
  if (length > 0.0) {
    // dE/dp_j = k_D strain / D0 * u
    const Vec2 f = (-k_distance * strain / (rest_length * length)) * d;
    f_j += f;
    f_i -= f;
  }
  return 0.5 * k_distance * strain * strain;
}

inline void DistanceDamping(const Vec2& p_i, const Vec2& p_j, const Vec2& v_i, const Vec2& v_j,
                     double rest_length, double k_damping, Vec2& f_i, Vec2& f_j) {
  const Vec2 d = p_j - p_i;
  const double length_sq = d.squaredNorm();
  if (length_sq <= 0.0) return;
  // ((v_i - v_j) . u) u = ((v_i - v_j) . d) d / |d|^2
  const Vec2 f = (-k_damping / (rest_length * rest_length) * (v_i - v_j).dot(d) / length_sq) * d;
  f_i += f;
  f_j -= f;
}

inline double AreaEnergy(const Vec2& a, const Vec2& b, const Vec2& c, double rest_area, double k_area,
                  Vec2& f_a, Vec2& f_b, Vec2& f_c) {
  const double area = 0.5 * Cross(b - a, c - a);
  const double rel = (area - rest_area) / rest_area;
  // dA/dp_k = 1/2 perp(p_{k+1} - p_{k+2}) with perp(x, y) = (y, -x).
  const double s = -k_area * rel / rest_area * 0.5;
  f_a += s * Vec2(b.y() - c.y(), c.x() - b.x());
  f_b += s * Vec2(c.y() - a.y(), a.x() - c.x());
  f_c += s * Vec2(a.y() - b.y(), b.x() - a.x());
  return 0.5 * k_area * rel * rel;
}

inline double AngleEnergy(const Vec2& prev, const Vec2& p, const Vec2& next, double rest_cos,
                   double rest_sin, double k_angle, Vec2& f_prev, Vec2& f_p, Vec2& f_next) {
  const Vec2 e1 = next - p;
  const Vec2 e2 = prev - p;
  const double l1_sq = e1.squaredNorm();
  const double l2_sq = e2.squaredNorm();
  if (l1_sq <= 0.0 || l2_sq <= 0.0) return 0.0;
  // phi - phi0 is the signed angle from e1 rotated by phi0 to e2: one atan2 of
  // a small angle, already wrapped to (-pi, pi].
  const double delta = energy_terms_detail::AngleDeviation(e1, e2, rest_cos, rest_sin);
  // d phi / d e2 = perp_ccw(e2) / |e2|^2, d phi / d e1 = -perp_ccw(e1) / |e1|^2,
  // perp_ccw(x, y) = (-y, x).
  const double s = -k_angle * delta;
  const Vec2 g_next = Vec2(e1.y(), -e1.x()) / l1_sq;
  const Vec2 g_prev = Vec2(-e2.y(), e2.x()) / l2_sq;
  f_next += s * g_next;
  f_prev += s * g_prev;
  f_p -= s * (g_next + g_prev);
  return 0.5 * k_angle * delta * delta;
}

inline double TriangleAngleEnergy(const Vec2& a, const Vec2& b, const Vec2& c,
                                  const std::array<double, 6>& rest_cos_sin, double k_angle,
                                  Vec2& f_a, Vec2& f_b, Vec2& f_c) {
  using energy_terms_detail::Atan2;
  using energy_terms_detail::Wrap;
  // Edge vectors ab = b - a, bc = c - b, ca = a - c, written on scalars so
  // the hot loop stays small.
  const double abx = b.x() - a.x(), aby = b.y() - a.y();
  const double bcx = c.x() - b.x(), bcy = c.y() - b.y();
  const double cax = a.x() - c.x(), cay = a.y() - c.y();
  const double l_ab = abx * abx + aby * aby;
  const double l_bc = bcx * bcx + bcy * bcy;
  const double l_ca = cax * cax + cay * cay;
  if (l_ab <= 0.0 || l_bc <= 0.0 || l_ca <= 0.0) return 0.0;
  // Corner a spans e1 = ab, e2 = -ca; corner b spans e1 = bc, e2 = -ab. The
  // deviation from rest is the angle from R(phi0) e1 to e2.
  const double ca0 = rest_cos_sin[0], sa0 = rest_cos_sin[1];
  const double cb0 = rest_cos_sin[2], sb0 = rest_cos_sin[3];
  const double rax = ca0 * abx - sa0 * aby, ray = sa0 * abx + ca0 * aby;
  const double rbx = cb0 * bcx - sb0 * bcy, rby = sb0 * bcx + cb0 * bcy;
  const double d_a = Atan2(-(rax * cay - ray * cax), -(rax * cax + ray * cay));
  const double d_b = Atan2(-(rbx * aby - rby * abx), -(rbx * abx + rby * aby));
  const double d_c = Wrap(-(d_a + d_b));
  // Gradients of the corner angles: d phi_a / db = P_ab, d phi_a / dc = P_ca,
  // d phi_b / dc = P_bc, d phi_b / da = P_ab, with P_xy = perp_cw(xy) / |xy|^2
  // (perp_cw(x, y) = (y, -x)), and grad phi_c = -(grad phi_a + grad phi_b).
  const double i_ab = 1.0 / l_ab, i_bc = 1.0 / l_bc, i_ca = 1.0 / l_ca;
  const double pabx = aby * i_ab, paby = -abx * i_ab;
  const double pbcx = bcy * i_bc, pbcy = -bcx * i_bc;
  const double pcax = cay * i_ca, pcay = -cax * i_ca;
  const double w_a = -k_angle * (d_a - d_c);
  const double w_b = -k_angle * (d_b - d_c);
  const double w_ab = w_b - w_a;
  f_a.x() += w_ab * pabx - w_a * pcax;
  f_a.y() += w_ab * paby - w_a * pcay;
  f_b.x() += -w_ab * pabx - w_b * pbcx;
  f_b.y() += -w_ab * paby - w_b * pbcy;
  f_c.x() += w_a * pcax + w_b * pbcx;
  f_c.y() += w_a * pcay + w_b * pbcy;
  return 0.5 * k_angle * (d_a * d_a + d_b * d_b + d_c * d_c);
}

}  // namespace calib
