#include "calib/core/simulator.h"

#include "calib/core/constraints.h"
#include "calib/core/implicit_step.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>

namespace calib {
namespace {

// An edge point this near an end node (share of the edge: 0.6 px of a 20 px
// edge) is that node's contact: held as both, the two nearly repeat each
// other, the contacts' system is singular up to rounding, their forces come
// out huge and of opposite signs, and the active set cycles. (At a tenth of
// the edge the node's radial contact stands in for the edge's too far from
// it: at the stiff push_centre fit the nodes then moved 0.35 px a substep
// against the finger's 0.1.)
constexpr double kEdgeContactEndShare = 0.03;

// Partial results over this many interleaved lanes: the reductions below
// vectorise (min and max are exact, so the lanes give the plain loop's
// result).
constexpr int kLanes = 4;

// The first i with the least |x_i - centre|^2, as the plain loop
// `if (d < best) { best = d; nearest = i; }` from best = +inf finds it (0
// when no distance is below +inf).
int NearestNode(std::span<const Vec2> x, const Vec2& centre) {
  const int n = static_cast<int>(x.size());
  const auto distance_sq = [&](int i) { return (x[i] - centre).squaredNorm(); };
  double lane_min[kLanes];
  for (double& m : lane_min) m = std::numeric_limits<double>::infinity();
  int i = 0;
  for (; i + kLanes <= n; i += kLanes) {
    for (int l = 0; l < kLanes; ++l) {
      const double d = distance_sq(i + l);
      lane_min[l] = d < lane_min[l] ? d : lane_min[l];
    }
  }
  for (; i < n; ++i) {
    const double d = distance_sq(i);
    lane_min[0] = d < lane_min[0] ? d : lane_min[0];
  }
  double best = lane_min[0];
  for (int l = 1; l < kLanes; ++l) best = lane_min[l] < best ? lane_min[l] : best;
  if (!(best < std::numeric_limits<double>::infinity())) return 0;
  for (i = 0; i < n; ++i) {
    if (distance_sq(i) == best) return i;
  }
  return 0;  // not reached: best is one of the distances
}

// v_i = (x_i - x_prev_i) inv_h for every node; returns the largest |v_i|^2
// as `fastest = std::max(fastest, |v_i|^2)` from 0 finds it.
double SetVelocities(std::span<const Vec2> x, std::span<const Vec2> x_prev, double inv_h,
                     std::span<Vec2> v) {
  const size_t n = x.size();
  double lane_max[kLanes] = {0.0, 0.0, 0.0, 0.0};
  size_t i = 0;
  for (; i + kLanes <= n; i += kLanes) {
    for (size_t l = 0; l < kLanes; ++l) {
      v[i + l] = (x[i + l] - x_prev[i + l]) * inv_h;
      const double s = v[i + l].squaredNorm();
      lane_max[l] = lane_max[l] < s ? s : lane_max[l];
    }
  }
  for (; i < n; ++i) {
    v[i] = (x[i] - x_prev[i]) * inv_h;
    lane_max[0] = std::max(lane_max[0], v[i].squaredNorm());
  }
  double fastest = lane_max[0];
  for (int l = 1; l < kLanes; ++l) fastest = std::max(fastest, lane_max[l]);
  return fastest;
}

}  // namespace

std::vector<uint8_t> ClampedNodes(const Mesh& mesh, const Scene& scene) {
  std::vector<uint8_t> clamped(mesh.NumNodes(), 0);
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    for (const RectPx& clamp : scene.clamps) {
      if (clamp.Contains(mesh.rest_positions[i])) clamped[i] = 1;
    }
  }
  return clamped;
}

bool SimulationOptions::IsValid(std::string* error) const {
  auto fail = [&](std::string message) {
    if (error != nullptr) *error = std::move(message);
    return false;
  };
  if (substeps < 1) {
    return fail(fmt::format("SimulationOptions::substeps = {}. Violated: substeps >= 1.", substeps));
  }
  if (constraint_iterations < 1) {
    return fail(fmt::format(
        "SimulationOptions::constraint_iterations = {}. Violated: constraint_iterations >= 1.",
        constraint_iterations));
  }
  if (!(min_area_fraction > 0.0 && min_area_fraction < 1.0)) {
    return fail(fmt::format(
        "SimulationOptions::min_area_fraction = {}. Violated: 0 < min_area_fraction < 1.",
        min_area_fraction));
  }
  if (!(std::isfinite(contact_friction) && contact_friction >= 0.0)) {
    return fail(fmt::format(
        "SimulationOptions::contact_friction = {}. Violated: finite and contact_friction >= 0.",
        contact_friction));
  }
  if (!(divergence_diameters > 0.0)) {
    return fail(fmt::format(
        "SimulationOptions::divergence_diameters = {}. Violated: divergence_diameters > 0.",
        divergence_diameters));
  }
  return true;
}

