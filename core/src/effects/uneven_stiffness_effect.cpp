// uneven_stiffness: a stiffness field over the rest shape.
//
// A real sponge is rarely uniform (density, cuts, glue, a worn side). The
// effect makes k_D, k_A and k_phi vary linearly across the rest shape: an
// element (edge or triangle) whose rest centre c lies at signed distance
// s = (c - C) . u from the rest centroid C along the direction
// u = (cos a, sin a), a = uneven_angle_deg in image axes, has its
// stiffnesses multiplied by
//   1 + g s / R,   R = max over rest nodes |(p - C) . u|,
// g = uneven_gradient in [0, 1): from 1 - g on the side opposite u (softer)
// to 1 + g on the side u points to (stiffer).
//
// The base model's arrays stay as they are: the effect adds (factor - 1)
// times each base term, so the sum is the base term with the element's
// stiffness (damping is not scaled). It computes them with the base model's
// vectorised kernels on its own copy of the mesh's arrays, each element's
// stiffnesses scaled by its factor - 1 (Model::ComputeScaledForces), and
// adds each node's sum to the forces. The added stiffness is elastic about the rest
// shape (rest_stiffness): the implicit step holds it in its matrix, so a
// stiff side is as stable as the base model.

#include <cmath>
#include <numbers>
#include <optional>

#include "calib/core/effects.h"
#include "calib/core/model.h"
#include "effect_factories.h"

namespace calib::effects {
namespace {

class UnevenStiffnessEffect final : public EffectTerm {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo kInfo = {
        "uneven_stiffness",
        "a linear stiffness field over the rest shape multiplying k_D, k_A and k_phi per element",
        {
            {"uneven_gradient", "1",
             "uneven_stiffness: stiffness factors range from 1 - g to 1 + g across the rest shape",
             0.0, 0.95, false,
             [](const SearchScales&) { return SearchBox::Linear(0.0, 0.9); }, nullptr},
            {"uneven_angle_deg", "deg",
             "uneven_stiffness: direction in which stiffness grows (0: +x right, 90: +y down)",
             -180.0, 180.0, false,
             [](const SearchScales&) { return SearchBox::Linear(-180.0, 180.0); },
             [](const SearchBox&) { return 0.0; }},  // irrelevant at gradient 0
        },
        true};
    return kInfo;
  }
  EffectHooks hooks() const override { return {.forces = true, .rest_stiffness = true}; }

  void Bind(const Mesh& mesh) override {
    mesh_ = &mesh;
    const int num_nodes = mesh.NumNodes();
    centroid_ = Vec2::Zero();
    for (const Vec2& p : mesh.rest_positions) centroid_ += p;
    if (num_nodes > 0) centroid_ /= num_nodes;
    edge_centre_.resize(mesh.NumEdges());
    for (int e = 0; e < mesh.NumEdges(); ++e) {
      const auto [i, j] = mesh.edges[e];
      edge_centre_[e] = 0.5 * (mesh.rest_positions[i] + mesh.rest_positions[j]);
    }
    triangle_centre_.resize(mesh.NumTriangles());
    for (int t = 0; t < mesh.NumTriangles(); ++t) {
      const auto [a, b, c] = mesh.triangles[t];
      triangle_centre_[t] =
          (mesh.rest_positions[a] + mesh.rest_positions[b] + mesh.rest_positions[c]) / 3.0;
    }
    edge_extra_.resize(mesh.NumEdges());
    triangle_extra_.resize(mesh.NumTriangles());
    field_.emplace(mesh);
    workspace_ = field_->MakeWorkspace();
    field_forces_.assign(mesh.NumNodes(), Vec2::Zero());
  }

  void Configure(const ParameterValues& values, const ModelParameters& base) override {
    gradient_ = values.at("uneven_gradient");
    const double angle = values.at("uneven_angle_deg") * (std::numbers::pi / 180.0);
    base_ = base;
    const Vec2 u(std::cos(angle), std::sin(angle));
    double reach = 0.0;
    for (const Vec2& p : mesh_->rest_positions)
      reach = std::max(reach, std::abs((p - centroid_).dot(u)));
    const double scale = reach > 0.0 ? gradient_ / reach : 0.0;
    for (size_t e = 0; e < edge_extra_.size(); ++e) {
      edge_extra_[e] = scale * (edge_centre_[e] - centroid_).dot(u);
    }
    for (size_t t = 0; t < triangle_extra_.size(); ++t) {
      triangle_extra_[t] = scale * (triangle_centre_[t] - centroid_).dot(u);
    }
  }

  void AddForces(std::span<const Vec2> x, std::span<const Vec2>, std::span<Vec2> forces,
                 double* energy) const override {
    if (gradient_ == 0.0) return;
    const double sum = field_->ComputeScaledForces(base_, edge_extra_, triangle_extra_, x,
                                                   field_forces_, workspace_);
    for (size_t i = 0; i < forces.size(); ++i) forces[i] += field_forces_[i];
    if (energy != nullptr) *energy += sum;
  }

 private:
  const Mesh* mesh_ = nullptr;
  Vec2 centroid_ = Vec2::Zero();
  std::vector<Vec2> edge_centre_, triangle_centre_;
  double gradient_ = 0.0;
  ModelParameters base_;
  std::vector<double> edge_extra_, triangle_extra_;  ///< factor - 1 per element
  // The mesh's arrays for the base kernels, their scratch and the field's
  // forces per node (AddForces is called on one thread, effects.h).
  std::optional<Model> field_;
  mutable ForceWorkspace workspace_;
  mutable std::vector<Vec2> field_forces_;
};

}  // namespace

std::unique_ptr<EffectTerm> MakeUnevenStiffnessEffect() {
  return std::make_unique<UnevenStiffnessEffect>();
}

}  // namespace calib::effects
