#include "calib/core/integrator.h"

#include "calib/core/enum_names.h"

namespace calib {
namespace {

constexpr auto kIntegratorNames = std::to_array<EnumName<IntegratorKind>>({
    {IntegratorKind::kFirstOrder, "first_order"},
    {IntegratorKind::kVerlet, "verlet"},
    {IntegratorKind::kImplicitFirstOrder, "implicit_first_order"},
});

}  // namespace

std::string ToString(IntegratorKind kind) { return EnumToString(kIntegratorNames, kind); }

std::string IntegratorKindNames() { return EnumNameList(kIntegratorNames); }

IntegratorKind IntegratorKindFromString(const std::string& name) {
  return EnumFromString(kIntegratorNames, "integrator", name);
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