Simulator::Simulator(const Mesh& mesh, const Scene& scene, const SimulationOptions& options)
    : Simulator(mesh, scene, options, ModelDefinition{}) {}

Simulator::Simulator(const Mesh& mesh, const Scene& scene, const SimulationOptions& options,
                     const ModelDefinition& model)
    : mesh_(mesh),
      scene_(scene),
      options_(options),
      model_(mesh),
      force_workspace_(model_.MakeWorkspace()),
      clamped_(ClampedNodes(mesh, scene)),
      inverse_weight_(mesh.NumNodes(), 1.0),
      x_(mesh.rest_positions),
      x_prev_(mesh.rest_positions),
      v_(mesh.NumNodes(), Vec2::Zero()),
      f_(mesh.NumNodes(), Vec2::Zero()),
      discs_(scene.num_obstacles),
      discs_start_(scene.num_obstacles),
      definition_(model),
      parameter_specs_(ModelParameterSpecs(model)),
      initial_motion_(mesh, clamped_),
      substeps_(options.substeps) {
  Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    const Vec2& p = mesh.rest_positions[i];
    if (clamped_[i] != 0) inverse_weight_[i] = 0.0;
    rest_centroid_ += p;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (mesh.NumNodes() > 0) rest_centroid_ /= mesh.NumNodes();
  const double radius = options.divergence_diameters * std::max((hi - lo).norm(), 1.0);
  divergence_radius_sq_ = radius * radius;

  for (const std::string& name : model.effects) {
    std::unique_ptr<EffectTerm> effect = MakeEffect(name);
    effect->Bind(mesh);
    const EffectHooks hooks = effect->hooks();
    if (hooks.forces) force_effects_.push_back(effect.get());
    if (hooks.after_substep) after_substep_effects_.push_back(effect.get());
    if (hooks.after_frame) after_frame_effects_.push_back(effect.get());
    if (hooks.step_limit) step_limit_effects_.push_back(effect.get());
    if (hooks.forces && hooks.rest_stiffness) rest_stiffness_effects_.push_back(effect.get());
    if (hooks.forces && hooks.shape_stiffness) shape_stiffness_effects_.push_back(effect.get());
    const auto claim = [&](const EffectTerm*& slot, const char* what) {
      if (slot != nullptr) {
        throw std::invalid_argument(fmt::format("effects '{}' and '{}' both change {}; use one",
                                                slot->name(), name, what));
      }
      slot = effect.get();
    };
    if (hooks.push) claim(push_effect_, "how the push acts");
    if (hooks.dynamics) claim(dynamics_effect_, "the dynamics");
    effects_.push_back(std::move(effect));
  }
  if (dynamics_effect_ != nullptr) {
    for (auto* buffer : {&mode_u_, &mode_y_, &mode_still_, &probe_x_, &probe_f_}) {
      buffer->assign(mesh.NumNodes(), Vec2::Zero());
    }
    mode_probe_px_ = 1e-4 * std::max(MeasureQuality(mesh).mean_edge_px, 1.0);
  }
  if (options.area_weighted && dynamics_effect_ != nullptr) {
    AreaWeights weights = ComputeAreaWeights(mesh, scene.motion.element_area_px2);
    model_.SetElementWeights(weights.edge, weights.triangle, weights.angle);
    mass_weight_ = std::move(weights.node);
    inverse_mass_weight_.resize(mass_weight_.size());
    for (size_t i = 0; i < mass_weight_.size(); ++i) inverse_mass_weight_[i] = 1.0 / mass_weight_[i];
  }
  if (options.integrator == IntegratorKind::kImplicitFirstOrder) {
    implicit_step_ = std::make_unique<ImplicitFirstOrderStep>(model_, inverse_weight_,
                                                              !shape_stiffness_effects_.empty());
    if (!rest_stiffness_effects_.empty()) zero_velocity_.assign(mesh.NumNodes(), Vec2::Zero());
    snap_px_ = 0.5 * MeasureQuality(mesh).mean_edge_px;
    size_t boundary_edges = 0;
    for (const std::vector<int>& loop : mesh.boundary_loops) boundary_edges += loop.size();
    step_contacts_.reserve(static_cast<size_t>(scene.num_obstacles) *
                           (static_cast<size_t>(mesh.NumNodes()) + boundary_edges));
  }
}

