#pragma once
// Time integrators for one substep of length h.

#include "calib/core/types.h"

#include <span>
#include <string>

namespace calib {

enum class IntegratorKind {
  kFirstOrder,  ///< paper eq. 10: x <- x + h F / m (velocity proportional to force)
  kVerlet,      ///< paper eq. 8: x <- 2x - x_prev + h^2 F / m (inertia)
  /// Eq. 10 implicit in the springs and the edge damping (ImplicitFirstOrderStep):
  /// (m / h + K0 + k_d / h D0) dx = F; stable at any stiffness.
  kImplicitFirstOrder,
};

std::string ToString(IntegratorKind kind);
/// Parses "first_order", "verlet" or "implicit_first_order"; throws std::invalid_argument naming the value.
IntegratorKind IntegratorKindFromString(const std::string& name);
/// Every integrator's name, as messages list them ("a, b or c").
std::string IntegratorKindNames();

/// First order: x += (h / m) f for nodes with inverse_weight 1 (clamped: 0).
void StepFirstOrder(double h_over_m, std::span<const Vec2> f, std::span<const double> inverse_weight,
                    std::span<Vec2> x);

/// Position Verlet: x_next = 2x - x_prev + (h^2 / m) f, then x_prev <- x and
/// x <- x_next, for nodes with nonzero inverse_weight.
void StepVerlet(double h2_over_m, std::span<const Vec2> f, std::span<const double> inverse_weight,
                std::span<Vec2> x, std::span<Vec2> x_prev);

}  // namespace calib
