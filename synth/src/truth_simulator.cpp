#include "calib/synth/truth_simulator.h"

#include "truth_system.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <utility>

namespace calib::synth {
namespace {

using truth_detail::Element;
using truth_detail::StepTerms;
using truth_detail::System;

bool Fail(std::string* error, std::string message) {
  if (error != nullptr) *error = std::move(message);
  return false;
}

std::string Show(const Vec2& v) { return fmt::format("({}, {})", v.x(), v.y()); }

}  // namespace

// ---------------------------------------------------------------- validation

bool TruthMaterial::IsValid(std::string* error) const {
  const std::string m = "TruthMaterial::";
  auto positive = [&](const char* name, double value) {
    return std::isfinite(value) && value > 0.0
               ? true
               : Fail(error, fmt::format("{}{} = {}. Violated: finite and > 0.", m, name, value));
  };
  if (!positive("youngs_modulus_pa", youngs_modulus_pa)) return false;
  if (!(poisson_ratio >= 0.0 && poisson_ratio < 0.5)) {
    return Fail(error, fmt::format("{}poisson_ratio = {}. Violated: 0 <= poisson_ratio < 0.5.", m,
                                   poisson_ratio));
  }
  if (!positive("thickness_m", thickness_m)) return false;
  if (!positive("density_kg_m3", density_kg_m3)) return false;
  if (!(stiffness_gradient >= 0.0 && stiffness_gradient < 1.0)) {
    return Fail(error, fmt::format("{}stiffness_gradient = {}. Violated: 0 <= stiffness_gradient < 1.",
                                   m, stiffness_gradient));
  }
  if (!stiffness_gradient_direction.allFinite() || stiffness_gradient_direction.norm() == 0.0) {
    return Fail(error, fmt::format("{}stiffness_gradient_direction = {}. Violated: finite, non-zero.",
                                   m, Show(stiffness_gradient_direction)));
  }
  for (size_t k = 0; k < stiffness_regions.size(); ++k) {
    const StiffnessRegion& r = stiffness_regions[k];
    if (!r.centre_px.allFinite()) {
      return Fail(error, fmt::format("{}stiffness_regions[{}].centre_px = {}. Violated: finite.", m,
                                     k, Show(r.centre_px)));
    }
    if (!(std::isfinite(r.radius_px) && r.radius_px > 0.0)) {
      return Fail(error, fmt::format("{}stiffness_regions[{}].radius_px = {}. Violated: finite and > 0.",
                                     m, k, r.radius_px));
    }
    if (!(std::isfinite(r.factor) && r.factor > 0.0)) {
      return Fail(error, fmt::format("{}stiffness_regions[{}].factor = {}. Violated: finite and > 0.",
                                     m, k, r.factor));
    }
  }
  if (!(std::isfinite(stiffening_coefficient) && stiffening_coefficient >= 0.0)) {
    return Fail(error, fmt::format("{}stiffening_coefficient = {}. Violated: finite and >= 0.", m,
                                   stiffening_coefficient));
  }
  if (!(plastic_yield_strain > 0.0)) {  // +inf (off) allowed; NaN rejected
    return Fail(error, fmt::format("{}plastic_yield_strain = {}. Violated: > 0 (inf: off).", m,
                                   plastic_yield_strain));
  }
  if (!positive("plastic_flow_rate_per_s", plastic_flow_rate_per_s)) return false;
  if (!(viscous_fraction >= 0.0 && viscous_fraction < 1.0)) {
    return Fail(error, fmt::format("{}viscous_fraction = {}. Violated: 0 <= viscous_fraction < 1.",
                                   m, viscous_fraction));
  }
  if (!positive("viscous_relaxation_time_s", viscous_relaxation_time_s)) return false;
  return true;
}

bool TruthEnvironment::IsValid(std::string* error) const {
  const std::string m = "TruthEnvironment::";
  if (!(std::isfinite(friction_coefficient) && friction_coefficient >= 0.0)) {
    return Fail(error, fmt::format("{}friction_coefficient = {}. Violated: finite and >= 0.", m,
                                   friction_coefficient));
  }
  if (!(std::isfinite(friction_regularisation_m_s) && friction_regularisation_m_s > 0.0)) {
    return Fail(error, fmt::format("{}friction_regularisation_m_s = {}. Violated: finite and > 0.",
                                   m, friction_regularisation_m_s));
  }
  if (!(std::isfinite(contact_friction_coefficient) && contact_friction_coefficient >= 0.0)) {
    return Fail(error, fmt::format("{}contact_friction_coefficient = {}. Violated: finite and >= 0.",
                                   m, contact_friction_coefficient));
  }
  if (!gravity_m_s2.allFinite()) {
    return Fail(error, fmt::format("{}gravity_m_s2 = {}. Violated: finite.", m, Show(gravity_m_s2)));
  }
  if (!initial_bend_m_s2.allFinite()) {
    return Fail(error, fmt::format("{}initial_bend_m_s2 = {}. Violated: finite.", m,
                                   Show(initial_bend_m_s2)));
  }
  return true;
}

bool TruthScene::IsValid(std::string* error) const {
  const std::string m = "TruthScene::";
  const Mesh& mesh = rest_mesh;
  if (mesh.NumNodes() < 3 || mesh.NumTriangles() < 1) {
    return Fail(error, fmt::format("{}rest_mesh has {} nodes and {} triangles. Violated: >= 3 nodes "
                                   "and >= 1 triangle.", m, mesh.NumNodes(), mesh.NumTriangles()));
  }
  if (static_cast<int>(mesh.rest_area_px2.size()) != mesh.NumTriangles()) {
    return Fail(error, fmt::format("{}rest_mesh.rest_area_px2 has {} entries. Violated: one per "
                                   "triangle ({}); build meshes with BuildMesh.", m,
                                   mesh.rest_area_px2.size(), mesh.NumTriangles()));
  }
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    if (!mesh.rest_positions[i].allFinite()) {
      return Fail(error, fmt::format("{}rest_mesh.rest_positions[{}] = {}. Violated: finite.", m, i,
                                     Show(mesh.rest_positions[i])));
    }
  }
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto& tri = mesh.triangles[t];
    for (int a = 0; a < 3; ++a) {
      if (tri[a] < 0 || tri[a] >= mesh.NumNodes()) {
        return Fail(error, fmt::format("{}rest_mesh.triangles[{}] has node {}. Violated: 0 <= node < {}.",
                                       m, t, tri[a], mesh.NumNodes()));
      }
    }
    const double area = SignedArea(mesh.rest_positions[tri[0]], mesh.rest_positions[tri[1]],
                                   mesh.rest_positions[tri[2]]);
    if (!(area > 0.0)) {
      return Fail(error, fmt::format("{}rest_mesh.triangles[{}] has signed area {} px^2. Violated: > 0.",
                                     m, t, area));
    }
  }
  if (!(std::isfinite(mm_per_px) && mm_per_px > 0.0)) {
    return Fail(error, fmt::format("{}mm_per_px = {}. Violated: finite and > 0.", m, mm_per_px));
  }
  if (!(std::isfinite(fps) && fps > 0.0)) {
    return Fail(error, fmt::format("{}fps = {}. Violated: finite and > 0.", m, fps));
  }
  if (num_frames < 1) {
    return Fail(error, fmt::format("{}num_frames = {}. Violated: num_frames >= 1.", m, num_frames));
  }
  if (substeps < 1) {
    return Fail(error, fmt::format("{}substeps = {}. Violated: substeps >= 1.", m, substeps));
  }
  if (static_cast<int>(obstacles.size()) != num_frames) {
    return Fail(error, fmt::format("{}obstacles has {} frames. Violated: one list per frame ({}).", m,
                                   obstacles.size(), num_frames));
  }
  const size_t count = obstacles.front().size();
  for (size_t f = 0; f < obstacles.size(); ++f) {
    if (obstacles[f].size() != count) {
      return Fail(error, fmt::format("{}obstacles[{}] has {} discs. Violated: the same number every "
                                     "frame ({} at frame 0).", m, f, obstacles[f].size(), count));
    }
    for (size_t k = 0; k < count; ++k) {
      const Disc& d = obstacles[f][k];
      if (!d.centre.allFinite()) {
        return Fail(error, fmt::format("{}obstacles[{}][{}].centre = {}. Violated: finite.", m, f, k,
                                       Show(d.centre)));
      }
      if (!(std::isfinite(d.radius_px) && d.radius_px > 0.0)) {
        return Fail(error, fmt::format("{}obstacles[{}][{}].radius_px = {}. Violated: finite and > 0.",
                                       m, f, k, d.radius_px));
      }
    }
  }
  if (force_obstacle < -1 || force_obstacle >= static_cast<int>(count)) {
    return Fail(error, fmt::format("{}force_obstacle = {}. Violated: -1 <= force_obstacle < {} "
                                   "(the number of obstacles).", m, force_obstacle, count));
  }
  for (size_t k = 0; k < clamps.size(); ++k) {
    const RectPx& r = clamps[k];
    if (!(std::isfinite(r.x) && std::isfinite(r.y) && std::isfinite(r.width) &&
          std::isfinite(r.height) && r.width >= 0.0 && r.height >= 0.0)) {
      return Fail(error, fmt::format("{}clamps[{}] = (x {}, y {}, width {}, height {}). Violated: "
                                     "finite, width and height >= 0.", m, k, r.x, r.y, r.width,
                                     r.height));
    }
  }
  return true;
}

