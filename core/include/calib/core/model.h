#pragma once
// The mass-spring-like model: sums the energy terms over the mesh.
//
// The sums are written for speed: rest quantities are inverted once here,
// and one pass over the edges computes each edge's vector and inverse squared
// length, which the distance and damping springs use and the triangle pass
// reuses for the angle springs (an edge is shared by two triangles). The
// kernels of energy_terms.h are the reference the tests hold these sums to.

#include "calib/core/mesh.h"
#include "calib/core/parameters.h"

#include <span>
#include <string>

namespace calib {

namespace force_kernels {
struct Stiffness;
}  // namespace force_kernels

/// The instruction sets Model::ComputeForces has kernels for. Every kernel
/// returns the same bits (same per-element operations in the same order, no
/// FMA contraction, the same fixed order of the sums into the nodes); the
/// choice changes only the speed.
enum class ForceKernel {
  kAuto,      ///< the fastest this CPU runs
  kBaseline,  ///< plain x86-64 (SSE2), or whatever the build targets
  kAvx2,      ///< AVX2, chosen at run time where the CPU has it
  kAvx512,    ///< AVX-512 (F, VL, DQ), chosen at run time where the CPU has it
};

std::string ToString(ForceKernel kernel);

/// Per-thread scratch of Model::ComputeForces, sized by the model: the
/// per-edge and per-triangle results of the vectorised passes, summed into
/// the nodes afterwards in a fixed order.
struct ForceWorkspace {
  /// Every force on a node, (2 #E + 3 #T) x 2, as blocks of (x, y) pairs:
  /// per edge the force on node j, per edge the force on node i (its exact
  /// negation), then per triangle the force on corner a, on b, on c; then
  /// one pair (+0, +0) that no pass writes, which pads the node sums.
  std::vector<double> contribution;
  // Per edge (#E).
  std::vector<double> edge_inv_length_sq;  ///< 1 / |p_j - p_i|^2 (0 if degenerate)
  std::vector<double> edge_energy;
  // Per triangle (#T).
  std::vector<double> triangle_energy;
  /// 1 where a corner angle is outside the atan series' range, so the
  /// triangle is redone with std::atan2.
  std::vector<int> triangle_needs_atan2;
};

class Model {
 public:
  /// Keeps a reference to `mesh`, which must outlive the model.
  explicit Model(const Mesh& mesh);

  const Mesh& mesh() const { return *mesh_; }

  ForceWorkspace MakeWorkspace() const;

  /// Overwrites `forces` (#N) with the internal forces at positions `x` and
  /// velocities `v` (#N each): distance, area and angle springs plus edge
  /// damping. Returns the elastic energy (damping has none). Allocates
  /// nothing. `kernel` picks the instruction set (tests compare them); a
  /// kernel the CPU lacks falls back to kBaseline.
  double ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                       std::span<const Vec2> v, std::span<Vec2> forces,
                       ForceWorkspace& workspace, ForceKernel kernel = ForceKernel::kAuto) const;

  /// As above with a temporary workspace (tests, one-off calls).
  double ComputeForces(const ModelParameters& params, std::span<const Vec2> x,
                       std::span<const Vec2> v, std::span<Vec2> forces) const;

  /// The elastic forces (no damping) with each element's stiffnesses
  /// scaled: edge e's k_D times edge_scale[e] (#E), triangle t's k_A and
  /// k_phi times triangle_scale[t] (#T), by the same kernels. Overwrites
  /// `forces`; returns the energy. A stiffness field (the uneven_stiffness
  /// effect) at the base kernels' speed. Allocates nothing.
  double ComputeScaledForces(const ModelParameters& params, std::span<const double> edge_scale,
                             std::span<const double> triangle_scale, std::span<const Vec2> x,
                             std::span<Vec2> forces, ForceWorkspace& workspace,
                             ForceKernel kernel = ForceKernel::kAuto) const;

  /// Weights each element's constants from now on: ComputeForces (and
  /// Energy) take edge e's k_D and k_d times edge_weight[e] (#E), triangle
  /// t's k_A times triangle_weight[t] and its k_phi times angle_weight[t]
  /// (#T each), by the same kernels. All empty: unweighted again. Throws
  /// std::invalid_argument when a size is wrong or a weight is not finite
  /// and > 0. ComputeScaledForces is not weighted.
  void SetElementWeights(std::span<const double> edge_weight,
                         std::span<const double> triangle_weight,
                         std::span<const double> angle_weight);

