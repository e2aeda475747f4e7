#pragma once
// A second truth material: the logarithmic-strain (Hencky) hyperelastic law,
// in the plane, as a kernel with the contract of NeoHookeanDensity, so that
// the truth model's triangles (TriangleEnergy, neo_hookean.h) take either.
//
// With V the left stretch of the in-plane deformation gradient F (2 x 2,
// J = det F > 0) and lambda_1 >= lambda_2 > 0 its principal stretches,
// e_i = ln lambda_i, the energy density (J/m^3) is
//
//   W(F) = mu |dev ln V|^2 + kappa/2 (ln J)^2 + s mu psi^2
//        = mu/2 (e_1 - e_2)^2 + kappa/2 (e_1 + e_2)^2 + s mu psi^2,
//   psi  = sum_i (lambda_i^2 - 1 - 2 ln lambda_i)
//
// (Hencky 1928; Xiao & Chen 2002 in 3D, dev and tr taken in the plane).
// kappa = mu + lambda is the 2D bulk modulus of the Lame pair: with the
// plane-stress lambda* of PlaneStressLame (kappa = E / (2 (1 - nu))), small
// strains give the same linear plate as the neo-Hookean law of the same E
// and nu, W ~ mu |dev eps|^2 + kappa/2 (tr eps)^2. Large strains differ:
// Hencky's volumetric term grows only as (ln J)^2, so it resists crushing
// less than the neo-Hookean -mu ln J + lambda/2 (ln J)^2, and its shear
// stiffness falls off at large stretch. The last term is the same fourth-order
// strain stiffening as the neo-Hookean one (neo_hookean.h).
//
// Derivatives are taken in the principal stretches: F = U diag(lambda) V^T
// (closed-form 2 x 2 polar and eigen-decompositions, U, V rotations), P =
// U diag(dW/dlambda) V^T, and dP/dF = sum_ij W_ij vec(u_i v_i^T) vec(u_j v_j^T)^T
// + (W_1 + W_2)/(lambda_1 + lambda_2) t t^T + (W_1 - W_2)/(lambda_1 - lambda_2) l l^T
// with t, l the twist and flip modes vec(U [[0,-1],[1,0]] V^T)/sqrt 2 and
// vec(U [[0,1],[1,0]] V^T)/sqrt 2 (Teran et al. 2005; Smith et al. 2019). The
// flip term's quotient is evaluated in a form that stays finite and accurate
// as lambda_1 -> lambda_2. TriangleEnergy projects dP/dF to PSD for Newton.

#include "calib/synth/neo_hookean.h"

#include <Eigen/Core>

namespace calib::synth {

/// W(F) of the Hencky law above, J/m^3, with kappa = mu + lambda; stress P
/// (Pa) and dP/dF (4 x 4 on vec(F) column-major) written where not null.
/// Returns +infinity (and writes nothing) when J <= 0.
double HenckyDensity(const Eigen::Matrix2d& F, const NeoHookeanParameters& parameters,
                     Eigen::Matrix2d* stress, Eigen::Matrix4d* stress_derivative);

/// TriangleEnergy of HenckyDensity.
double HenckyTriangleEnergy(const Vec6& x, const Eigen::Matrix2d& rest_inverse, double volume_m3,
                            const NeoHookeanParameters& parameters, Vec6* gradient, Mat6* hessian,
                            bool project_hessian);

}  // namespace calib::synth