bool TruthOptions::IsValid(std::string* error) const {
  const std::string m = "TruthOptions::";
  if (max_newton_iterations < 1) {
    return Fail(error, fmt::format("{}max_newton_iterations = {}. Violated: max_newton_iterations >= 1.",
                                   m, max_newton_iterations));
  }
  if (!(std::isfinite(tolerance_px) && tolerance_px > 0.0)) {
    return Fail(error, fmt::format("{}tolerance_px = {}. Violated: finite and > 0.", m, tolerance_px));
  }
  if (!(std::isfinite(contact_distance_px) && contact_distance_px > 0.0)) {
    return Fail(error, fmt::format("{}contact_distance_px = {}. Violated: finite and > 0.", m,
                                   contact_distance_px));
  }
  if (!(std::isfinite(contact_stiffness_scale) && contact_stiffness_scale > 0.0)) {
    return Fail(error, fmt::format("{}contact_stiffness_scale = {}. Violated: finite and > 0.", m,
                                   contact_stiffness_scale));
  }
  if (max_step_splits < 0) {
    return Fail(error, fmt::format("{}max_step_splits = {}. Violated: max_step_splits >= 0.", m,
                                   max_step_splits));
  }
  return true;
}

// ---------------------------------------------------------------- simulation
namespace {

// sqrt of a symmetric positive-definite 2 x 2 matrix, closed form:
// sqrt(C) = (C + sqrt(det C) I) / sqrt(tr C + 2 sqrt(det C)).
Eigen::Matrix2d SqrtSpd(const Eigen::Matrix2d& c) {
  const double s = std::sqrt(std::max(c.determinant(), 0.0));
  return (c + s * Eigen::Matrix2d::Identity()) / std::sqrt(c.trace() + 2.0 * s);
}

// Eigenvalues of a symmetric 2 x 2 matrix, larger first.
std::pair<double, double> SymmetricEigenvalues(const Eigen::Matrix2d& c) {
  const double mean = 0.5 * (c(0, 0) + c(1, 1));
  const double half_diff = 0.5 * (c(0, 0) - c(1, 1));
  const double off = 0.5 * (c(0, 1) + c(1, 0));
  const double r = std::hypot(half_diff, off);
  return {mean + r, mean - r};
}

// Young's modulus multiplier of an element whose rest centroid is `p` (px).
double StiffnessFactor(const TruthMaterial& material, const Vec2& p, double projection_min,
                       double projection_max) {
  double factor = 1.0;
  if (material.stiffness_gradient > 0.0 && projection_max > projection_min) {
    const Vec2 dir = material.stiffness_gradient_direction.normalized();
    const double u = (dir.dot(p) - projection_min) / (projection_max - projection_min);
    factor *= 1.0 - material.stiffness_gradient + 2.0 * material.stiffness_gradient * u;
  }
  for (const StiffnessRegion& r : material.stiffness_regions) {
    if ((p - r.centre_px).norm() <= r.radius_px) factor *= r.factor;
  }
  return factor;
}

std::vector<Disc> DiscsAt(const TruthScene& scene, int frame, double s, double m_per_px) {
  // Linear interpolation from frame - 1 (s = 0) to frame (s = 1), in metres.
  std::vector<Disc> discs = scene.obstacles[frame];
  const std::vector<Disc>& prev = scene.obstacles[std::max(frame - 1, 0)];
  for (size_t k = 0; k < discs.size(); ++k) {
    discs[k].centre = m_per_px * ((1.0 - s) * prev[k].centre + s * discs[k].centre);
    discs[k].radius_px = m_per_px * ((1.0 - s) * prev[k].radius_px + s * discs[k].radius_px);
  }
  return discs;
}

std::vector<Disc> Lerp(const std::vector<Disc>& a, const std::vector<Disc>& b, double s) {
  std::vector<Disc> out = a;
  for (size_t k = 0; k < a.size(); ++k) {
    out[k].centre = (1.0 - s) * a[k].centre + s * b[k].centre;
    out[k].radius_px = (1.0 - s) * a[k].radius_px + s * b[k].radius_px;
  }
  return out;
}

class Simulation {
 public:
  Simulation(const TruthScene& scene, const TruthMaterial& material,
             const TruthEnvironment& environment, const TruthOptions& options)
      : scene_(scene), material_(material), environment_(environment), options_(options),
        m_per_px_(scene.mm_per_px * 1e-3), step_s_(1.0 / (scene.fps * scene.substeps)) {
    const Mesh& mesh = scene.rest_mesh;
    const int n = mesh.NumNodes();
    x_.resize(2 * n);
    for (int i = 0; i < n; ++i) x_.segment<2>(2 * i) = m_per_px_ * mesh.rest_positions[i];

    double pmin = std::numeric_limits<double>::infinity(), pmax = -pmin;
    const Vec2 dir = material.stiffness_gradient_direction.normalized();
    for (const Vec2& p : mesh.rest_positions) {
      pmin = std::min(pmin, dir.dot(p));
      pmax = std::max(pmax, dir.dot(p));
    }
    const double phi = material.viscous_fraction;
    std::vector<Element> elements(mesh.NumTriangles());
    Eigen::VectorXd mass = Eigen::VectorXd::Zero(n);
    double max_modulus = 0.0;
    for (int t = 0; t < mesh.NumTriangles(); ++t) {
      Element& e = elements[t];
      e.nodes = mesh.triangles[t];
      const Vec2 p0 = mesh.rest_positions[e.nodes[0]];
      const Vec2 p1 = mesh.rest_positions[e.nodes[1]];
      const Vec2 p2 = mesh.rest_positions[e.nodes[2]];
      Eigen::Matrix2d dm;
      dm << p1 - p0, p2 - p0;
      e.rest_inverse = (m_per_px_ * dm).inverse();
      const double area_m2 = 0.5 * (m_per_px_ * m_per_px_) * std::abs(dm.determinant());
      e.volume_m3 = area_m2 * material.thickness_m;
      const double modulus =
          material.youngs_modulus_pa * StiffnessFactor(material, (p0 + p1 + p2) / 3.0, pmin, pmax);
      max_modulus = std::max(max_modulus, modulus);
      NeoHookeanParameters full = PlaneStressLame(modulus, material.poisson_ratio);
      full.stiffening = material.stiffening_coefficient;
      e.elastic = full;
      e.elastic.mu_pa *= 1.0 - phi;
      e.elastic.lambda_pa *= 1.0 - phi;
      e.viscous = full;
      e.viscous.mu_pa *= phi;
      e.viscous.lambda_pa *= phi;
      e.elastic_rest_inverse = e.viscous_rest_inverse = e.rest_inverse;
      for (int a = 0; a < 3; ++a) mass[e.nodes[a]] += material.density_kg_m3 * e.volume_m3 / 3.0;
    }
    std::vector<char> fixed(n, 0);
    for (int i = 0; i < n; ++i) {
      for (const RectPx& r : scene.clamps) {
        if (r.Contains(mesh.rest_positions[i])) fixed[i] = 1;
      }
    }
    double edge_sum = 0.0;
    for (const double l : mesh.rest_length_px) edge_sum += l;
    const double mean_edge_m =
        m_per_px_ * (mesh.rest_length_px.empty() ? 1.0 : edge_sum / mesh.rest_length_px.size());
    const double dhat = options.contact_distance_px * m_per_px_;
    const double kappa =
        options.contact_stiffness_scale * max_modulus * material.thickness_m * mean_edge_m / dhat;
    system_ = std::make_unique<System>(std::move(elements), std::move(mass), std::move(fixed),
                                       dhat, kappa, DensityOf(material.law));
    x_prev_ = x_;
    v_ = v_prev_ = Eigen::VectorXd::Zero(2 * n);
  }