  /// Elastic energy at positions `x`.
  double Energy(const ModelParameters& params, std::span<const Vec2> x) const;

  /// The springs' rest quantities (edge lengths, triangle areas, corner
  /// angles) from the positions `rest` (#N) instead of the mesh's rest shape:
  /// the model is then at rest at `rest`. Returns -1, or the first triangle
  /// that is not positive at `rest` (the model is then left unchanged).
  int SetRestShape(std::span<const Vec2> rest);

  /// Back to the mesh's rest quantities (as constructed).
  void ResetRestShape();

  /// Whether this CPU runs `kernel` (kAuto and kBaseline: always).
  static bool IsAvailable(ForceKernel kernel);

 private:
  double RunKernel(const force_kernels::Stiffness& k, const double* edge_scale,
                   const double* triangle_scale, const double* angle_scale,
                   std::span<const Vec2> x, std::span<const Vec2> v,
                   std::span<Vec2> forces, ForceWorkspace& workspace, ForceKernel kernel) const;
  const Mesh* mesh_;
  // The mesh as flat arrays for the vectorised passes (force_kernels.h).
  std::vector<int> edge_i_, edge_j_;
  std::vector<double> rest_length_, inv_rest_length_;      ///< D0, 1 / D0 per edge
  std::vector<int> triangle_a_, triangle_b_, triangle_c_;
  std::vector<int> triangle_edge_ab_, triangle_edge_bc_, triangle_edge_ca_;
  std::vector<double> rest_area_, inv_rest_area_;          ///< A0, 1 / A0 per triangle
  std::vector<double> rest_cos_a_, rest_sin_a_, rest_cos_b_, rest_sin_b_;  ///< rest corners a, b
  // Node n's forces are ForceWorkspace::contribution pairs, in the order of
  // the plain scatter: edges in index order, then triangles in index order.
  // They are summed four nodes at a time (nodes of about as many forces
  // together; force_kernels::Arrays): group g's nodes are
  // node_group_nodes_[4 g .. 4 g + 4) (-1: none), its pairs
  // node_group_pairs_[node_group_start_[g] ..), four a slot, each node's
  // list padded with the zero pair to the group's longest.
  std::vector<int> node_group_start_, node_group_nodes_, node_group_pairs_;
  std::vector<double> edge_weight_, triangle_weight_, angle_weight_;  ///< empty: unweighted
};

/// The edge length of the lattice that area weights are relative to.
inline constexpr double kAreaWeightReferenceEdgePx = 20.0;

/// Weights that make the model's constants a material's rather than the
/// mesh's (SimulationOptions::area_weighted): each element's and node's
/// share of the rest area, over that share on the equilateral lattice of
/// kAreaWeightReferenceEdgePx edges. A triangle's weight (its area spring's)
/// is its area over the lattice triangle's; an edge's is a third of each
/// adjacent triangle's area over two thirds of the lattice triangle's (an
/// interior lattice edge has 1, a boundary one 1/2); a node's is a third of
/// each adjacent triangle's area over two lattice triangles' (an interior
/// lattice node has 1). The angle springs keep weight 1: a corner's angle
/// changes with the curvature times the element's size, so its energy per
/// area is already the same on a finer mesh of the same bend, which
/// weighting by area would undo. A mesh of that lattice's interior is thus
/// weighted 1 throughout, and the same material meshed more finely or
/// coarsely has about the same mass and stiffness per area.
struct AreaWeights {
  std::vector<double> node;      ///< #N
  std::vector<double> edge;      ///< #E
  std::vector<double> triangle;  ///< #T, the area springs
  std::vector<double> angle;     ///< #T, the angle springs (1)
};

/// The weights of `mesh` at its rest positions; with `triangle_areas` (#T),
/// the weights of triangles of those areas (px^2) instead: an object's
/// elements as measured on another recording of it.
AreaWeights ComputeAreaWeights(const Mesh& mesh, std::span<const double> triangle_areas = {});

}  // namespace calib
