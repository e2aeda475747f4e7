// table_friction: Coulomb friction between the nodes and the table.
//
// The body's weight rests evenly on its nodes, so each node can be held by
// a friction force of up to F_c / N, F_c = friction_force the Coulomb limit
// of the whole body (mu times its weight) in the force unit of the push
// sensor, which makes it comparable to the measured push and independent of
// the mesh resolution.
//
// Friction is applied exactly implicitly, on the step rather than as a
// force, so that it can hold a node still (sticking) and never reverses its
// motion: after the integrator moved a node from x_start to x, the step is
// shortened by h F_c / (N m) in the first-order model (where the step is
// h F / m, this is the force F reduced by F_c / N along itself, or zero when
// |F| <= F_c / N: Coulomb's law for an overdamped node) and by
// h^2 F_c / (N m) in the second-order model (the velocity reduced by the
// impulse h F_c / (N m), or zero). No regularisation is needed, and a
// viscous drag is left out: in the first-order model it is the same as a
// larger m, and with inertia it is inertia_damping_per_s.

#include "calib/core/effect_kernels.h"
#include "effect_factories.h"

namespace calib::effects {
namespace {

class TableFrictionEffect final : public EffectTerm {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo kInfo = {
        "table_friction",
        "Coulomb friction of the table on every node (stick and slip), implicit on the step",
        {
            {"friction_force", "force",
             "table_friction: Coulomb limit of the whole body (mu x weight), shared evenly by "
             "the nodes",
             0.0, kUnbounded, false,
             [](const SearchScales& s) {
               // Friction competes with the model's drag, not with the sensor's
               // reading: on the bundled pushes 2 x the peak reading (~3) holds a
               // node back by 1e-4 px a substep where the finger moves it 0.1 px.
               const double force = SearchScales::Positive(s.peak_force, 1.0);
               const double drag = SearchScales::Positive(s.drag_force, force);
               return SearchBox::Log(1e-3 * drag, 2.0 * drag);
             }, nullptr},
        },
        false};
    return kInfo;
  }
  EffectHooks hooks() const override { return {.step_limit = true}; }

  void Bind(const Mesh& mesh) override { num_nodes_ = mesh.NumNodes(); }

  void Configure(const ParameterValues& values, const ModelParameters&) override {
    friction_force_ = values.at("friction_force");
  }

  void LimitStep(std::span<const Vec2> x_start, std::span<const double> inverse_weight,
                 std::span<Vec2> x, const StepInfo& step) const override {
    if (!(friction_force_ > 0.0) || num_nodes_ == 0) return;
    const double per_node = friction_force_ / num_nodes_;
    const double max_slip =
        (step.second_order ? step.h_s * step.h_s : step.h_s) * per_node / step.mass;
    for (size_t i = 0; i < x.size(); ++i) {
      if (inverse_weight[i] == 0.0) continue;
      CoulombLimitStep(x_start[i], x[i], max_slip);
    }
  }

 private:
  int num_nodes_ = 0;
  double friction_force_ = 0.0;
};

}  // namespace

std::unique_ptr<EffectTerm> MakeTableFrictionEffect() {
  return std::make_unique<TableFrictionEffect>();
}

}  // namespace calib::effects
