#pragma once
// The truth model of synthetic recordings: a 2D continuum finite-element model
// (linear triangles, compressible neo-Hookean or Hencky, plane stress with a
// thickness),
// deliberately NOT the calibrated mass-spring model, so that a calibration
// tested on its recordings cannot be trivially perfect.
//
// Units: positions in and out are image pixels; inside, everything is SI
// (mm_per_px converts). Forces are newtons, in image axes (x right, y down).
//
// Time stepping: each frame is split into `substeps` steps; each step
// minimises an incremental potential (elastic energy + friction dissipation
// potential + inertia when enabled + gravity) with a projected Newton method
// and a backtracking line search, with obstacle discs as hard constraints
// (no node inside a disc after any step). Quasi-static when inertia is off.
//
// Methods (details in src/truth_system.h):
//  - elements: linear triangles, neo_hookean.h or hencky.h (material_law.h),
//    per-element PSD projection;
//  - contact: an IPC log barrier on each node's gap to each disc, with a
//    line search that rejects any step through a disc, so gaps stay > 0; the
//    reported contact force is the barrier's (+ disc friction) force, which
//    the Newton solve balances against the internal and friction forces;
//  - table friction: the smoothed Coulomb dissipation potential of IPC
//    (linear drag below friction_regularisation_m_s), normal force m_i g;
//  - disc friction: the same, lagged (normal force from the step's start);
//  - clamps: nodes inside a clamp rectangle are fixed DOFs;
//  - inertia: BDF2 in incremental-potential form;
//  - plasticity, viscoelasticity: per-element rest stretches that flow after
//    each step (multiplicative split F U^-1, rotation-free stretch U).

#include "calib/core/mesh.h"
#include "calib/core/types.h"
#include "calib/synth/material_law.h"

#include <limits>
#include <string>
#include <vector>

namespace calib::synth {

/// A disc region of the rest shape whose stiffness is scaled.
struct StiffnessRegion {
  Vec2 centre_px = Vec2::Zero();
  double radius_px = 0.0;
  double factor = 1.0;  ///< Young's modulus multiplier inside the region
};

/// The material, with the optional effects the calibrated model lacks.
struct TruthMaterial {
  /// The hyperelastic law; both take E and nu the same way (PlaneStressLame)
  /// and agree at small strains.
  MaterialLaw law = MaterialLaw::kNeoHookean;
  double youngs_modulus_pa = 30e3;
  double poisson_ratio = 0.3;
  double thickness_m = 0.02;
  double density_kg_m3 = 40.0;

  /// Uneven stiffness, gradient: E scales linearly from (1 - g) to (1 + g)
  /// across the rest shape along `stiffness_gradient_direction`. 0: off.
  double stiffness_gradient = 0.0;
  Vec2 stiffness_gradient_direction = Vec2(1.0, 0.0);
  /// Uneven stiffness, regions.
  std::vector<StiffnessRegion> stiffness_regions;

  /// Strain stiffening: the energy density W gains
  /// stiffening_coefficient * mu * (I1 - 2 - 2 ln J)^2, fourth order in the
  /// strain, so E and nu still describe small strains (neo_hookean.h). 0: off.
  double stiffening_coefficient = 0.0;

  /// Plasticity: where the deviatoric strain exceeds plastic_yield_strain,
  /// the rest shape (plastic deformation gradient) flows towards the current
  /// shape at plastic_flow_rate_per_s, leaving a permanent set. inf: off.
  double plastic_yield_strain = std::numeric_limits<double>::infinity();
  double plastic_flow_rate_per_s = 5.0;

  /// Viscoelastic relaxation (a Maxwell branch in parallel): a share
  /// viscous_fraction of the stiffness relaxes with viscous_relaxation_time_s,
  /// so the object recovers slowly after the load is removed. 0: off.
  double viscous_fraction = 0.0;
  double viscous_relaxation_time_s = 1.0;

  bool IsValid(std::string* error) const;
};

/// The object's surroundings.
struct TruthEnvironment {
  /// Coulomb friction with the table, distributed over the nodes by their
  /// mass (regularised: drag grows linearly up to friction_regularisation_m_s).
  /// The regularisation speed must lie well below the speeds that matter (a
  /// finger moving a few mm/s): a stuck body creeps at up to this speed. At
  /// the default 0.01 mm/s a sponge held for 2 s creeps < 0.1 px.
  double friction_coefficient = 0.3;
  double friction_regularisation_m_s = 1e-5;
  /// Gravity in the image plane (a hanging object: (0, 9.81)); a body on a
  /// table seen from above has none.
  Vec2 gravity_m_s2 = Vec2::Zero();
  /// Friction between the obstacles (skin, pencil) and the object: Coulomb,
  /// regularised as the table friction, with the normal force of the start of
  /// each step (lagged). It keeps a squeezed object from sliding round the
  /// discs. >= 0; 0: frictionless discs.
  double contact_friction_coefficient = 0.8;
  /// Second-order dynamics (BDF2 with inertia); off: quasi-static.
  bool inertia = false;
  /// Extra body acceleration that holds the object in its initial, bent pose
  /// and is released at frame 0 (a hanging strip released from a bend).
  Vec2 initial_bend_m_s2 = Vec2::Zero();

