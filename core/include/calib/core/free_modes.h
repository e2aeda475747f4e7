#pragma once
// The model's slowest free vibration: what sets the stiffness a model with
// inertia needs to swing at the period a video shows.
//
// With inertia every node of mass m obeys m x'' = F(x). About a rest shape
// the forces are -K u (u the displacement), and K scales with a common
// stiffness k (k_D = k_A = k_phi = k): K = k K1. The free vibrations are
// the eigenvectors of K1 and their angular frequencies omega^2 = k lambda / m
// with lambda the eigenvalues of K1. For a clamped strip the slowest is its
// swing, so a video whose object swings with period T asks for
//
//   k = m (2 pi / T)^2 / lambda_min.
//
// K1 is the Hessian of the base model's elastic energy with unit
// stiffnesses at the rest shape, probed by central differences of
// Model::ComputeForces (the model's own forces, exact to rounding at rest),
// restricted to the nodes the clamps leave free, and its smallest
// eigenvalue is found densely (Eigen::SelfAdjointEigenSolver: a few
// hundred nodes take milliseconds; it runs once per calibration).

#include "calib/core/mesh.h"
#include "calib/core/types.h"

#include <cstdint>
#include <span>

namespace calib {

/// lambda_min of K1 for `mesh` resting at `rest` (#N; e.g. the mesh's own
/// rest positions), nodes with clamped[i] != 0 held. NaN when no node is
/// free, the clamps do not hold the mesh (lambda_min ~ 0: it can move
/// rigidly) or `rest` turns a triangle over. `area_weighted`: the model of
/// SimulationOptions::area_weighted, its elements weighted and node i of
/// mass m w_i (ComputeAreaWeights), so lambda_min is that of
/// W^-1/2 K1 W^-1/2.
double SlowestModeRate(const Mesh& mesh, std::span<const uint8_t> clamped,
                       std::span<const Vec2> rest, bool area_weighted = false);

/// The common stiffness k at which nodes of `mass` swing with `period_s`:
/// mass (2 pi / period_s)^2 / rate, for rate = SlowestModeRate(...). NaN
/// when the rate is NaN or the period or mass is not positive.
double SwingStiffness(double rate, double period_s, double mass);

}  // namespace calib