  std::vector<TruthFrame> Run() {
    std::vector<TruthFrame> frames;
    frames.reserve(scene_.num_frames);
    frame_ = 0;
    iterations_ = 0;
    SolveFrameZero();
    frames.push_back(Record());
    for (frame_ = 1; frame_ < scene_.num_frames; ++frame_) {
      iterations_ = 0;
      for (int k = 0; k < scene_.substeps; ++k) {
        const double s0 = static_cast<double>(k) / scene_.substeps;
        const double s1 = static_cast<double>(k + 1) / scene_.substeps;
        const std::vector<Disc> from = DiscsAt(scene_, frame_, s0, m_per_px_);
        const std::vector<Disc> to = DiscsAt(scene_, frame_, s1, m_per_px_);
        if (environment_.inertia) {
          DynamicStep(from, to);
        } else {
          QuasiStaticStep(from, to, step_s_, 0);
        }
      }
      frames.push_back(Record());
    }
    return frames;
  }

 private:
  [[noreturn]] void Throw(const std::string& what) const {
    throw std::runtime_error(fmt::format("SimulateTruth: frame {}: {}", frame_, what));
  }

  // `from`: the discs at the step's start (for the lagged contacts).
  StepTerms BaseTerms(const std::vector<Disc>& from, const std::vector<Disc>& discs,
                      double h) const {
    StepTerms t;
    t.discs_m = discs;
    t.contact_friction_coefficient = environment_.contact_friction_coefficient;
    if (t.contact_friction_coefficient > 0.0) {
      std::vector<Vec2> motion(discs.size());
      for (size_t k = 0; k < discs.size(); ++k) motion[k] = discs[k].centre - from[k].centre;
      t.contacts = system_->Contacts(x_, from, motion);
    }
    t.body_acceleration_m_s2 = environment_.gravity_m_s2;
    t.friction_coefficient = environment_.friction_coefficient;
    t.friction_anchor_m = x_;
    t.friction_epsilon_m = environment_.friction_regularisation_m_s * h;
    return t;
  }

