#pragma once
// Runs the model over a scene frame by frame. All buffers are allocated once
// in the constructor: Reset and Advance allocate nothing (except that with
// the implicit step Reset factorises its matrix), so one Simulator per
// thread can evaluate many candidates.
//
// A simulator runs the base model, or the base model plus the effects of a
// ModelDefinition (effects.h, model_definition.h): each effect's term is
// built and sized in the constructor, configured by Reset(ParameterValues)
// and called from Substep through the hooks it declares. With no effects
// the substep is the base model's, bit for bit.

#include "calib/core/effects.h"
#include "calib/core/initial_motion.h"
#include "calib/core/integrator.h"
#include "calib/core/model.h"
#include "calib/core/model_definition.h"
#include "calib/core/scene.h"
#include "calib/core/step_contact.h"

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace calib {

class ImplicitFirstOrderStep;  // the implicit step, complete in simulator.cpp

struct SimulationOptions {
  int substeps = 10;  ///< integration steps per video frame
  IntegratorKind integrator = IntegratorKind::kFirstOrder;
  /// Rounds of (obstacles, inversion repair, clamps) after each substep.
  int constraint_iterations = 8;
  /// Obstacles keep out of the outline's edges too, not only its nodes
  /// (ProjectBoundaryOutOfDiscs): a disc narrower than the mesh's edges then
  /// presses a dent as wide as its contact instead of slipping between two
  /// boundary nodes. Off: the paper's node-only contact.
  bool outline_contact = false;
  /// Coulomb friction between the obstacles and the object (SubstepStart::
  /// friction): a squeezed object does not slide round the discs. >= 0;
  /// 0: frictionless, the paper's contact.
  double contact_friction = 0.0;
  /// Triangles are kept above this fraction of their rest area.
  double min_area_fraction = 0.05;
  /// A node farther than this many mesh diameters from the rest centroid
  /// means the state diverged.
  double divergence_diameters = 10.0;
  /// With a second-order effect (inertia): the parameters are a material's,
  /// not the mesh's. Each node's mass is `mass` times its share of the rest
  /// area, each element's constants the parameters times its share
  /// (ComputeAreaWeights, relative to the lattice of
  /// kAreaWeightReferenceEdgePx edges), and gravity pulls each node in
  /// proportion to its mass: the same object meshed differently swings the
  /// same. Without such an effect (mass is a drag) it changes nothing.
  bool area_weighted = false;

  /// False with a message naming the field, its value and the rule.
  bool IsValid(std::string* error) const;
};

enum class SimulationStatus { kRunning, kFinished, kFailed };

class Simulator {
 public:
  /// `mesh` and `scene` must outlive the simulator. `options` must be valid.
  Simulator(const Mesh& mesh, const Scene& scene, const SimulationOptions& options);

  /// The base model plus the effects of `model`, in its order. Throws
  /// std::invalid_argument naming an unknown or repeated effect. With the
  /// "inertia" effect the integrator is the damped second-order step of that
  /// effect, whatever options.integrator says.
  Simulator(const Mesh& mesh, const Scene& scene, const SimulationOptions& options,
            const ModelDefinition& model);

  // Out of line: the implicit step is an incomplete type here.
  Simulator(Simulator&&);
  ~Simulator();

  /// Back to frame 0 (the mesh's rest shape, at rest) with new parameters. Only for
  /// a simulator without effects (else std::logic_error: use the overload
  /// below, which also gives the effects their parameters).
  void Reset(const ModelParameters& params);

  /// As above, from named values: exactly the names of parameter_specs()
  /// (the base model's and every effect's), each finite and within its
  /// bounds; else ParameterError naming the parameter ("parameters: ...").
  /// Configures every effect and resets its state (allocates nothing but
  /// the implicit step's factor).
  /// With inertia, a clamped object whose scene knows its observed motion
  /// (Scene::motion) starts from it (initial_motion.h): the springs rest at
  /// the estimated equilibrium and the nodes move with the observed
  /// velocity; a failure to estimate them fails the simulation (status()).
  /// With inertia it also chooses substeps() for the candidate, or fails it
  /// when the step would need more than kMaxSubsteps.
  void Reset(const ParameterValues& values);

  /// Simulates from the current frame to the next. Returns false when the
  /// simulation has failed (now or before) or there is no next frame.
  bool Advance() {
    return Advance([](int) {});
  }

  /// As Advance(), calling after_substep(s) after each substep s that
  /// succeeded (tests use it to check constraints after every substep).
  template <class AfterSubstep>
  bool Advance(AfterSubstep&& after_substep) {
    if (status_ != SimulationStatus::kRunning) return false;
    for (int s = 0; s < substeps_; ++s) {
      if (!Substep(s)) return false;
      after_substep(s);
    }
    return FinishFrame();
  }

  /// Substep s of substeps() from the current frame towards the next,
  /// without advancing the frame (exposed for benchmarks). Returns false on
  /// failure.
  bool Substep(int substep);

  /// Steps per frame of the current candidate: options.substeps, or with
  /// the inertia effect's second-order step as many more as it needs to be
  /// stable at this candidate's stiffness (kStabilityMargin below), chosen
  /// by Reset(ParameterValues).
  int substeps() const { return substeps_; }

  /// The second-order step x += h v / (1 + h c) + h^2 M^-1 F is explicit in
  /// the springs and the edge damping: for a mode of M^-1 K rate lambda_K
  /// and of M^-1 D rate lambda_D it is stable while h^2 lambda_K + 2 h
  /// lambda_D < 4. The fastest modes (a short edge's stretch) are far
  /// faster than a swing: a strip stiff enough to swing at its video's
  /// period can need several times the paper's 10 substeps a frame, and at
  /// 10 it turns a triangle over within a frame. So each candidate with
  /// inertia takes the least number of substeps, at least options.substeps,
  /// with kStabilityMargin (h^2 lambda_K + 2 h lambda_D) <= 4, both rates
  /// estimated at frame 0 by power iteration; a candidate that would need
  /// more than kMaxSubsteps fails, saying so.
  static constexpr double kStabilityMargin = 2.0;
  static constexpr int kMaxSubsteps = 1000;

  int frame() const { return frame_; }
  SimulationStatus status() const { return status_; }
  const std::string& failure_reason() const { return failure_reason_; }
  /// Frame at which the failure happened, or -1.
  int failure_frame() const { return status_ == SimulationStatus::kFailed ? frame_ + 1 : -1; }

  const std::vector<Vec2>& positions() const { return x_; }
  const std::vector<Disc>& obstacles() const { return discs_; }
  /// 1 for nodes held by a clamp.
  const std::vector<uint8_t>& clamped() const { return clamped_; }
  const Model& model() const { return model_; }
  /// Where the springs rest: the mesh's rest shape (frame 0), or the
  /// equilibrium estimated from the observed motion (see Reset).
  std::span<const Vec2> rest_shape() const {
    return rest_shifted_ ? std::span<const Vec2>(initial_motion_.rest_shape())
                         : std::span<const Vec2>(mesh_.rest_positions);
  }
  /// Node velocities at frame 0 (zero unless started from observed motion).
  std::span<const Vec2> initial_velocities() const { return initial_motion_.velocities(); }

  const ModelDefinition& definition() const { return definition_; }
  /// The parameters Reset(ParameterValues) takes: ModelParameterSpecs(definition()).
  const std::vector<ParameterSpec>& parameter_specs() const { return parameter_specs_; }
  /// The effects' terms, in the order of definition().effects.
  const std::vector<std::unique_ptr<EffectTerm>>& effects() const { return effects_; }
  const ModelParameters& parameters() const { return params_; }
  /// Whether the integrator is the inertia effect's second-order step.
  bool second_order() const { return second_order_; }

 private:
  void ResetState();
  // Picks this candidate's step (implicit_) and factorises its matrix.
  void ConfigureIntegrator();
  void StartFromObservedMotion();
  void StepDampedSecondOrder(double h, double damping_per_s, double mass);
  // The substeps the second-order step needs to be stable for the current
  // candidate at frame 0 (see kStabilityMargin); fails it beyond
  // kMaxSubsteps.
  void ChooseStableSubsteps();
  // The largest eigenvalue of M^-1 J by power iteration, J u given by
  // apply(u, out) for movable nodes; M the nodes' masses.
  template <class Apply>
  double FastestModeRate(Apply&& apply);
  void InterpolateObstacles(double alpha);
  // The implicit step's candidate contacts (step_contacts_) at the start of
  // a substep, against the obstacles where it ends (discs_).
  void GatherStepContacts();
  // Fails the candidate where the implicit step moved a node by snap_px_
  // or more.
  bool CheckImplicitStep(int substep);
  bool ApplyConstraints();
  bool FinishFrame();
  void Fail(std::string reason);

  const Mesh& mesh_;
  const Scene& scene_;
  SimulationOptions options_;
  Model model_;
  ForceWorkspace force_workspace_;
  ModelParameters params_;
  // The parameters of the substep's force pass: params_, without the edge
  // damping where the implicit step treats it in its matrix.
  ModelParameters force_params_;

  std::vector<uint8_t> clamped_;
  std::vector<double> inverse_weight_;  // 0 for clamped nodes, 1 otherwise
  // Area weighting (SimulationOptions::area_weighted) with a second-order
  // effect: each node's mass over `mass`, and its inverse; empty otherwise.
  std::vector<double> mass_weight_, inverse_mass_weight_;
  Vec2 body_force_ = Vec2::Zero();  // the effects' UniformNodeForce at unit mass weight
  Vec2 rest_centroid_ = Vec2::Zero();
  double divergence_radius_sq_ = 0.0;

  std::vector<Vec2> x_, x_prev_, v_, f_;
  std::vector<Disc> discs_;        // obstacles at the current substep
  std::vector<Disc> discs_start_;  // obstacles at the current substep's start
  Vec2 push_ = Vec2::Zero();

  // Effects (none for the base model): the terms, and per hook the terms
  // that use it (pointers into effects_, stable under moves).
  ModelDefinition definition_;
  std::vector<ParameterSpec> parameter_specs_;
  std::vector<std::unique_ptr<EffectTerm>> effects_;
  std::vector<EffectTerm*> force_effects_, after_substep_effects_, after_frame_effects_,
      step_limit_effects_, rest_stiffness_effects_, shape_stiffness_effects_;
  std::vector<Vec2> zero_velocity_;  // #N with rest-stiffness effects
  const EffectTerm* push_effect_ = nullptr;
  const EffectTerm* dynamics_effect_ = nullptr;
  bool second_order_ = false;
  double second_order_damping_per_s_ = 0.0;
  InitialMotion initial_motion_;
  bool rest_shifted_ = false;  // model_ rests at initial_motion_.rest_shape()
  // options.integrator == kImplicitFirstOrder: the step's matrices (built in
  // the constructor), used unless an effect owns the dynamics.
  std::unique_ptr<ImplicitFirstOrderStep> implicit_step_;
  bool implicit_ = false;  // this candidate takes the implicit step
  std::vector<StepContact> step_contacts_;
  double last_step_px_ = 0.0;  // the longest node move of the last substep
  double snap_px_ = 0.0;  // half the mesh's mean rest edge length

  int substeps_ = 1;  // steps per frame of this candidate (substeps())
  // ChooseStableSubsteps' vectors (mode_still_: zero velocities).
  std::vector<Vec2> mode_u_, mode_y_, mode_still_, probe_x_, probe_f_;
  double mode_probe_px_ = 0.0;  // finite-difference step of K u

  int frame_ = 0;
  SimulationStatus status_ = SimulationStatus::kRunning;
  std::string failure_reason_;
};

}  // namespace calib
