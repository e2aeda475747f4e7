// strain_stiffening: nonlinear distance springs that stiffen at large strain.
//
// Foams and rubbers get stiffer as they are stretched or crushed. Each
// distance spring gains a quartic term on its strain,
//   E_3 = 1/4 k_3 ((|p_j - p_i| - D0) / D0)^4   (QuarticDistanceEnergy),
// so its force is k_D strain + k_3 strain^3 (over D0): unchanged at small
// strain, stiffer at large strain. The force loop is the kernel with the
// inverse rest lengths precomputed (one square root, one division an edge).
// Its stiffness along an edge, 3 k_3 strain^2 / D0^2, is zero at rest and
// grows with the dent, so the implicit step takes it at the current shape
// once a frame (EffectHooks::shape_stiffness; refactorised where it moved).

#include "calib/core/effect_kernels.h"
#include "effect_factories.h"

namespace calib::effects {
namespace {

class StrainStiffeningEffect final : public EffectTerm {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo kInfo = {
        "strain_stiffening",
        "nonlinear distance springs: a quartic term 1/4 k_3 strain^4 on every edge",
        {
            {"stiffening_k3", "force*px",
             "strain_stiffening: coefficient of the quartic term on the edge strain", 0.0,
             kUnbounded, false,
             [](const SearchScales& s) {
               const double k_d = s.Reference("k_D", 100.0);
               return SearchBox::Log(1e-2 * k_d, 1e4 * k_d);
             }, nullptr},
        },
        true};
    return kInfo;
  }
  EffectHooks hooks() const override { return {.forces = true, .shape_stiffness = true}; }

  void Bind(const Mesh& mesh) override {
    mesh_ = &mesh;
    inv_rest_.resize(mesh.NumEdges());
    for (int e = 0; e < mesh.NumEdges(); ++e) inv_rest_[e] = 1.0 / mesh.rest_length_px[e];
  }

  void Configure(const ParameterValues& values, const ModelParameters&) override {
    k_3_ = values.at("stiffening_k3");
  }

  void AddForces(std::span<const Vec2> x, std::span<const Vec2>, std::span<Vec2> forces,
                 double* energy) const override {
    if (k_3_ == 0.0) return;
    double sum = 0.0;
    const int num_edges = mesh_->NumEdges();
    for (int e = 0; e < num_edges; ++e) {
      const auto [i, j] = mesh_->edges[e];
      const Vec2 d = x[j] - x[i];
      const double length = d.norm();
      const double strain = length * inv_rest_[e] - 1.0;
      const double strain2 = strain * strain;
      if (length > 0.0) {
        // dE/dp_j = k_3 strain^3 / D0 * u (QuarticDistanceEnergy)
        const Vec2 f = (-k_3_ * strain2 * strain * inv_rest_[e] / length) * d;
        forces[j] += f;
        forces[i] -= f;
      }
      sum += strain2 * strain2;
    }
    if (energy != nullptr) *energy += 0.25 * k_3_ * sum;
  }

  void AddShapeStiffness(std::span<const Vec2> x, EdgeStiffnessSink& sink) const override {
    if (k_3_ == 0.0) return;
    const int num_edges = mesh_->NumEdges();
    for (int e = 0; e < num_edges; ++e) {
      const auto [i, j] = mesh_->edges[e];
      const Vec2 d = x[j] - x[i];
      const double length = d.norm();
      if (!(length > 0.0)) continue;
      const double strain = length * inv_rest_[e] - 1.0;
      // d/dL of the force k_3 strain^3 / D0
      const double k = 3.0 * k_3_ * strain * strain * inv_rest_[e] * inv_rest_[e];
      if (k > 0.0) sink.AddEdgeStiffness(e, k, d / length);
    }
  }

 private:
  const Mesh* mesh_ = nullptr;
  double k_3_ = 0.0;
  std::vector<double> inv_rest_;  ///< 1 / D0 per edge
};

}  // namespace

std::unique_ptr<EffectTerm> MakeStrainStiffeningEffect() {
  return std::make_unique<StrainStiffeningEffect>();
}

}  // namespace calib::effects