  double Tolerance() const { return options_.tolerance_px * m_per_px_; }

  // Frame 0: static equilibrium under gravity + initial bend and the frame-0
  // discs; on failure the load is applied in halves.
  void SolveFrameZero() {
    const std::vector<Disc> discs = DiscsAt(scene_, 0, 1.0, m_per_px_);
    system_->PushOutOfDiscs(x_, discs);
    terms_ = BaseTerms(discs, discs, step_s_);
    SolveLoad(0.0, 1.0, 0);
    x_prev_ = x_;
  }

  void SolveLoad(double from, double to, int depth) {
    StepTerms t = terms_;
    t.body_acceleration_m_s2 = to * (environment_.gravity_m_s2 + environment_.initial_bend_m_s2);
    Eigen::VectorXd x = x_;
    const auto r = system_->Minimise(x, t, 4 * options_.max_newton_iterations, Tolerance());
    iterations_ += r.iterations;
    if (r.converged) {
      x_ = x;
      last_terms_ = t;
      return;
    }
    if (depth >= options_.max_step_splits) {
      Throw(fmt::format("the static equilibrium did not converge in {} Newton iterations at load "
                        "factor {}", 4 * options_.max_newton_iterations, to));
    }
    SolveLoad(from, 0.5 * (from + to), depth + 1);
    SolveLoad(0.5 * (from + to), to, depth + 1);
  }

