#pragma once
// The passes of Model::ComputeForces over flat arrays (private to core).
//
// Structure, for the vectoriser: (1) one branch-free loop over the edges
// gathers node positions and velocities and writes each edge's force and
// energy to the workspace; (2) one over the triangles does the same for the
// area and angle springs, with the atan series on every lane; (3) a scalar
// pass redoes the rare triangles whose angles are outside the series' range
// with std::atan2; (4) a node pass sums each node's forces from a list of
// them kept in the order of the plain scatter (edges then triangles, each in
// index order, a subtraction x - f as the identical x + (-f)), four nodes
// side by side, so the sums are those of the sequential scatter bit for bit; (5) the energies are
// summed in eight fixed interleaved partial sums.
//
// Every step is the same sequence of IEEE operations per element whatever
// the vector width, and GCC vectorises floating point only where that keeps
// the source's result (no -ffast-math; -std=c++20 means -ffp-contract=off,
// and the AVX2 kernel is compiled without FMA), so every kernel gives the
// same bits. tests/core/model_test.cpp checks this.

#include "calib/core/model.h"

namespace calib::force_kernels {

/// The mesh and scratch as raw arrays; sizes num_edges / num_triangles.
struct Arrays {
  int num_edges = 0;
  const int* edge_i = nullptr;
  const int* edge_j = nullptr;
  const double* rest_length = nullptr;
  const double* inv_rest_length = nullptr;

  int num_triangles = 0;
  const int* triangle_a = nullptr;
  const int* triangle_b = nullptr;
  const int* triangle_c = nullptr;
  const int* triangle_edge_ab = nullptr;
  const int* triangle_edge_bc = nullptr;
  const int* triangle_edge_ca = nullptr;
  const double* rest_area = nullptr;
  const double* inv_rest_area = nullptr;
  const double* rest_cos_a = nullptr;
  const double* rest_sin_a = nullptr;
  const double* rest_cos_b = nullptr;
  const double* rest_sin_b = nullptr;

  /// Per-element factors, all null or all set: edge e's k_D and k_d times
  /// edge_scale[e], triangle t's k_A times triangle_scale[t] and its k_phi
  /// times angle_scale[t] (Model::ComputeScaledForces, and a weighted
  /// model's ComputeForces).
  const double* edge_scale = nullptr;
  const double* triangle_scale = nullptr;
  const double* angle_scale = nullptr;

  /// The node pass's groups (Model::node_group_*): group g sums the nodes
  /// node_group_nodes[kNodeGroup g ..] (-1: none) side by side from the
  /// pairs node_group_pairs[node_group_start[g] .. [g + 1]) of
  /// workspace->contribution, kNodeGroup a slot.
  int num_node_groups = 0;
  const int* node_group_start = nullptr;  ///< #groups + 1
  const int* node_group_nodes = nullptr;  ///< kNodeGroup #groups
  const int* node_group_pairs = nullptr;

  ForceWorkspace* workspace = nullptr;
};

/// Nodes summed side by side in the node pass: independent chains of
/// additions, which the CPU overlaps (one node's chain alone waits on each
/// addition's latency).
inline constexpr int kNodeGroup = 4;

struct Stiffness {
  double distance = 0.0;
  double damping = 0.0;
  double area = 0.0;
  double angle = 0.0;
};

/// x, v: #N interleaved (x, y) pairs; forces: #N pairs, overwritten.
/// Returns the elastic energy.
double ComputeForcesBaseline(const Arrays& arrays, const Stiffness& k, const double* x,
                             const double* v, double* forces);
double ComputeForcesAvx2(const Arrays& arrays, const Stiffness& k, const double* x,
                         const double* v, double* forces);
double ComputeForcesAvx512(const Arrays& arrays, const Stiffness& k, const double* x,
                           const double* v, double* forces);

/// Whether the CPU (and OS) run AVX2 code; AVX-512 F, VL and DQ code.
bool CpuHasAvx2();
bool CpuHasAvx512();

}  // namespace calib::force_kernels
