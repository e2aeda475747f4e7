// viscoelastic: a Maxwell branch on every distance spring (a standard linear
// solid), so the body relaxes under a held load and recovers slowly.
//
// The share s = visco_share of each distance spring's stiffness k_D sits in
// a Maxwell branch: a spring of stiffness s k_D whose rest length D_v flows
// towards the current length L with the time constant T = visco_time_s
// (the dashpot in series), dD_v/dt = (L - D_v) / T, integrated exactly over
// each substep: D_v += (1 - exp(-h / T)) (L - D_v). The equilibrium branch
// keeps (1 - s) k_D and the rest length D0. So a held dent loses the share
// s of its restoring force over a few T, and after release the body springs
// back part of the way at once and the rest over a few T.
//
// As a force term (DistanceRestShiftEnergy): s k_D (E(L; D_v) - E(L; D0)),
// added to the base spring k_D E(L; D0), gives (1 - s) k_D E(L; D0) +
// s k_D E(L; D_v). D_v is kept within [0.1, 10] D0.
//
// The force loop is DistanceRestShiftEnergy with the inverse rest lengths
// kept beside the rest lengths (1 / D_v updated with D_v), so an edge costs
// one square root and one division.

#include <algorithm>
#include <cmath>

#include "calib/core/effect_kernels.h"
#include "effect_factories.h"

namespace calib::effects {
namespace {

class ViscoelasticEffect final : public EffectTerm {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo kInfo = {
        "viscoelastic",
        "a relaxing (Maxwell) branch on every edge: rest lengths of a share of the stiffness "
        "flow towards the current lengths, so the body relaxes and recovers slowly",
        {
            {"visco_share", "1", "viscoelastic: share of k_D in the relaxing branch", 0.0, 0.95,
             false,
             [](const SearchScales&) { return SearchBox::Linear(0.0, 0.9); }, nullptr},
            {"visco_time_s", "s", "viscoelastic: relaxation time constant of the branch", 0.0,
             kUnbounded, true,
             [](const SearchScales& s) {
               const double fps = SearchScales::Positive(s.fps, 30.0);
               const double duration = SearchScales::Positive(s.duration_s, 1.0);
               return SearchBox::Log(1.0 / fps, std::max(2.0 * duration, 10.0 / fps));
             },
             [](const SearchBox& box) { return std::sqrt(box.lower * box.upper); }},  // irrelevant at share 0
        },
        true};
    return kInfo;
  }
  EffectHooks hooks() const override { return {.forces = true, .after_substep = true}; }

  void Bind(const Mesh& mesh) override {
    mesh_ = &mesh;
    inv_rest_.resize(mesh.NumEdges());
    for (int e = 0; e < mesh.NumEdges(); ++e) inv_rest_[e] = 1.0 / mesh.rest_length_px[e];
    branch_rest_.resize(mesh.NumEdges());
    inv_branch_rest_.resize(mesh.NumEdges());
    Reset();
  }

  void Configure(const ParameterValues& values, const ModelParameters& base) override {
    share_ = values.at("visco_share");
    time_s_ = values.at("visco_time_s");
    k_branch_ = share_ * base.k_distance;
  }

  void Reset() override {
    std::copy(mesh_->rest_length_px.begin(), mesh_->rest_length_px.end(), branch_rest_.begin());
    std::copy(inv_rest_.begin(), inv_rest_.end(), inv_branch_rest_.begin());
  }

  void AddForces(std::span<const Vec2> x, std::span<const Vec2>, std::span<Vec2> forces,
                 double* energy) const override {
    if (k_branch_ == 0.0) return;
    const Mesh& mesh = *mesh_;
    double sum = 0.0;
    for (int e = 0; e < mesh.NumEdges(); ++e) {
      const auto [i, j] = mesh.edges[e];
      const Vec2 d = x[j] - x[i];
      const double length = d.norm();
      const double strain_to = length * inv_branch_rest_[e] - 1.0;
      const double strain_from = length * inv_rest_[e] - 1.0;
      if (length > 0.0) {
        const double dE_dL =
            k_branch_ * (strain_to * inv_branch_rest_[e] - strain_from * inv_rest_[e]);
        const Vec2 f = (-dE_dL / length) * d;
        forces[j] += f;
        forces[i] -= f;
      }
      sum += strain_to * strain_to - strain_from * strain_from;
    }
    if (energy != nullptr) *energy += 0.5 * k_branch_ * sum;
  }

  void AfterSubstep(std::span<const Vec2> x, double h_s) override {
    if (k_branch_ == 0.0) return;
    const double alpha = -std::expm1(-h_s / time_s_);
    const Mesh& mesh = *mesh_;
    for (int e = 0; e < mesh.NumEdges(); ++e) {
      const auto [i, j] = mesh.edges[e];
      const double rest = mesh.rest_length_px[e];
      const double length = (x[j] - x[i]).norm();
      const double next = branch_rest_[e] + alpha * (length - branch_rest_[e]);
      branch_rest_[e] = std::clamp(next, 0.1 * rest, 10.0 * rest);
      inv_branch_rest_[e] = 1.0 / branch_rest_[e];
    }
  }

 private:
  const Mesh* mesh_ = nullptr;
  double share_ = 0.0;
  double time_s_ = 1.0;
  double k_branch_ = 0.0;
  std::vector<double> inv_rest_;                       ///< 1 / D0
  std::vector<double> branch_rest_, inv_branch_rest_;  ///< D_v, 1 / D_v
};

}  // namespace

std::unique_ptr<EffectTerm> MakeViscoelasticEffect() {
  return std::make_unique<ViscoelasticEffect>();
}

}  // namespace calib::effects
