#pragma once
// The incremental potential of one truth-model step and its projected Newton
// minimiser (private to synth; SimulateTruth drives it).
//
// Everything here is SI: positions x in metres as a 2N vector
// (x0, y0, x1, y1, ...), energies in joules, gradients in newtons. One step
// minimises
//
//   Phi(x) = sum_T E_T(x)                          elastic (neo_hookean.h, hencky.h)
//          - sum_i m_i a . x_i                     body force (gravity, bend)
//          + sum_i mu m_i g_table f0(|x_i - xa_i|) table friction (IPC 2020 eq. 21)
//          + 1/(2 h^2) |x - x_hat|^2_M             inertia (BDF2 or implicit Euler)
//          + sum_i sum_k b(gap_ik)                 disc contact barrier
//
// over the free nodes (clamped nodes keep their positions). f0 is the C1
// smoothed Coulomb potential: f0(y) = y^2/eps - y^3/(3 eps^2) + eps/3 for
// y < eps, y above, eps = friction_regularisation * h, so friction is a drag
// that grows linearly up to the regularisation speed and is Coulomb above.
// b(d) = -kappa (d - dhat)^2 ln(d / dhat) for 0 < d < dhat, 0 above, +inf for
// d <= 0: no node ever reaches a disc.

#include "calib/core/types.h"
#include "calib/synth/neo_hookean.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <array>
#include <vector>

namespace calib::synth::truth_detail {

/// One triangle with its two branches: the elastic branch (share
/// 1 - viscous_fraction, rest shape flowing plastically) and the Maxwell
/// branch (share viscous_fraction, rest shape relaxing to the current shape).
struct Element {
  std::array<int, 3> nodes{};
  Eigen::Matrix2d rest_inverse = Eigen::Matrix2d::Identity();  ///< Dm0^-1, 1/m
  double volume_m3 = 0.0;
  NeoHookeanParameters elastic;   ///< pre-scaled by the branch share
  NeoHookeanParameters viscous;   ///< zero when the branch is off
  /// Rest stretches (symmetric, positive definite, against Dm0): the branch
  /// sees F U^-1 with F = Ds Dm0^-1.
  Eigen::Matrix2d plastic_stretch = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d viscous_stretch = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d elastic_rest_inverse = Eigen::Matrix2d::Identity();  ///< Dm0^-1 Up^-1
  Eigen::Matrix2d viscous_rest_inverse = Eigen::Matrix2d::Identity();  ///< Dm0^-1 Uv^-1
};

/// A node in contact with a disc at the start of a step (lagged friction).
struct ContactLag {
  int node = 0;
  int disc = 0;
  double normal_force_n = 0.0;   ///< barrier force magnitude at the step's start
  Vec2 tangent = Vec2::Zero();   ///< unit tangent of the disc there
  Vec2 anchor_m = Vec2::Zero();  ///< node position minus the disc's motion over the step
};

/// What a step minimises besides the elastic energy.
struct StepTerms {
  std::vector<Disc> discs_m;                      ///< centre and radius in metres
  Vec2 body_acceleration_m_s2 = Vec2::Zero();
  double friction_coefficient = 0.0;              ///< mu (normal force m_i g_table)
  Eigen::VectorXd friction_anchor_m;              ///< 2N: positions at the step's start
  double friction_epsilon_m = 1e-9;               ///< regularisation speed * h
  bool inertia = false;
  Eigen::VectorXd inertia_target_m;               ///< 2N: x_hat
  double inertia_step_s = 1.0;                    ///< h of the 1/(2 h^2) |.|_M^2 term
  /// Disc-object friction, lagged (IPC 2020 sec. 5): mu_c lambda f0(|t . (x_i -
  /// anchor)|) per contact, normal force and tangent frozen at the step's start.
  double contact_friction_coefficient = 0.0;
  std::vector<ContactLag> contacts;
};

struct NewtonResult {
  bool converged = false;
  int iterations = 0;
};

class System {
 public:
  /// `fixed` (#N) marks clamped nodes; masses (#N) in kg; `density` is the
  /// material law of every element's branches (NeoHookeanDensity, ...).
  System(std::vector<Element> elements, Eigen::VectorXd node_mass_kg, std::vector<char> fixed,
         double barrier_distance_m, double barrier_stiffness_n_m, EnergyDensity density);