  bool IsValid(std::string* error) const;
};

/// What moves the object: the fine rest mesh, obstacle discs per frame
/// (prescribed kinematics), clamps.
struct TruthScene {
  Mesh rest_mesh;             ///< pixels; at least 3x finer than the calibrated mesh
  double mm_per_px = 0.25;
  double fps = 30.0;
  int num_frames = 0;
  int substeps = 10;
  /// num_frames lists of discs, the same obstacles in the same order each frame.
  std::vector<std::vector<Disc>> obstacles;
  /// Index of the obstacle whose contact force is reported, or -1.
  int force_obstacle = -1;
  /// Nodes inside these in the rest shape are held fixed.
  std::vector<RectPx> clamps;

  bool IsValid(std::string* error) const;
};

struct TruthOptions {
  int max_newton_iterations = 50;
  /// Newton stops when the step's largest node displacement is below this.
  double tolerance_px = 1e-4;
  /// Contact barrier: a node closer than this to a disc's rim feels the
  /// log barrier b(d) = -kappa (d - dhat)^2 ln(d / dhat) (Li et al., IPC,
  /// 2020) of its gap d; the gap never reaches 0. Pixels, > 0.
  double contact_distance_px = 0.1;
  /// kappa = contact_stiffness_scale * E_max * thickness * mean edge / dhat
  /// (N/m): a node carrying a typical share of the contact load sits at
  /// about half of contact_distance_px from the rim. > 0.
  double contact_stiffness_scale = 0.1;
  /// A step whose Newton solve fails is split in halves (obstacle motion or,
  /// at frame 0, load) up to this many times before SimulateTruth throws.
  int max_step_splits = 8;
  /// Fill TruthFrame's per-node force vectors (diagnostics, tests).
  bool record_node_forces = false;

  bool IsValid(std::string* error) const;
};

/// One frame of the truth: the state after the frame's last substep.
struct TruthFrame {
  std::vector<Vec2> positions_px;   ///< #N fine-mesh nodes
  Vec2 contact_force_n = Vec2::Zero();  ///< exerted by force_obstacle on the object
  double elastic_energy_j = 0.0;
  /// Force each obstacle exerts on the object, N (#obstacles, scene order);
  /// contact_force_n is obstacle_forces_n[force_obstacle].
  std::vector<Vec2> obstacle_forces_n;
  /// Total force the table's friction exerts on the object, N.
  Vec2 friction_force_n = Vec2::Zero();
  /// Newton iterations (factorisations) this frame took, over its substeps.
  int newton_iterations = 0;
  /// With TruthOptions::record_node_forces, #N each, N: the elastic force
  /// (minus the gradient of the elastic energy, both viscoelastic branches),
  /// the table friction and the contact force (all obstacles) on each node.
  /// In a converged quasi-static step elastic + friction + contact + body
  /// forces (gravity) vanish at every free node. Empty otherwise.
  std::vector<Vec2> elastic_forces_n;
  std::vector<Vec2> friction_forces_n;
  std::vector<Vec2> contact_forces_n;
};

/// Simulates the whole scene: #num_frames frames. Frame 0 is the static
/// equilibrium of the frame-0 scene (the rest shape under gravity +
/// initial_bend_m_s2 and the frame-0 obstacles, table friction anchored at the
/// rest shape); each later frame advances `substeps` steps of 1/(fps substeps)
/// seconds with the obstacles interpolated linearly between the frames'
/// discs, initial_bend_m_s2 off, starting at rest. Dynamics use BDF2 (second
/// order, almost no numerical damping at the resolved frequencies).
/// Deterministic: the same inputs give the same bits. Throws
/// std::invalid_argument for invalid inputs and std::runtime_error (naming
/// the frame) when a step cannot be solved.
std::vector<TruthFrame> SimulateTruth(const TruthScene& scene, const TruthMaterial& material,
                                      const TruthEnvironment& environment,
                                      const TruthOptions& options = {});

}  // namespace calib::synth