  void QuasiStaticStep(const std::vector<Disc>& from, const std::vector<Disc>& to, double h,
                       int depth) {
    FlowPending();
    StepTerms t = BaseTerms(from, to, h);
    // Start from the last step's motion, extrapolated (a slowly moving
    // finger moves the body almost uniformly in time); where that start is
    // infeasible, from the current state.
    Eigen::VectorXd x = x_;
    if (last_step_s_ > 0.0) {
      x += (h / last_step_s_) * last_step_m_;
      system_->PushOutOfDiscs(x, to);
      if (!std::isfinite(system_->Energy(x, t))) x = x_;
    }
    system_->PushOutOfDiscs(x, to);
    bool converged = false;
    if (std::isfinite(system_->Energy(x, t))) {
      const auto r = system_->Minimise(x, t, options_.max_newton_iterations, Tolerance());
      iterations_ += r.iterations;
      converged = r.converged;
    }
    if (converged) {
      last_step_m_ = x - x_;
      last_step_s_ = h;
      x_ = x;
      last_terms_ = std::move(t);
      pending_flow_s_ = h;
      return;
    }
    if (depth >= options_.max_step_splits) {
      Throw(fmt::format("a quasi-static step did not converge in {} Newton iterations after {} "
                        "splits", options_.max_newton_iterations, depth));
    }
    const std::vector<Disc> mid = Lerp(from, to, 0.5);
    QuasiStaticStep(from, mid, 0.5 * h, depth + 1);
    QuasiStaticStep(mid, to, 0.5 * h, depth + 1);
  }