Simulator::Simulator(Simulator&&) = default;
Simulator::~Simulator() = default;

void Simulator::Reset(const ModelParameters& params) {
  if (!effects_.empty()) {
    throw std::logic_error(fmt::format(
        "Simulator::Reset(ModelParameters) on the model {}: the effects need their parameters; "
        "call Reset(ParameterValues)",
        definition_.ToString()));
  }
  params_ = params;
  second_order_ = false;
  substeps_ = options_.substeps;
  ResetState();
  ConfigureIntegrator();
}

void Simulator::ConfigureIntegrator() {
  implicit_ = implicit_step_ != nullptr && !second_order_;
  force_params_ = params_;
  if (!implicit_) return;
  force_params_.k_damping = 0.0;
  // The effects' springs go into the step's matrix with the base springs.
  const ImplicitFirstOrderStep::ExtraForces effect_springs =
      [this](std::span<const Vec2> x, std::span<Vec2> f) {
        for (const EffectTerm* effect : rest_stiffness_effects_) {
          effect->AddForces(x, zero_velocity_, f, nullptr);
        }
      };
  std::string error;
  if (!implicit_step_->Configure(params_, scene_.frame_time_s / options_.substeps,
                                 rest_stiffness_effects_.empty() ? nullptr : &effect_springs,
                                 &error)) {
    Fail(std::move(error));
  }
}

void Simulator::Reset(const ParameterValues& values) {
  ValidateParameters(values, parameter_specs_, "parameters");
  params_ = ModelParameters::FromValues(values);
  for (const auto& effect : effects_) {
    effect->Configure(values, params_);
    effect->Reset();
  }
  second_order_ = false;
  second_order_damping_per_s_ = 0.0;
  body_force_.setZero();
  for (const EffectTerm* effect : force_effects_) body_force_ += effect->UniformNodeForce();
  if (dynamics_effect_ != nullptr) {
    if (const std::optional<double> damping = dynamics_effect_->SecondOrderDamping()) {
      second_order_ = true;
      second_order_damping_per_s_ = *damping;
    }
  }
  substeps_ = options_.substeps;
  ResetState();
  ConfigureIntegrator();
  if (second_order_ && status_ == SimulationStatus::kRunning) ChooseStableSubsteps();
}

template <class Apply>
double Simulator::FastestModeRate(Apply&& apply) {
  // Power iteration in the M inner product from a fixed alternating field
  // (the fastest modes alternate from node to node), so the estimate is the
  // same on every run. The Rayleigh quotient u^T J u / u^T M u approaches
  // the largest rate from below; the margin covers what 30 rounds miss.
  constexpr int kRounds = 30;
  const size_t n = x_.size();
  const auto mass = [&](size_t i) {
    return params_.mass * (mass_weight_.empty() ? 1.0 : mass_weight_[i]);
  };
  for (size_t i = 0; i < n; ++i) {
    const double sign = (i % 2 == 0) ? 1.0 : -1.0;
    const double turn = (i / 2) % 2 == 0 ? 0.5 : -0.5;
    mode_u_[i] = inverse_weight_[i] == 0.0 ? Vec2::Zero() : Vec2(sign, turn * sign);
  }
  double rate = 0.0;
  for (int round = 0; round < kRounds; ++round) {
    double norm_sq = 0.0;
    for (size_t i = 0; i < n; ++i) norm_sq += mass(i) * mode_u_[i].squaredNorm();
    if (!(norm_sq > 0.0) || !std::isfinite(norm_sq)) break;
    const double scale = 1.0 / std::sqrt(norm_sq);
    for (Vec2& u : mode_u_) u *= scale;
    apply(mode_u_, mode_y_);
    double quotient = 0.0;
    for (size_t i = 0; i < n; ++i) {
      if (inverse_weight_[i] == 0.0) continue;
      quotient += mode_u_[i].dot(mode_y_[i]);
      mode_u_[i] = mode_y_[i] / mass(i);
    }
    if (!std::isfinite(quotient)) return quotient;
    rate = std::max(rate, std::abs(quotient));
  }
  return rate;
}

