// plasticity: the rest shape drifts towards the current shape where the
// strain exceeds a yield, leaving a permanent set after the load.
//
// Each element keeps a plastic rest quantity, starting at the mesh's rest
// value: per edge a rest length D_p, per triangle a rest area A_p and three
// rest corner angles phi_p (summing to pi). After every substep, where the
// element's strain against its plastic rest exceeds the yield y =
// plastic_yield_strain (edges: (L - D_p) / D_p; triangles: (A - A_p) / A_p;
// corners: phi - phi_p in radians, a shear strain), the plastic rest flows
// towards the value that would leave exactly the yield strain, at the rate
// r = plastic_rate_per_s. The flow is integrated once per video frame, a
// share 1 - exp(-r dt) of the way over the frame time dt (exact for the
// frame's end state): plastic flow is slow beside a frame, and checking
// every element's strain once per frame instead of per substep keeps the
// effect cheap. Below the yield nothing flows: small loads are elastic,
// large ones leave a dent.
//
// The forces are those of the base springs with the plastic rest in place
// of the original one, as a term added to the base model (which keeps its
// arrays and its speed): per yielded element E(x; plastic rest) - E(x; rest)
// with the base stiffnesses, by the reference kernels (DistanceRestShiftEnergy,
// AreaEnergy, TriangleAngleEnergy). Elements that never yielded cost nothing.
// Plastic rest lengths and areas are kept within [0.1, 10] times the
// original; a corner whose plastic rest angle would leave [0.01, pi - 0.01]
// keeps its old one.

#include <cmath>
#include <numbers>

#include "calib/core/effect_kernels.h"
#include "effect_factories.h"

namespace calib::effects {
namespace {

constexpr double kMinAngle = 0.01;

class PlasticityEffect final : public EffectTerm {
 public:
  const EffectInfo& info() const override {
    static const EffectInfo kInfo = {
        "plasticity",
        "rest lengths, areas and angles flow towards the current ones where the strain exceeds "
        "a yield (a permanent set)",
        {
            {"plastic_yield_strain", "1",
             "plasticity: strain (edge, area; corner angle in rad) above which the rest shape "
             "flows",
             0.0, 0.9, true,
             [](const SearchScales&) { return SearchBox::Log(0.005, 0.5); },
             [](const SearchBox& box) {
               // Where the effect's strength is 0, it starts in the middle of its
               // (log) box, where the search can reach any value.
               return std::sqrt(box.lower * box.upper);
             }},
            {"plastic_rate_per_s", "1/s",
             "plasticity: rate at which the rest shape flows towards the yield surface", 0.0,
             kUnbounded, false,
             [](const SearchScales&) { return SearchBox::Log(0.05, 50.0); }, nullptr},
        },
        true};
    return kInfo;
  }
  EffectHooks hooks() const override { return {.forces = true, .after_frame = true}; }

  void Bind(const Mesh& mesh) override {
    mesh_ = &mesh;
    const size_t num_edges = mesh.NumEdges(), num_triangles = mesh.NumTriangles();
    rest_cos_sin_.resize(num_triangles);
    for (size_t t = 0; t < num_triangles; ++t) {
      for (int k = 0; k < 3; ++k) {
        rest_cos_sin_[t][2 * k] = std::cos(mesh.rest_angle_rad[t][k]);
        rest_cos_sin_[t][2 * k + 1] = std::sin(mesh.rest_angle_rad[t][k]);
      }
    }
    plastic_length_.resize(num_edges);
    plastic_area_.resize(num_triangles);
    plastic_angle_.resize(num_triangles);
    plastic_cos_sin_.resize(num_triangles);
    edge_active_.resize(num_edges);
    triangle_active_.resize(num_triangles);
    active_edges_.reserve(num_edges);
    active_triangles_.reserve(num_triangles);
    Reset();
  }

  void Configure(const ParameterValues& values, const ModelParameters& base) override {
    yield_ = values.at("plastic_yield_strain");
    rate_per_s_ = values.at("plastic_rate_per_s");
    tan_yield_ = std::tan(yield_);
    base_ = base;
  }