  // BDF2: with h' = 2h/3 and x~ = (4 x_n - x_{n-1}) / 3, the step minimises
  // Phi with inertia target x^ = x~ + h' (4 v_n - v_{n-1}) / 3 and friction
  // anchored at x~; then v_{n+1} = (x_{n+1} - x~) / h'. The history starts
  // at rest (x_{-1} = x_0, v = 0), where the first step is consistent.
  void DynamicStep(const std::vector<Disc>& from, const std::vector<Disc>& to) {
    FlowPending();
    const double hp = 2.0 * step_s_ / 3.0;
    const Eigen::VectorXd x_tilde = (4.0 * x_ - x_prev_) / 3.0;
    StepTerms t = BaseTerms(from, to, hp);
    t.friction_anchor_m = x_tilde;
    t.inertia = true;
    t.inertia_step_s = hp;
    t.inertia_target_m = x_tilde + hp * (4.0 * v_ - v_prev_) / 3.0;
    Eigen::VectorXd x = x_;
    system_->PushOutOfDiscs(x, to);
    const auto r = system_->Minimise(x, t, options_.max_newton_iterations, Tolerance());
    iterations_ += r.iterations;
    if (!r.converged) {
      Throw(fmt::format("a dynamic step did not converge in {} Newton iterations",
                        options_.max_newton_iterations));
    }
    x_prev_ = x_;
    v_prev_ = v_;
    v_ = (x - x_tilde) / hp;
    const auto& fixed = system_->fixed();
    for (size_t i = 0; i < fixed.size(); ++i) {
      if (fixed[i]) v_.segment<2>(2 * i).setZero();
    }
    x_ = std::move(x);
    last_terms_ = std::move(t);
    pending_flow_s_ = step_s_;
  }

  // The rest shapes flow after each step (applied lazily, at the start of
  // the next step, so that a recorded frame's forces belong to the state its
  // Newton solve balanced). U = sqrt(F^T F) is the current stretch against the
  // original rest shape (rotation-free, so a rotating body does not flow).
  //  - Plasticity: with Ce the elastic-branch Cauchy-Green tensor and
  //    e1 >= e2 its principal log strains, the deviatoric strain is
  //    (e1 - e2) / 2; above the yield strain Y the plastic stretch moves
  //    towards U by (1 - exp(-rate dt)) (1 - Y / dev): a rate-limited return
  //    that stops once the elastic strain is back at yield.
  //  - Viscoelasticity: the Maxwell branch's stretch relaxes towards U by
  //    1 - exp(-dt / tau) (exact for a linear Maxwell element).
  void FlowPending() {
    const double dt = pending_flow_s_;
    pending_flow_s_ = 0.0;
    const bool plastic = std::isfinite(material_.plastic_yield_strain);
    const bool viscous = material_.viscous_fraction > 0.0;
    if (dt <= 0.0 || (!plastic && !viscous)) return;
    const double plastic_share = 1.0 - std::exp(-material_.plastic_flow_rate_per_s * dt);
    const double viscous_share = 1.0 - std::exp(-dt / material_.viscous_relaxation_time_s);
    for (Element& e : system_->elements()) {
      Eigen::Matrix2d ds;
      ds << x_.segment<2>(2 * e.nodes[1]) - x_.segment<2>(2 * e.nodes[0]),
          x_.segment<2>(2 * e.nodes[2]) - x_.segment<2>(2 * e.nodes[0]);
      const Eigen::Matrix2d F = ds * e.rest_inverse;
      const Eigen::Matrix2d U = SqrtSpd(F.transpose() * F);
      if (plastic) {
        const Eigen::Matrix2d fe = F * e.plastic_stretch.inverse();
        const auto [c1, c2] = SymmetricEigenvalues(fe.transpose() * fe);
        const double dev = 0.25 * std::log(c1 / c2);
        if (dev > material_.plastic_yield_strain) {
          const double beta = plastic_share * (1.0 - material_.plastic_yield_strain / dev);
          Eigen::Matrix2d up = e.plastic_stretch + beta * (U - e.plastic_stretch);
          up = 0.5 * (up + up.transpose()).eval();
          e.plastic_stretch = up;
          e.elastic_rest_inverse = e.rest_inverse * up.inverse();
        }
      }
      if (viscous) {
        Eigen::Matrix2d uv = e.viscous_stretch + viscous_share * (U - e.viscous_stretch);
        uv = 0.5 * (uv + uv.transpose()).eval();
        e.viscous_stretch = uv;
        e.viscous_rest_inverse = e.rest_inverse * uv.inverse();
      }
    }
  }

