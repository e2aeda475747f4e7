// push_relaxation: the push as a force balance against table friction, the
// better-founded replacement of the base model's translation share.
//
// The base model applies the measured push P on the node nearest the finger
// except the share tau spread evenly over all nodes. In the first-order
// model the body's centroid then moves at P / (N m) whatever tau is (the
// internal forces sum to zero), so as long as the sensor reads a force the
// body keeps translating, even when the finger has stopped and the real
// sponge is held by the table (the paper's Fig. 6, frame 300: the mesh keeps
// sliding after the finger stops).
//
// A sponge on a table moves as a whole only when the push overcomes the
// table's friction. This effect adds that force balance: the table holds the
// body with a reaction opposite to P of up to F_c = push_friction_force (the
// body's static friction, in the sensor's force unit), acting evenly on all
// nodes as friction does. The contact node still gets (1 - tau) P, so
//   spread = tau P - min(|P|, F_c) P / |P|,   net force = max(0, |P| - F_c) along P:
// while the finger pushes harder than friction the body slides; when the
// finger stops and the reading falls to the force that merely holds the dent
// (below F_c), the body stops and keeps the dent, balanced by friction.
// F_c = 0 is the base model exactly. (With inertia, table friction must act
// against the velocity, not the push: use table_friction there.)

#include "calib/core/effect_kernels.h"
#include "effect_factories.h"

namespace calib::effects {
namespace {

class PushRelaxationEffect final : public EffectTerm {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo kInfo = {
        "push_relaxation",
        "the push balanced by the table's friction on the whole body: the body translates only "
        "while the push exceeds friction (replaces tau's endless translation)",
        {
            {"push_friction_force", "force",
             "push_relaxation: static friction of the whole body against the push", 0.0, kUnbounded,
             false,
             [](const SearchScales& s) {
               const double force = SearchScales::Positive(s.peak_force, 1.0);
               return SearchBox::Log(1e-3 * force, 2.0 * force);
             }, nullptr},
        },
        false};
    return kInfo;
  }
  EffectHooks hooks() const override { return {.push = true}; }

  void Bind(const Mesh&) override {}

  void Configure(const ParameterValues& values, const ModelParameters&) override {
    friction_force_ = values.at("push_friction_force");
  }

  PushSplit SplitPush(const PushInfo& push) const override {
    return FrictionBalancedPush(push.push, push.translation, friction_force_);
  }

 private:
  double friction_force_ = 0.0;
};

}  // namespace

std::unique_ptr<EffectTerm> MakePushRelaxationEffect() {
  return std::make_unique<PushRelaxationEffect>();
}

}  // namespace calib::effects