void Simulator::ChooseStableSubsteps() {
  const size_t n = x_.size();
  // J u for the springs (K, by central differences of the forces at zero
  // velocity, the effects' forces included) and for the edge damping (D,
  // linear in the velocities: minus the forces of the damping alone).
  ModelParameters stiffness = params_;
  stiffness.k_damping = 0.0;
  ModelParameters damping = params_;
  damping.k_distance = damping.k_area = damping.k_angle = 0.0;
  const double probe_px = mode_probe_px_;
  const auto forces_at = [&](std::span<const Vec2> x, std::span<Vec2> f) {
    model_.ComputeForces(stiffness, x, mode_still_, f, force_workspace_);
    for (const EffectTerm* effect : force_effects_) effect->AddForces(x, mode_still_, f, nullptr);
  };
  const double lambda_k = FastestModeRate([&](std::span<const Vec2> u, std::span<Vec2> out) {
    for (size_t i = 0; i < n; ++i) probe_x_[i] = x_[i] + probe_px * u[i];
    forces_at(probe_x_, probe_f_);
    for (size_t i = 0; i < n; ++i) probe_x_[i] = x_[i] - probe_px * u[i];
    forces_at(probe_x_, out);
    for (size_t i = 0; i < n; ++i) out[i] = (out[i] - probe_f_[i]) / (2.0 * probe_px);
  });
  const double lambda_d =
      params_.k_damping == 0.0
          ? 0.0
          : FastestModeRate([&](std::span<const Vec2> u, std::span<Vec2> out) {
              model_.ComputeForces(damping, x_, u, out, force_workspace_);
              for (Vec2& f : out) f = -f;
            });
  if (!std::isfinite(lambda_k) || !std::isfinite(lambda_d)) {
    Fail(fmt::format("the second-order step's fastest mode could not be estimated at frame 0 "
                     "(rates {} /s^2 and {} /s)",
                     lambda_k, lambda_d));
    return;
  }
  // The largest h with margin (h^2 lambda_K + 2 h lambda_D) <= 4.
  const double a = kStabilityMargin * lambda_k, b = 2.0 * kStabilityMargin * lambda_d;
  double h_max = std::numeric_limits<double>::infinity();
  if (a > 0.0) {
    h_max = (-b + std::sqrt(b * b + 16.0 * a)) / (2.0 * a);
  } else if (b > 0.0) {
    h_max = 4.0 / b;
  }
  const double needed = std::ceil(scene_.frame_time_s / h_max);
  if (needed > kMaxSubsteps) {
    Fail(fmt::format(
        "the second-order step needs {:.0f} substeps a frame to be stable at these stiffnesses "
        "(fastest mode {:.3g} rad/s; at most {}): springs too stiff for their mass",
        needed, std::sqrt(lambda_k), kMaxSubsteps));
    return;
  }
  substeps_ = std::max(options_.substeps, static_cast<int>(needed));
}

void Simulator::StartFromObservedMotion() {
  model_.ResetRestShape();
  std::string error;
  if (!initial_motion_.Compute(model_, params_, scene_.motion, force_workspace_, &error)) {
    Fail(std::move(error));
    return;
  }
  if (initial_motion_.from_tracked_shape() && model_.SetRestShape(initial_motion_.rest_shape()) < 0) {
    // The tracked shape is where the object hangs, under gravity: the
    // springs rest where that shape is their equilibrium with it (or as
    // near as keeps every triangle; the model is left resting there).
    if (!initial_motion_.SubtractStaticResponse(model_, params_, body_force_, mass_weight_,
                                                force_workspace_, &error)) {
      Fail(std::move(error));
      return;
    }
  } else if (model_.SetRestShape(initial_motion_.rest_shape()) >= 0) {
    // The estimate turned a triangle over (a deflection too large for the
    // linear estimate): rest at the largest share of it that keeps every
    // triangle.
    initial_motion_.LimitDeflection(model_);
  }
  rest_shifted_ = true;
  std::copy(initial_motion_.velocities().begin(), initial_motion_.velocities().end(), v_.begin());
  // The tracked shape's own start pose: the rest shape posed on frame 0
  // (unstretched), rather than the mesh fitted to its blurred outline.
  const std::vector<Vec2>& start = scene_.motion.node_start_px;
  if (initial_motion_.from_tracked_shape() && start.size() == x_.size()) {
    std::copy(start.begin(), start.end(), x_.begin());
    std::copy(start.begin(), start.end(), x_prev_.begin());
  }
}

