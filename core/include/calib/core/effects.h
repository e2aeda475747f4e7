#pragma once
// Effects: optional model terms beyond the paper's base model (issue 5).
//
// Each effect is a plug-in term with its own named parameters (ParameterSpec,
// bounds and units) and kernels (effect_kernels.h, gradient-checked like the
// base terms of energy_terms.h). The simulator owns one EffectTerm per
// effect of its ModelDefinition (model_definition.h) and calls it through
// the hooks it declares:
//
//   forces        AddForces: forces added to the base model's, the exact
//                 negative gradient of an energy where `energy` is set;
//   after_substep AfterSubstep: state updates after every substep;
//   after_frame   AfterFrame: state updates once per video frame (slow
//                 processes, e.g. a rest shape that drifts);
//   dynamics      SecondOrderDamping: the integrator becomes second order;
//   step_limit    LimitStep: the step is limited after integration (friction);
//   push          SplitPush: how the measured push acts on the mesh;
//   shape_stiffness AddShapeStiffness: the stiffness of the effect's edge
//                 springs at the current shape, which the implicit step
//                 takes into its matrix once a frame (stiffening springs).
//
// Life cycle, all on one thread: Bind(mesh) once (allocates every buffer),
// then per candidate Configure(values, base) and Reset(), then per substep
// the hooks. Configure, Reset and the hooks allocate nothing.
//
// Units as the base model: positions in pixels, forces in the force unit of
// the calibration (that of the sensor's readings), time in seconds.

#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "calib/core/mesh.h"
#include "calib/core/parameters.h"

namespace calib {

/// What the catalogue says about an effect.
struct EffectInfo {
  std::string name;         ///< e.g. "table_friction"
  std::string description;  ///< one line: the physics
  /// The effect's own parameters, in addition to the base model's. Names are
  /// unique over the whole catalogue and never a base parameter's name.
  std::vector<ParameterSpec> parameters;
  /// AddForces' forces are the negative gradient of the energy it reports
  /// (the tests check it by finite differences).
  bool has_energy = false;
};

/// Which hooks an effect uses; the simulator calls only those.
struct EffectHooks {
  bool forces = false;
  bool after_substep = false;
  bool after_frame = false;
  bool dynamics = false;
  bool step_limit = false;
  bool push = false;
  /// The forces are springs about the rest shape, each node's depending only
  /// on the nodes that share a mesh element with it (as the base terms').
  /// The implicit first-order step then takes their stiffness at the rest
  /// shape into its matrix, as it does the base springs': a stiffness the
  /// effect adds is then as stable as the base model's, where left explicit
  /// it would make the step overshoot by the added share every substep.
  bool rest_stiffness = false;
  /// The forces are springs along the mesh's edges whose stiffness grows
  /// with their strain (zero at rest, so `rest_stiffness` cannot hold it).
  /// The implicit first-order step re-linearises them at the start of every
  /// frame (AddShapeStiffness) and refactorises its matrix: left explicit,
  /// a spring stiffened by a deep dent overshoots every substep.
  bool shape_stiffness = false;
};

/// Where an effect adds the stiffness of its edge springs at a shape
/// (EffectTerm::AddShapeStiffness): edge `edge` of the mesh gains the axial
/// stiffness k >= 0 (force per px) along the unit vector u, i.e. the blocks
/// k u u^T of its two nodes (positive semi-definite: a spring's geometric
/// stiffness across its axis is left out, so the matrix stays definite).
class EdgeStiffnessSink {
 public:
  virtual void AddEdgeStiffness(int edge, double k, const Vec2& u) = 0;

 protected:
  ~EdgeStiffnessSink() = default;
};

/// One substep's integration, as LimitStep sees it.
struct StepInfo {
  double h_s = 0.0;           ///< substep length, s
  double mass = 1.0;          ///< node mass m (base parameter)
  bool second_order = false;  ///< x advanced by h v + h^2 F / m (inertia) instead of h F / m
};

/// The measured push at one substep, as SplitPush sees it.
struct PushInfo {
  Vec2 push = Vec2::Zero();  ///< force on the object by the force obstacle (force units)
  int contact_node = -1;     ///< node nearest the force obstacle's centre
  int num_nodes = 0;
  double translation = 0.0;  ///< tau, the base model's share
};

/// How the push acts: `node_force` on the contact node, and `spread_total`
/// spread evenly over all nodes (each gets spread_total / num_nodes).
struct PushSplit {
  Vec2 node_force = Vec2::Zero();
  Vec2 spread_total = Vec2::Zero();
};

class EffectTerm {
 public:
  virtual ~EffectTerm() = default;

