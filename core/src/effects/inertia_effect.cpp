// inertia: second-order dynamics with a velocity damping, and gravity.
//
// The base model is first order (paper eq. 10): a node's velocity is
// proportional to the force on it, so it stops the moment the force does and
// never overshoots. A hanging strip that swings, or a sponge that slides on
// after a push, needs momentum. With this effect the simulator advances
//   x <- x + h v / (1 + h c) + h^2 F / m,   v = (x - x_prev) / h,
// semi-implicit Euler in position form (paper eq. 8 with the velocity taken
// after the constraints, so an obstacle that stops a node also takes its
// momentum) with the velocity decay c (inertia_damping_per_s, 1/s) treated
// implicitly, so any c >= 0 is stable. m becomes a mass (force s^2 / px).
//
// Gravity is an in-plane body force m g on every node, g of strength
// gravity_px_s2 (px / s^2) along the image direction gravity_angle_deg
// (0: +x, to the right; 90: +y, down the image): for a camera looking at a
// hanging object, gravity lies in the image plane; for a top view of a table
// the strength is 0 (or a tilt of the table). Its energy is -m g . x.

#include <algorithm>
#include <cmath>
#include <numbers>

#include "calib/core/effect_kernels.h"
#include "effect_factories.h"

namespace calib::effects {
namespace {

class InertiaEffect final : public EffectTerm {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo kInfo = {
        "inertia",
        "second-order dynamics (momentum) with a velocity damping, and gravity as an in-plane "
        "body force",
        {
            {"inertia_damping_per_s", "1/s",
             "inertia: velocity decay rate of the second-order step (air and table drag)", 0.0,
             kUnbounded, false,
             [](const SearchScales& s) { return SearchBox::Log(0.1, 2.0 * SearchScales::Positive(s.fps, 30.0)); },
             [](const SearchBox& box) { return box.upper; }},  // overdamped: closest to first order
            {"gravity_px_s2", "px/s^2", "inertia: strength of gravity in the image plane", 0.0,
             kUnbounded, false,
             [](const SearchScales& s) {
               // A clamped object filmed from the side hangs in the image
               // plane: where the recording gives its scale, gravity is
               // 9.81 m/s^2 in its pixels, not a fit (a fitted strength
               // trades against the springs: a swing's rate is theirs and
               // gravity's together).
               if (std::isfinite(s.hanging_angle_deg) && s.mm_per_px > 0.0) {
                 return SearchBox::Fixed(9810.0 / s.mm_per_px);
               }
               // 9.81 m/s^2 in pixels; an unknown scale is taken as 0.25 mm/px
               // (the box reaches twice that, so any scale down to 0.125 mm/px fits).
               return SearchBox::Linear(0.0, 2.0 * (9810.0 / SearchScales::Positive(s.mm_per_px, 0.25)));
             }, nullptr},
            {"gravity_angle_deg", "deg",
             "inertia: direction of gravity in the image (0: +x right, 90: +y down)", -180.0, 180.0,
             false,
             [](const SearchScales& s) {
               // A clamped object hangs the way gravity pulls: the
               // direction is the video's, not a fit's (one recording
               // cannot tell a tilted gravity from a stiffer spring).
               if (std::isfinite(s.hanging_angle_deg)) {
                 return SearchBox::Fixed(std::clamp(s.hanging_angle_deg, -180.0, 180.0));
               }
               return SearchBox::Linear(-180.0, 180.0);
             },
             [](const SearchBox&) { return 90.0; }},  // down the image (irrelevant at g = 0)
        },
        true};
    return kInfo;
  }
  EffectHooks hooks() const override { return {.forces = true, .dynamics = true}; }

  void Bind(const Mesh&) override {}

  void Configure(const ParameterValues& values, const ModelParameters& base) override {
    damping_per_s_ = values.at("inertia_damping_per_s");
    const double g = values.at("gravity_px_s2");
    const double angle = values.at("gravity_angle_deg") * (std::numbers::pi / 180.0);
    body_force_ = (base.mass * g) * Vec2(std::cos(angle), std::sin(angle));
  }

  void AddForces(std::span<const Vec2> x, std::span<const Vec2>, std::span<Vec2> forces,
                 double* energy) const override {
    if (energy != nullptr) {
      for (size_t i = 0; i < x.size(); ++i)
        *energy += BodyForceEnergy(x[i], body_force_, forces[i]);
      return;
    }
    for (Vec2& f : forces) f += body_force_;
  }

  Vec2 UniformNodeForce() const override { return body_force_; }

  std::optional<double> SecondOrderDamping() const override { return damping_per_s_; }

 private:
  double damping_per_s_ = 0.0;
  Vec2 body_force_ = Vec2::Zero();  ///< m g per node
};

}  // namespace

std::unique_ptr<EffectTerm> MakeInertiaEffect() { return std::make_unique<InertiaEffect>(); }

}  // namespace calib::effects