  int NumNodes() const { return static_cast<int>(mass_.size()); }
  std::vector<Element>& elements() { return elements_; }
  const Eigen::VectorXd& mass() const { return mass_; }
  const std::vector<char>& fixed() const { return fixed_; }
  double barrier_distance() const { return dhat_; }

  /// Phi(x); +inf when an element is inverted or a node touches a disc.
  double Energy(const Eigen::VectorXd& x, const StepTerms& terms) const;

  /// Minimises Phi from the feasible x (updated in place) with projected
  /// Newton and an Armijo backtracking line search that keeps every element's
  /// J > 0 and every node's path outside every disc. Converged when a full
  /// step moves no node more than tolerance_m (or, when the iterations run
  /// out or no decrease is found, the last step moved less than 100 of them:
  /// a slow tail along a nearly neutral mode). Newton systems are solved by
  /// CG preconditioned with the last LDLT factorisation while that takes at
  /// most 20 iterations, refactorised otherwise.
  NewtonResult Minimise(Eigen::VectorXd& x, const StepTerms& terms, int max_iterations,
                        double tolerance_m);

  // ---- individual terms (gradients ADDED to `gradient`, 2N, may be null) ----
  double ElasticEnergy(const Eigen::VectorXd& x, Eigen::VectorXd* gradient) const;
  double FrictionEnergy(const Eigen::VectorXd& x, const StepTerms& terms,
                        Eigen::VectorXd* gradient) const;
  /// Barrier of disc `disc` only (or all discs when -1).
  double BarrierEnergy(const Eigen::VectorXd& x, const std::vector<Disc>& discs_m, int disc,
                       Eigen::VectorXd* gradient) const;
  /// Lagged disc-object friction of disc `disc` only (or all when -1).
  double ContactFrictionEnergy(const Eigen::VectorXd& x, const StepTerms& terms, int disc,
                               Eigen::VectorXd* gradient) const;
  /// The contacts of x against discs_m (nodes closer than dhat), anchored so
  /// that a node moving with the disc by `disc_motion_m` (per disc) slips 0.
  std::vector<ContactLag> Contacts(const Eigen::VectorXd& x, const std::vector<Disc>& discs_m,
                                   const std::vector<Vec2>& disc_motion_m) const;

  /// Nodes inside or closer than dhat / 4 to a disc are moved radially out to
  /// dhat / 2 (free nodes only): a feasible start after the discs moved.
  void PushOutOfDiscs(Eigen::VectorXd& x, const std::vector<Disc>& discs_m) const;

 private:
  double Assemble(const Eigen::VectorXd& x, const StepTerms& terms, Eigen::VectorXd& gradient);
  bool PathOutsideDiscs(const Eigen::VectorXd& from, const Eigen::VectorXd& to,
                        const std::vector<Disc>& discs_m) const;
  void AddNodeBlock(int node, const Eigen::Matrix2d& block);
  /// LDLT of the current Hessian plus the smallest positive-making shift.
  bool Factorise();
  /// Solves with the current Hessian by CG preconditioned with the last
  /// factorisation (which may be from an earlier iteration or step).
  bool SolveWithStaleFactor(const Eigen::VectorXd& rhs, Eigen::VectorXd& solution) const;

  std::vector<Element> elements_;
  EnergyDensity density_;
  Eigen::VectorXd mass_;
  std::vector<char> fixed_;
  double dhat_;
  double kappa_;

  // Sparse Hessian on the free DOFs, pattern fixed at construction.
  std::vector<int> free_index_;                 // 2N: index among free DOFs or -1
  int num_free_ = 0;
  Eigen::SparseMatrix<double> hessian_;
  std::vector<std::array<int, 36>> element_slots_;  // value index per 6x6 entry or -1
  std::vector<std::array<int, 4>> node_slots_;      // (xx, yx, xy, yy) or -1
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;
  bool analysed_ = false;
  bool factor_valid_ = false;
  double factor_shift_ = 0.0;
};

}  // namespace calib::synth::truth_detail