  virtual const EffectInfo& info() const = 0;
  const std::string& name() const { return info().name; }
  const std::string& description() const { return info().description; }
  const std::vector<ParameterSpec>& parameter_specs() const { return info().parameters; }
  virtual EffectHooks hooks() const = 0;

  /// Sizes every buffer for `mesh`, which must outlive the effect. Called
  /// once, before anything else.
  virtual void Bind(const Mesh& mesh) = 0;

  /// Takes the effect's parameters from `values` (validated against the
  /// model's specs: every name of parameter_specs() is there and in bounds)
  /// and the base model's parameters (stiffnesses, mass) from `base`.
  virtual void Configure(const ParameterValues& values, const ModelParameters& base) = 0;

  /// Back to the state of the rest shape, at rest. Stateless effects: no-op.
  virtual void Reset() {}

  /// hooks().forces: ADDS the effect's forces at positions `x` and
  /// velocities `v` (#N each) to `forces` (#N). With `energy` non-null and
  /// info().has_energy, ADDS the effect's energy to *energy (computing it may
  /// cost more than the forces; the simulator passes nullptr).
  virtual void AddForces(std::span<const Vec2> x, std::span<const Vec2> v, std::span<Vec2> forces,
                         double* energy) const;

  /// hooks().after_substep: updates the state from the positions `x` at the
  /// end of a substep of length h_s (after the constraints).
  virtual void AfterSubstep(std::span<const Vec2> x, double h_s);

  /// hooks().after_frame: updates the state from the positions `x` at the
  /// end of a video frame of length frame_time_s (after its last substep).
  virtual void AfterFrame(std::span<const Vec2> x, double frame_time_s);

  /// The part of AddForces that is one constant force on every node
  /// (gravity's m g), force units; zero for most effects. A simulation that
  /// starts from an observed motion rests its springs where the observed
  /// shape is in equilibrium under it (Simulator::Reset).
  virtual Vec2 UniformNodeForce() const { return Vec2::Zero(); }

  /// hooks().dynamics: the velocity damping (1/s) of the second-order step
  /// the simulator switches to, x += h (v / (1 + h c)) + h^2 F / m.
  virtual std::optional<double> SecondOrderDamping() const { return std::nullopt; }

  /// hooks().step_limit: after integration, moves the nodes `x` back
  /// towards their positions `x_start` at the start of the substep. Nodes
  /// with inverse_weight 0 (clamped) are not touched.
  virtual void LimitStep(std::span<const Vec2> x_start, std::span<const double> inverse_weight,
                         std::span<Vec2> x, const StepInfo& step) const;

  /// hooks().push: how the measured push acts on the mesh.
  virtual PushSplit SplitPush(const PushInfo& push) const;

  /// hooks().shape_stiffness: adds the axial stiffness of the effect's edge
  /// springs at the positions `x` (#N) to `sink`, the derivative along
  /// each edge of its force's magnitude. Allocates nothing.
  virtual void AddShapeStiffness(std::span<const Vec2> x, EdgeStiffnessSink& sink) const;

  /// Energy of AddForces at `x` (zero velocities), with temporary buffers:
  /// for tests. 0 for an effect without energy.
  double Energy(std::span<const Vec2> x) const;
};

/// Every effect there is, in the fixed order of kEntries in
/// effect_catalogue.cpp (docs/effects.md lists them; discovery's
/// hypotheses.h traces each by its name).
const std::vector<EffectInfo>& EffectTermCatalogue();

/// Names of EffectTermCatalogue() joined by ", " (for messages).
std::string EffectNames();

/// A new, unbound effect. Throws std::invalid_argument naming `name` and
/// listing the known effects when `name` is none of them.
std::unique_ptr<EffectTerm> MakeEffect(const std::string& name);

}  // namespace calib
