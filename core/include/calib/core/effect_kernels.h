#pragma once
// Kernels of the effect terms (effects.h), beside the base terms of
// energy_terms.h: pure functions of a few node positions that return an
// energy and ADD its exact negative gradient to the force slots, or pure
// rules for the effects without an energy (friction, the push's balance).
// tests/core/effect_kernels_test.cpp checks the forces against central
// differences of the energies.
//
// Units: positions in pixels, forces in the calibration's force unit,
// stiffnesses in force x pixels (as the base terms).

#include <algorithm>
#include <array>
#include <cmath>

#include "calib/core/effects.h"
#include "calib/core/energy_terms.h"

namespace calib {

/// A constant body force g_force (= m g, force units) on node p:
///   E = -g_force . p,  force g_force.
inline double BodyForceEnergy(const Vec2& p, const Vec2& g_force, Vec2& f) {
  f += g_force;
  return -g_force.dot(p);
}

/// Strain stiffening of the distance spring i-j: a quartic term on the
/// same strain as E_D,
///   E_3 = 1/4 k_3 ((|p_j - p_i| - D0) / D0)^4,
/// so the spring's force grows as strain + (k_3 / k_D) strain^3: the same
/// at small strain, stiffer at large strain (stretch or compression). A
/// zero-length spring has no direction: no force, energy 1/4 k_3.
inline double QuarticDistanceEnergy(const Vec2& p_i, const Vec2& p_j, double rest_length,
                                    double k_3, Vec2& f_i, Vec2& f_j) {
  const Vec2 d = p_j - p_i;
  const double length = d.norm();
  const double strain = (length - rest_length) / rest_length;
  const double strain3 = strain * strain * strain;
  if (length > 0.0) {
    // dE/dp_j = k_3 strain^3 / D0 * u
    const Vec2 f = (-k_3 * strain3 / (rest_length * length)) * d;
    f_j += f;
    f_i -= f;
  }
  return 0.25 * k_3 * strain3 * strain;
}

/// The change of a distance spring's energy when its rest length moves from
/// `rest_from` to `rest_to` (both > 0):
///   E = 1/2 k ((L - rest_to) / rest_to)^2 - 1/2 k ((L - rest_from) / rest_from)^2,
/// L = |p_j - p_i|. Added to the base spring (rest D0 = rest_from, stiffness
/// k_D = k) it makes a spring of rest length rest_to: the plastic and
/// viscoelastic effects shift rest lengths this way without touching the
/// base model's arrays. Zero force when rest_to == rest_from.
inline double DistanceRestShiftEnergy(const Vec2& p_i, const Vec2& p_j, double rest_from,
                                      double rest_to, double k, Vec2& f_i, Vec2& f_j) {
  const Vec2 d = p_j - p_i;
  const double length = d.norm();
  const double strain_to = (length - rest_to) / rest_to;
  const double strain_from = (length - rest_from) / rest_from;
  if (length > 0.0) {
    // dE/dL = k (strain_to / rest_to - strain_from / rest_from)
    const double dE_dL = k * (strain_to / rest_to - strain_from / rest_from);
    const Vec2 f = (-dE_dL / length) * d;
    f_j += f;
    f_i -= f;
  }
  return 0.5 * k * (strain_to * strain_to - strain_from * strain_from);
}

/// The signed deviations phi_k - phi0_k of the three corners of triangle
/// (a, b, c) from the rest angles whose cos and sin are rest_cos_sin (as
/// TriangleAngleEnergy: they must sum to pi), each in (-pi, pi]. False (and
/// deviations 0) for a triangle with a zero-length edge.
inline bool TriangleAngleDeviations(const Vec2& a, const Vec2& b, const Vec2& c,
                                    const std::array<double, 6>& rest_cos_sin,
                                    std::array<double, 3>& deviation) {
  using energy_terms_detail::AngleDeviation;
  using energy_terms_detail::Wrap;
  deviation = {0.0, 0.0, 0.0};
  const Vec2 ab = b - a, bc = c - b, ca = a - c;
  if (ab.squaredNorm() <= 0.0 || bc.squaredNorm() <= 0.0 || ca.squaredNorm() <= 0.0) return false;
  // Corner a spans e1 = ab, e2 = -ca; corner b spans e1 = bc, e2 = -ab.
  deviation[0] = AngleDeviation(ab, -ca, rest_cos_sin[0], rest_cos_sin[1]);
  deviation[1] = AngleDeviation(bc, -ab, rest_cos_sin[2], rest_cos_sin[3]);
  deviation[2] = Wrap(-(deviation[0] + deviation[1]));
  return true;
}

/// Coulomb friction on one node's step, exactly implicit: the node moved
/// from `start` to `x` in a substep; friction takes `max_slip_px` (its
/// limit's share of the step: h F_c / m first order, h^2 F_c / m second
/// order) off the length of the step, and holds the node where the step is
/// shorter (sticking). Returns the length taken off. The step's direction
/// never turns, so friction only removes motion.
inline double CoulombLimitStep(const Vec2& start, Vec2& x, double max_slip_px) {
  const Vec2 step = x - start;
  const double length = step.norm();
  if (length <= max_slip_px) {
    x = start;
    return length;
  }
  x = start + (1.0 - max_slip_px / length) * step;
  return max_slip_px;
}

/// The push as a rigid-body force balance against table friction (the
/// push_relaxation effect): the contact node gets (1 - tau) P as in the base
/// model; the table holds the body with a reaction opposite to P of up to
/// `friction_force` (spread evenly, as friction acts on every node), so the
/// whole body takes tau P - min(|P|, F_c) P/|P| spread evenly, and the net
/// external force is max(0, |P| - F_c) along P: the body slides only while
/// the push exceeds friction. friction_force = 0 is the base model.
inline PushSplit FrictionBalancedPush(const Vec2& push, double translation, double friction_force) {
  PushSplit split;
  split.node_force = (1.0 - translation) * push;
  split.spread_total = translation * push;
  const double magnitude = push.norm();
  if (magnitude > 0.0 && friction_force > 0.0) {
    split.spread_total -= (std::min(magnitude, friction_force) / magnitude) * push;
  }
  return split;
}

}  // namespace calib