  void Reset() override {
    const Mesh& mesh = *mesh_;
    std::copy(mesh.rest_length_px.begin(), mesh.rest_length_px.end(), plastic_length_.begin());
    std::copy(mesh.rest_area_px2.begin(), mesh.rest_area_px2.end(), plastic_area_.begin());
    std::copy(mesh.rest_angle_rad.begin(), mesh.rest_angle_rad.end(), plastic_angle_.begin());
    std::copy(rest_cos_sin_.begin(), rest_cos_sin_.end(), plastic_cos_sin_.begin());
    std::fill(edge_active_.begin(), edge_active_.end(), 0);
    std::fill(triangle_active_.begin(), triangle_active_.end(), 0);
    active_edges_.clear();
    active_triangles_.clear();
  }

  void AddForces(std::span<const Vec2> x, std::span<const Vec2>, std::span<Vec2> forces,
                 double* energy) const override {
    const Mesh& mesh = *mesh_;
    double sum = 0.0;
    for (const int e : active_edges_) {
      const auto [i, j] = mesh.edges[e];
      sum += DistanceRestShiftEnergy(x[i], x[j], mesh.rest_length_px[e], plastic_length_[e],
                                     base_.k_distance, forces[i], forces[j]);
    }
    for (const int t : active_triangles_) {
      const auto [a, b, c] = mesh.triangles[t];
      Vec2 &fa = forces[a], &fb = forces[b], &fc = forces[c];
      sum += AreaEnergy(x[a], x[b], x[c], plastic_area_[t], base_.k_area, fa, fb, fc);
      sum += AreaEnergy(x[a], x[b], x[c], mesh.rest_area_px2[t], -base_.k_area, fa, fb, fc);
      sum += TriangleAngleEnergy(x[a], x[b], x[c], plastic_cos_sin_[t], base_.k_angle, fa, fb, fc);
      sum += TriangleAngleEnergy(x[a], x[b], x[c], rest_cos_sin_[t], -base_.k_angle, fa, fb, fc);
    }
    if (energy != nullptr) *energy += sum;
  }

  void AfterFrame(std::span<const Vec2> x, double frame_time_s) override {
    if (!(rate_per_s_ > 0.0)) return;
    const double alpha = -std::expm1(-rate_per_s_ * frame_time_s);
    const Mesh& mesh = *mesh_;
    // Cheap tests first (no square root, no arc tangent): most elements are
    // within the yield in most substeps.
    const double low = 1.0 - yield_, high = 1.0 + yield_;
    for (int e = 0; e < mesh.NumEdges(); ++e) {
      const auto [i, j] = mesh.edges[e];
      const double length_sq = (x[j] - x[i]).squaredNorm();
      const double rest = plastic_length_[e];
      if (length_sq <= (high * rest) * (high * rest) && length_sq >= (low * rest) * (low * rest)) {
        continue;
      }
      const double length = std::sqrt(length_sq);
      const double strain = (length - rest) / rest;
      if (std::abs(strain) <= yield_) continue;
      const double target = length / (1.0 + std::copysign(yield_, strain));
      const double original = mesh.rest_length_px[e];
      plastic_length_[e] =
          std::clamp(rest + alpha * (target - rest), 0.1 * original, 10.0 * original);
      MarkEdge(e);
    }
    for (int t = 0; t < mesh.NumTriangles(); ++t) {
      const auto [a, b, c] = mesh.triangles[t];
      bool changed = false;
      const double area = SignedArea(x[a], x[b], x[c]);
      const double rest = plastic_area_[t];
      const double strain = (area - rest) / rest;
      if (std::abs(strain) > yield_) {
        const double target = area / (1.0 + std::copysign(yield_, strain));
        const double original = mesh.rest_area_px2[t];
        plastic_area_[t] =
            std::clamp(rest + alpha * (target - rest), 0.1 * original, 10.0 * original);
        changed = true;
      }
      std::array<double, 3> deviation;
      if (AnyCornerBeyond(x[a], x[b], x[c], plastic_cos_sin_[t]) &&
          TriangleAngleDeviations(x[a], x[b], x[c], plastic_cos_sin_[t], deviation) &&
          (std::abs(deviation[0]) > yield_ || std::abs(deviation[1]) > yield_ ||
           std::abs(deviation[2]) > yield_)) {
        changed = FlowAngles(t, deviation, alpha) || changed;
      }
      if (changed) MarkTriangle(t);
    }
  }

