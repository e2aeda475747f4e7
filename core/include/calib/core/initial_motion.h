#pragma once
// The start of a simulation with inertia from the motion the video shows.
//
// A clamped object filmed while it swings is, in frame 0, neither at rest
// nor in its equilibrium: the mesh (the frame-0 shape) is deflected and
// moving. With the base model's rest shape at frame 0 and zero velocity, a
// second-order model would sit still. InitialMotion estimates both from
// Scene::ObservedMotion (the object's time-mean centroid offset and its
// frame-0 centroid velocity), along the object's own static responses: u_x,
// u_y solve K u = f for a uniform unit force f per movable node along x and
// y (K the stiffness at the frame-0 shape, clamped nodes fixed), so
//
//   rest shape R = X0 + a u_x + b u_y,  initial velocity v0 = p u_x + q u_y,
//
// with (a, b) and (p, q) chosen so that the area-weighted mean of the
// displacement / velocity equals the observed centroid offset / velocity.
// That is the shape a cantilever takes under a uniform load: to first order
// frame 0 is then the object held out of its equilibrium by such a load and
// released. Directions in which the mean response is stiff (compliance
// below kMinRelativeCompliance of the softest, e.g. stretching a hanging
// strip along its length) are left out: a centroid offset there is a swing's
// second-order arc, not an elastic deflection.
//
// Linear: large deflections stretch R (the linear response of a rotation);
// where a triangle turns over in R, the largest share of the deflection that
// keeps every triangle is used (LimitDeflection).
//
// Where the evaluator tracked the mesh through the video (Scene::
// ObservedMotion's node fields, evaluator/shape_tracking.h), the tracked
// rest shape and node velocities are taken as they are instead, and the
// springs rest above the tracked shape by gravity's sag
// (SubtractStaticResponse).

#include "calib/core/mesh.h"
#include "calib/core/model.h"
#include "calib/core/parameters.h"
#include "calib/core/scene.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace calib {

class InitialMotion {
 public:
  /// Mean compliances below this fraction of the largest are not used.
  static constexpr double kMinRelativeCompliance = 0.05;

  /// Sizes every buffer for `mesh` (which must outlive this); `clamped`
  /// (#N) marks the nodes the clamps hold.
  InitialMotion(const Mesh& mesh, std::span<const uint8_t> clamped);

  /// Whether the clamps hold the mesh against rigid motion (at least two
  /// distinct clamped nodes), so that K is invertible on the other nodes.
  bool applicable() const { return applicable_; }

  /// Computes rest_shape() and velocities() for `model` (whose rest must be
  /// the mesh's) with the stiffnesses of `params`. Allocates nothing.
  /// Returns false with *error set when a static response cannot be found
  /// (the conjugate gradients stall: a stiffness too low to hold the mesh).
  bool Compute(const Model& model, const ModelParameters& params,
               const Scene::ObservedMotion& motion, ForceWorkspace& workspace, std::string* error);

  /// After Compute from the tracked shape (Scene::ObservedMotion's node
  /// fields), with `model` resting at rest_shape(): moves the rest shape so
  /// that the tracked shape is the equilibrium under the force
  /// `mass_weight[i] load` on every movable node i (gravity's m g; weight 1
  /// for every node when `mass_weight` is empty), rest -= K^-1 load, K the
  /// stiffness at the tracked shape, refined by up to three Newton steps on
  /// F(S; rest) + load = 0. Where that turns a triangle over, the largest
  /// share of it by halves (none: the tracked shape). Leaves `model`
  /// resting at the new rest_shape(); the velocities stay. Returns false
  /// with *error set when K cannot be solved (a stiffness too low to hold
  /// the mesh).
  bool SubtractStaticResponse(Model& model, const ModelParameters& params, const Vec2& load,
                              std::span<const double> mass_weight, ForceWorkspace& workspace,
                              std::string* error);

  /// Whether the last Compute took the tracked shape (node fields) rather
  /// than the estimate from the centroid.
  bool from_tracked_shape() const { return from_tracked_shape_; }

  /// After Compute: scales the deflection rest_shape() - frame 0 (and the
  /// velocities alike) down by halves until model.SetRestShape(rest_shape())
  /// accepts it, and leaves `model` resting there (at frame 0 when no share
  /// of it does). Returns the share kept, in [0, 1].
  double LimitDeflection(Model& model);

  const std::vector<Vec2>& rest_shape() const { return rest_; }
  const std::vector<Vec2>& velocities() const { return velocity_; }

 private:
  // Solves K u = f (f: `direction` on every movable node) by conjugate
  // gradients, K applied as central differences of the model's forces.
  // K is taken at the positions `at` (#N). SolveLoad solves K u = load
  // (#N, zero on clamped nodes), SolveResponse for the uniform `load`.
  // Where the gradients stall (K not positive definite at a seen shape
  // under tension, or one spring kind far stiffer than the others),
  // SolveLoadDense takes over.
  bool SolveLoad(const Model& model, const ModelParameters& params, std::span<const Vec2> at,
                 std::span<const Vec2> load, ForceWorkspace& workspace, std::vector<Vec2>& u);
  // K assembled column by column from the same differences (free nodes
  // only) and solved by LU with full pivoting; false when K is singular,
  // the mesh has more than kMaxDenseDofs free coordinates or the solution
  // misses the load by more than the accepted residual. Allocates.
  bool SolveLoadDense(const Model& model, const ModelParameters& params, std::span<const Vec2> at,
                      std::span<const Vec2> load, ForceWorkspace& workspace, std::vector<Vec2>& u);
  bool SolveResponse(const Model& model, const ModelParameters& params, std::span<const Vec2> at,
                     const Vec2& direction, ForceWorkspace& workspace, std::vector<Vec2>& u);
  void ApplyStiffness(const Model& model, const ModelParameters& params, std::span<const Vec2> at,
                      std::span<const Vec2> direction, ForceWorkspace& workspace,
                      std::span<Vec2> out);
  Vec2 AreaMean(std::span<const Vec2> field) const;

  const Mesh& mesh_;
  std::vector<double> movable_;     // 1 for free nodes, 0 for clamped ones
  std::vector<double> node_area_;   // lumped area per node (a third of each triangle)
  double total_area_ = 0.0;
  double probe_px_ = 0.0;           // finite-difference step of K v
  bool applicable_ = false;
  bool from_tracked_shape_ = false;

  std::vector<Vec2> response_x_, response_y_;
  std::vector<Vec2> rest_, velocity_;
  // Conjugate-gradient and probe buffers.
  std::vector<Vec2> residual_, direction_, k_direction_, probe_, force_plus_, force_minus_,
      zero_velocity_;
  // SubtractStaticResponse's load and rest shape in the making.
  std::vector<Vec2> load_field_, candidate_rest_;
};

}  // namespace calib