void Simulator::ResetState() {
  std::copy(mesh_.rest_positions.begin(), mesh_.rest_positions.end(), x_.begin());
  std::copy(mesh_.rest_positions.begin(), mesh_.rest_positions.end(), x_prev_.begin());
  for (Vec2& v : v_) v.setZero();
  frame_ = 0;
  last_step_px_ = 0.0;
  status_ = scene_.num_frames > 1 ? SimulationStatus::kRunning : SimulationStatus::kFinished;
  failure_reason_.clear();
  InterpolateObstacles(0.0);
  if (rest_shifted_) model_.ResetRestShape();
  rest_shifted_ = false;
  if (second_order_ && scene_.motion.known && initial_motion_.applicable()) {
    StartFromObservedMotion();
  }
}

void Simulator::InterpolateObstacles(double alpha) {
  if (scene_.num_obstacles == 0) return;
  const Disc* from = scene_.ObstaclesAt(frame_);
  const Disc* to = scene_.ObstaclesAt(std::min(frame_ + 1, scene_.num_frames - 1));
  for (int k = 0; k < scene_.num_obstacles; ++k) {
    discs_[k].centre = (1.0 - alpha) * from[k].centre + alpha * to[k].centre;
    discs_[k].radius_px = (1.0 - alpha) * from[k].radius_px + alpha * to[k].radius_px;
  }
}

void Simulator::Fail(std::string reason) {
  status_ = SimulationStatus::kFailed;
  failure_reason_ = std::move(reason);
}

bool Simulator::Substep(int substep) {
  if (status_ != SimulationStatus::kRunning) return false;
  const int n = mesh_.NumNodes();
  const double h = scene_.frame_time_s / substeps_;
  const double alpha0 = static_cast<double>(substep) / substeps_;

  if (implicit_ && substep == 0 && !shape_stiffness_effects_.empty()) {
    // Springs that stiffen with strain: their stiffness at this frame's
    // shape goes into the step's matrix.
    implicit_step_->BeginShapeStiffness();
    for (const EffectTerm* effect : shape_stiffness_effects_) {
      effect->AddShapeStiffness(x_, *implicit_step_);
    }
    std::string error;
    if (!implicit_step_->FinishShapeStiffness(&error)) {
      Fail(fmt::format("{} (frame {})", error, frame_));
      return false;
    }
  }

  model_.ComputeForces(force_params_, x_, v_, f_, force_workspace_);
  for (const EffectTerm* effect : force_effects_) effect->AddForces(x_, v_, f_, nullptr);

  // The measured push: on the node nearest the force obstacle, except the
  // share tau ("translation") spread evenly over all nodes; or as the push
  // effect (push_relaxation) splits it.
  if (scene_.force_obstacle >= 0 && !scene_.forces.empty()) {
    const Vec2 push = (1.0 - alpha0) * scene_.forces[frame_] +
                      alpha0 * scene_.forces[std::min(frame_ + 1, scene_.num_frames - 1)];
    const Vec2 centre = discs_[scene_.force_obstacle].centre;
    const int nearest = NearestNode(x_, centre);
    if (push_effect_ != nullptr) {
      PushInfo info;
      info.push = push;
      info.contact_node = nearest;
      info.num_nodes = n;
      info.translation = params_.translation;
      const PushSplit split = push_effect_->SplitPush(info);
      const Vec2 spread = split.spread_total / n;
      for (Vec2& f : f_) f += spread;
      f_[nearest] += split.node_force;
    } else {
      const Vec2 spread = (params_.translation / n) * push;
      for (Vec2& f : f_) f += spread;
      f_[nearest] += (1.0 - params_.translation) * push;
    }
  }

  // The obstacles where the substep starts and where it ends.
  std::copy(discs_.begin(), discs_.end(), discs_start_.begin());
  InterpolateObstacles(static_cast<double>(substep + 1) / substeps_);

  if (second_order_) {
    std::copy(x_.begin(), x_.end(), x_prev_.begin());
    StepDampedSecondOrder(h, second_order_damping_per_s_, params_.mass);
  } else if (implicit_) {
    std::copy(x_.begin(), x_.end(), x_prev_.begin());
    GatherStepContacts();
    implicit_step_->Step(f_, x_, step_contacts_, options_.contact_friction);
    if (!CheckImplicitStep(substep)) return false;
  } else if (options_.integrator == IntegratorKind::kFirstOrder) {
    std::copy(x_.begin(), x_.end(), x_prev_.begin());
    StepFirstOrder(h / params_.mass, f_, inverse_weight_, x_);
  } else {
    StepVerlet(h * h / params_.mass, f_, inverse_weight_, x_, x_prev_);
  }
  if (!step_limit_effects_.empty()) {
    StepInfo step;
    step.h_s = h;
    step.mass = params_.mass;
    step.second_order = second_order_ || options_.integrator == IntegratorKind::kVerlet;
    for (const EffectTerm* effect : step_limit_effects_) {
      effect->LimitStep(x_prev_, inverse_weight_, x_, step);
    }
  }

  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(x_[i].x()) || !std::isfinite(x_[i].y())) {
      Fail(fmt::format("node {} position is not finite (substep {})", i, substep));
      return false;
    }
  }

  if (!ApplyConstraints()) return false;

  const double fastest_sq = SetVelocities(x_, x_prev_, 1.0 / h, v_);
  last_step_px_ = std::sqrt(fastest_sq) * h;
  for (EffectTerm* effect : after_substep_effects_) effect->AfterSubstep(x_, h);
  return true;
}