 private:
  // Whether a corner of (a, b, c) may deviate from its rest angle by more
  // than the yield: the deviation d of a corner has tan d = cross / dot of
  // the rest-rotated first edge and the second edge, so |d| <= y exactly
  // when dot > 0 and |cross| <= tan(y) dot. Conservative at the boundary
  // (the exact test follows).
  bool AnyCornerBeyond(const Vec2& a, const Vec2& b, const Vec2& c,
                       const std::array<double, 6>& cs) const {
    const std::array<Vec2, 3> p = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      const Vec2 e1 = p[(k + 1) % 3] - p[k], e2 = p[(k + 2) % 3] - p[k];
      const Vec2 r1(cs[2 * k] * e1.x() - cs[2 * k + 1] * e1.y(),
                    cs[2 * k + 1] * e1.x() + cs[2 * k] * e1.y());
      const double dot = r1.dot(e2), cross = Cross(r1, e2);
      if (!(dot > 0.0) || std::abs(cross) >= 0.999 * tan_yield_ * dot) return true;
    }
    return false;
  }

  // Moves triangle t's plastic rest angles a share alpha towards the angles
  // that leave the yield deviation, then back onto the sum pi. False (and
  // nothing changed) where a corner would leave [kMinAngle, pi - kMinAngle].
  bool FlowAngles(int t, const std::array<double, 3>& deviation, double alpha) {
    std::array<double, 3> next;
    double sum = 0.0;
    for (int k = 0; k < 3; ++k) {
      const double excess = deviation[k] - std::clamp(deviation[k], -yield_, yield_);
      next[k] = plastic_angle_[t][k] + alpha * excess;
      sum += next[k];
    }
    const double correction = (sum - std::numbers::pi) / 3.0;
    for (double& angle : next) {
      angle -= correction;
      if (!(angle >= kMinAngle && angle <= std::numbers::pi - kMinAngle)) return false;
    }
    plastic_angle_[t] = next;
    for (int k = 0; k < 3; ++k) {
      plastic_cos_sin_[t][2 * k] = std::cos(next[k]);
      plastic_cos_sin_[t][2 * k + 1] = std::sin(next[k]);
    }
    return true;
  }

  void MarkEdge(int e) {
    if (edge_active_[e]) return;
    edge_active_[e] = 1;
    active_edges_.push_back(e);  // within the capacity reserved by Bind
  }
  void MarkTriangle(int t) {
    if (triangle_active_[t]) return;
    triangle_active_[t] = 1;
    active_triangles_.push_back(t);
  }

  const Mesh* mesh_ = nullptr;
  double yield_ = 0.1;
  double tan_yield_ = std::tan(0.1);
  double rate_per_s_ = 0.0;
  ModelParameters base_;
  std::vector<std::array<double, 6>> rest_cos_sin_;  ///< of the mesh's rest angles
  std::vector<double> plastic_length_, plastic_area_;
  std::vector<std::array<double, 3>> plastic_angle_;
  std::vector<std::array<double, 6>> plastic_cos_sin_;
  std::vector<uint8_t> edge_active_, triangle_active_;
  std::vector<int> active_edges_, active_triangles_;  ///< elements that ever yielded
};

}  // namespace

std::unique_ptr<EffectTerm> MakePlasticityEffect() { return std::make_unique<PlasticityEffect>(); }

}  // namespace calib::effects
