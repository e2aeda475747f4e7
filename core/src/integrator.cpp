#include "calib/core/integrator.h"

#include <stdexcept>

namespace calib {

std::string ToString(IntegratorKind kind) {
  switch (kind) {
    case IntegratorKind::kFirstOrder: return "first_order";
    case IntegratorKind::kVerlet: return "verlet";
    case IntegratorKind::kImplicitFirstOrder: return "implicit_first_order";
  }
  return "unknown";
}

IntegratorKind IntegratorKindFromString(const std::string& name) {
  if (name == "first_order") return IntegratorKind::kFirstOrder;
  if (name == "verlet") return IntegratorKind::kVerlet;
  if (name == "implicit_first_order") return IntegratorKind::kImplicitFirstOrder;
  throw std::invalid_argument("integrator '" + name +
                              "' is unknown; expected first_order, verlet or implicit_first_order");
}

void StepFirstOrder(double h_over_m, std::span<const Vec2> f, std::span<const double> inverse_weight,
                    std::span<Vec2> x) {
  for (size_t i = 0; i < x.size(); ++i) x[i] += (h_over_m * inverse_weight[i]) * f[i];
}

void StepVerlet(double h2_over_m, std::span<const Vec2> f, std::span<const double> inverse_weight,
                std::span<Vec2> x, std::span<Vec2> x_prev) {
  for (size_t i = 0; i < x.size(); ++i) {
    if (inverse_weight[i] == 0.0) continue;
    const Vec2 next = 2.0 * x[i] - x_prev[i] + h2_over_m * f[i];
    x_prev[i] = x[i];
    x[i] = next;
  }
}

}  // namespace calib