bool Simulator::CheckImplicitStep(int substep) {
  // The mesh follows its obstacles and its load a fraction of a pixel a
  // substep. A node the step moves by half an edge or more has snapped
  // through: squeezed between obstacles, a mesh far stiffer in its edges
  // and areas than in its angles stores the obstacles' work until it folds,
  // then releases it in a few substeps (tens of pixels each) and ends with
  // triangles turned over. Such a candidate follows no video; it fails
  // here, with the node and the move, rather than by chance a few frames on.
  const double snap_sq = snap_px_ * snap_px_;
  for (size_t i = 0; i < x_.size(); ++i) {
    const double move_sq = (x_[i] - x_prev_[i]).squaredNorm();
    if (move_sq >= snap_sq) {
      Fail(fmt::format(
          "the implicit step moved node {} by {:.1f} px in one substep (substep {}), half a mesh "
          "edge or more: the mesh snapped through",
          i, std::sqrt(move_sq), substep));
      return false;
    }
  }
  return true;
}

void Simulator::GatherStepContacts() {
  // Every node, and with outline contact every boundary edge, within reach
  // of an obstacle where the substep ends: as far as the last substep moved
  // a node, twice, plus the obstacle's own motion. The step holds those it
  // would break; what it misses the projections catch.
  step_contacts_.clear();
  const int n = mesh_.NumNodes();
  for (size_t k = 0; k < discs_.size(); ++k) {
    const Vec2 c = discs_[k].centre;
    const double r = discs_[k].radius_px;
    const Vec2 motion = c - discs_start_[k].centre;
    const double reach = r + 1.0 + 2.0 * last_step_px_ + motion.norm();
    // Beyond this squared distance a node is surely out of reach (sqrt is
    // correctly rounded): its square root is not taken.
    const double reach_sq_bound = reach * reach * (1.0 + 1e-9);
    for (int i = 0; i < n; ++i) {
      if (inverse_weight_[i] == 0.0) continue;
      const Vec2 d = x_[i] - c;
      if (d.squaredNorm() > reach_sq_bound) continue;
      const double dist = d.norm();
      if (!(dist < reach && dist > 0.0)) continue;
      StepContact contact;
      contact.nodes = {i, -1};
      contact.normal = d / dist;
      contact.gap = r - dist;
      contact.obstacle_step = motion;
      step_contacts_.push_back(contact);
    }
    if (!options_.outline_contact) continue;
    for (const std::vector<int>& loop : mesh_.boundary_loops) {
      for (size_t e = 0, m = loop.size(); e < m; ++e) {
        const int a = loop[e], b = loop[(e + 1) % m];
        // An edge whose bounding box lies farther than the reach (and a
        // pixel) from the centre has no point within it.
        if (!BoxWithin(x_[a], x_[b], c, reach + 1.0)) continue;
        // Nearest an end node: that node's contact. s > 0: the centre is in
        // front of the edge.
        EdgePoint nearest;
        if (!NearestInteriorEdgePoint(x_[a], x_[b], c, &nearest)) continue;
        if (!(nearest.s > 0.0 && nearest.s < reach)) continue;
        if (std::min(nearest.t, 1.0 - nearest.t) < kEdgeContactEndShare) continue;
        StepContact contact;
        contact.nodes = {a, b};
        contact.weights = {1.0 - nearest.t, nearest.t};
        contact.normal = nearest.inward;
        contact.gap = r - nearest.s;
        contact.obstacle_step = motion;
        step_contacts_.push_back(contact);
      }
    }
  }
}