  TruthFrame Record() const {
    const int n = system_->NumNodes();
    TruthFrame frame;
    frame.newton_iterations = iterations_;
    frame.positions_px.resize(n);
    for (int i = 0; i < n; ++i) frame.positions_px[i] = x_.segment<2>(2 * i) / m_per_px_;
    frame.elastic_energy_j = system_->ElasticEnergy(x_, nullptr);
    const StepTerms& t = last_terms_;
    const auto& fixed = system_->fixed();
    auto total_force = [&](const Eigen::VectorXd& gradient) {
      Vec2 sum = Vec2::Zero();
      for (int i = 0; i < n; ++i) {
        if (!fixed[i]) sum -= gradient.segment<2>(2 * i);
      }
      return sum;
    };
    for (size_t k = 0; k < t.discs_m.size(); ++k) {
      Eigen::VectorXd g = Eigen::VectorXd::Zero(2 * n);
      system_->BarrierEnergy(x_, t.discs_m, static_cast<int>(k), &g);
      system_->ContactFrictionEnergy(x_, t, static_cast<int>(k), &g);
      frame.obstacle_forces_n.push_back(total_force(g));
    }
    if (scene_.force_obstacle >= 0) {
      frame.contact_force_n = frame.obstacle_forces_n[scene_.force_obstacle];
    }
    Eigen::VectorXd friction = Eigen::VectorXd::Zero(2 * n);
    system_->FrictionEnergy(x_, t, &friction);
    frame.friction_force_n = total_force(friction);
    if (options_.record_node_forces) {
      Eigen::VectorXd elastic = Eigen::VectorXd::Zero(2 * n);
      Eigen::VectorXd contact = Eigen::VectorXd::Zero(2 * n);
      system_->ElasticEnergy(x_, &elastic);
      system_->BarrierEnergy(x_, t.discs_m, -1, &contact);
      system_->ContactFrictionEnergy(x_, t, -1, &contact);
      frame.elastic_forces_n.resize(n);
      frame.friction_forces_n.resize(n);
      frame.contact_forces_n.resize(n);
      for (int i = 0; i < n; ++i) {
        frame.elastic_forces_n[i] = -elastic.segment<2>(2 * i);
        frame.friction_forces_n[i] = -friction.segment<2>(2 * i);
        frame.contact_forces_n[i] = -contact.segment<2>(2 * i);
      }
    }
    return frame;
  }

  const TruthScene& scene_;
  const TruthMaterial& material_;
  const TruthEnvironment& environment_;
  const TruthOptions& options_;
  const double m_per_px_;
  const double step_s_;
  std::unique_ptr<System> system_;
  Eigen::VectorXd x_, x_prev_, v_, v_prev_;
  StepTerms terms_, last_terms_;
  double pending_flow_s_ = 0.0;
  /// The last quasi-static step's displacement and length (the predictor).
  Eigen::VectorXd last_step_m_;
  double last_step_s_ = 0.0;
  int frame_ = 0;
  int iterations_ = 0;
};

}  // namespace

std::vector<TruthFrame> SimulateTruth(const TruthScene& scene, const TruthMaterial& material,
                                      const TruthEnvironment& environment,
                                      const TruthOptions& options) {
  std::string error;
  if (!scene.IsValid(&error) || !material.IsValid(&error) || !environment.IsValid(&error) ||
      !options.IsValid(&error)) {
    throw std::invalid_argument("SimulateTruth: " + error);
  }
  Simulation simulation(scene, material, environment, options);
  return simulation.Run();
}

}  // namespace calib::synth