// The inertia effect's step from x (already copied to x_prev_) with the
// velocities v_ of the last substep (after its constraints):
//   x += h v / (1 + h c) + h^2 F / m,
// semi-implicit Euler with the velocity decay c implicit, for movable nodes.
//
// Area weighted, node i's mass is m w_i and the body force on it w_i b (b
// the effects' uniform force at weight 1, gravity's m g), so that
//   x += h v / (1 + h c) + h^2 ((F - b) / w_i + b) / m.
void Simulator::StepDampedSecondOrder(double h, double damping_per_s, double mass) {
  const double keep = h / (1.0 + h * damping_per_s);
  const double h2_over_m = h * h / mass;
  if (!inverse_mass_weight_.empty()) {
    for (size_t i = 0; i < x_.size(); ++i) {
      if (inverse_weight_[i] == 0.0) continue;
      x_[i] += keep * v_[i] + h2_over_m * ((f_[i] - body_force_) * inverse_mass_weight_[i] + body_force_);
    }
    return;
  }
  for (size_t i = 0; i < x_.size(); ++i) {
    if (inverse_weight_[i] == 0.0) continue;
    x_[i] += keep * v_[i] + h2_over_m * f_[i];
  }
}

bool Simulator::ApplyConstraints() {
  // Clamped nodes have inverse weight 0: the integrator and the projections
  // never move them, so they stay at their rest positions.
  // Whether every triangle passed the repair's test at the present
  // positions: a round whose projections then move nothing would find no
  // triangle to repair, so its scan is skipped (the same result).
  bool triangles_pass = false;
  for (int iter = 0; iter < options_.constraint_iterations; ++iter) {
    // Edges first, nodes last: a node is never left inside a disc by the
    // edge step (the check below holds nodes to it; an edge that the rounds
    // leave a little inside is tolerated).
    // Against where the substep started: a step longer than a disc's
    // radius (stiff springs with the implicit step) is resolved back to the
    // side it came from, not out of the disc's far side.
    const SubstepStart start{x_prev_, discs_start_, options_.contact_friction};
    const int edges_moved =
        options_.outline_contact
            ? ProjectBoundaryOutOfDiscs(mesh_, discs_, inverse_weight_, x_, start)
            : 0;
    const int moved = edges_moved + ProjectOutOfDiscs(discs_, inverse_weight_, x_, start);
    // The projections count every node they move.
    if (moved > 0) triangles_pass = false;
    const int repaired =
        triangles_pass
            ? 0
            : RepairInvertedTriangles(mesh_, options_.min_area_fraction, inverse_weight_, x_);
    // A round that moved nothing found every constraint met.
    if (moved == 0 && repaired == 0) return true;
    triangles_pass = repaired == 0;
  }
  // Out of rounds: constraints that are still not met end the candidate.
  if (const int t = FindInvertedTriangle(mesh_, x_); t >= 0) {
    Fail(fmt::format("triangle {} stays inverted after {} constraint iterations", t,
                     options_.constraint_iterations));
    return false;
  }
  if (const int i = FindNodeInsideDisc(discs_, x_, 1e-6); i >= 0) {
    Fail(fmt::format("node {} stays inside an obstacle after {} constraint iterations", i,
                     options_.constraint_iterations));
    return false;
  }
  return true;
}

bool Simulator::FinishFrame() {
  for (int i = 0; i < mesh_.NumNodes(); ++i) {
    const Vec2& p = x_[i];
    if ((p - rest_centroid_).squaredNorm() > divergence_radius_sq_) {
      Fail(fmt::format("node {} left the scene ({:.1f} px from the rest centroid): the state diverged",
                       i, (p - rest_centroid_).norm()));
      return false;
    }
  }
  for (EffectTerm* effect : after_frame_effects_) effect->AfterFrame(x_, scene_.frame_time_s);
  ++frame_;
  if (frame_ + 1 >= scene_.num_frames) status_ = SimulationStatus::kFinished;
  return true;
}

}  // namespace calib
