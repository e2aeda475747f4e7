#include "truth_system.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace calib::synth::truth_detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// The table's normal acceleration: the weight that presses each node on it.
constexpr double kTableGravity = 9.81;
/// Steps below this many tolerances count as converged when Newton stalls.
constexpr double kLooseFactor = 100.0;

Vec6 Gather(const Eigen::VectorXd& x, const std::array<int, 3>& n) {
  Vec6 e;
  for (int a = 0; a < 3; ++a) e.segment<2>(2 * a) = x.segment<2>(2 * n[a]);
  return e;
}

// Barrier b(d) and its first two derivatives (d in metres).
struct BarrierValue {
  double b, db, ddb;
};
BarrierValue Barrier(double d, double dhat, double kappa) {
  const double t = d - dhat;
  const double l = std::log(d / dhat);
  return {-kappa * t * t * l, -kappa * (2.0 * t * l + t * t / d),
          -kappa * (2.0 * l + 4.0 * t / d - t * t / (d * d))};
}

}  // namespace

System::System(std::vector<Element> elements, Eigen::VectorXd node_mass_kg,
               std::vector<char> fixed, double barrier_distance_m, double barrier_stiffness_n_m,
               EnergyDensity density)
    : elements_(std::move(elements)),
      density_(density),
      mass_(std::move(node_mass_kg)),
      fixed_(std::move(fixed)),
      dhat_(barrier_distance_m),
      kappa_(barrier_stiffness_n_m) {
  const int n = NumNodes();
  free_index_.assign(2 * n, -1);
  for (int i = 0; i < n; ++i) {
    if (fixed_[i]) continue;
    free_index_[2 * i] = num_free_++;
    free_index_[2 * i + 1] = num_free_++;
  }
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(elements_.size() * 36 + 4 * n);
  for (int i = 0; i < n; ++i) {
    for (int a = 0; a < 2; ++a) {
      for (int b = 0; b < 2; ++b) {
        const int r = free_index_[2 * i + a], c = free_index_[2 * i + b];
        if (r >= 0 && c >= 0) triplets.emplace_back(r, c, 0.0);
      }
    }
  }
  for (const Element& e : elements_) {
    for (int a = 0; a < 6; ++a) {
      for (int b = 0; b < 6; ++b) {
        const int r = free_index_[2 * e.nodes[a / 2] + a % 2];
        const int c = free_index_[2 * e.nodes[b / 2] + b % 2];
        if (r >= 0 && c >= 0) triplets.emplace_back(r, c, 0.0);
      }
    }
  }
  hessian_.resize(num_free_, num_free_);
  hessian_.setFromTriplets(triplets.begin(), triplets.end());
  hessian_.makeCompressed();
  auto slot = [this](int row_dof, int col_dof) -> int {
    const int r = free_index_[row_dof], c = free_index_[col_dof];
    if (r < 0 || c < 0) return -1;
    const int* begin = hessian_.innerIndexPtr() + hessian_.outerIndexPtr()[c];
    const int* end = hessian_.innerIndexPtr() + hessian_.outerIndexPtr()[c + 1];
    return static_cast<int>(std::lower_bound(begin, end, r) - hessian_.innerIndexPtr());
  };
  element_slots_.resize(elements_.size());
  for (size_t t = 0; t < elements_.size(); ++t) {
    const auto& nodes = elements_[t].nodes;
    for (int a = 0; a < 6; ++a) {
      for (int b = 0; b < 6; ++b) {
        element_slots_[t][a + 6 * b] =
            slot(2 * nodes[a / 2] + a % 2, 2 * nodes[b / 2] + b % 2);
      }
    }
  }
  node_slots_.resize(n);
  for (int i = 0; i < n; ++i) {
    node_slots_[i] = {slot(2 * i, 2 * i), slot(2 * i + 1, 2 * i), slot(2 * i, 2 * i + 1),
                      slot(2 * i + 1, 2 * i + 1)};
  }
}

double System::ElasticEnergy(const Eigen::VectorXd& x, Eigen::VectorXd* gradient) const {
  double energy = 0.0;
  Vec6 g;
  for (const Element& e : elements_) {
    const Vec6 xe = Gather(x, e.nodes);
    for (int branch = 0; branch < 2; ++branch) {
      const NeoHookeanParameters& p = branch == 0 ? e.elastic : e.viscous;
      if (p.mu_pa == 0.0) continue;
      const Eigen::Matrix2d& B = branch == 0 ? e.elastic_rest_inverse : e.viscous_rest_inverse;
      const double w = TriangleEnergy(density_, xe, B, e.volume_m3, p,
                                      gradient != nullptr ? &g : nullptr, nullptr, false);
      if (!std::isfinite(w)) return kInf;
      energy += w;
      if (gradient != nullptr) {
        for (int a = 0; a < 3; ++a) gradient->segment<2>(2 * e.nodes[a]) += g.segment<2>(2 * a);
      }
    }
  }
  return energy;
}

double System::FrictionEnergy(const Eigen::VectorXd& x, const StepTerms& terms,
                              Eigen::VectorXd* gradient) const {
  if (terms.friction_coefficient <= 0.0) return 0.0;
  const double eps = terms.friction_epsilon_m;
  double energy = 0.0;
  for (int i = 0; i < NumNodes(); ++i) {
    if (fixed_[i]) continue;
    const double normal = terms.friction_coefficient * mass_[i] * kTableGravity;
    const Vec2 u = x.segment<2>(2 * i) - terms.friction_anchor_m.segment<2>(2 * i);
    const double y = u.norm();
    if (y < eps) {
      energy += normal * (y * y / eps - y * y * y / (3.0 * eps * eps) + eps / 3.0);
      if (gradient != nullptr) gradient->segment<2>(2 * i) += normal * (2.0 / eps - y / (eps * eps)) * u;
    } else {
      energy += normal * y;
      if (gradient != nullptr) gradient->segment<2>(2 * i) += (normal / y) * u;
    }
  }
  return energy;
}

double System::BarrierEnergy(const Eigen::VectorXd& x, const std::vector<Disc>& discs_m,
                             int disc, Eigen::VectorXd* gradient) const {
  double energy = 0.0;
  for (int k = 0; k < static_cast<int>(discs_m.size()); ++k) {
    if (disc >= 0 && k != disc) continue;
    const Disc& d = discs_m[k];
    for (int i = 0; i < NumNodes(); ++i) {
      const Vec2 r = x.segment<2>(2 * i) - d.centre;
      const double rho = r.norm();
      const double gap = rho - d.radius_px;  // radius in metres here
      if (gap >= dhat_) continue;
      if (!(gap > 0.0)) return kInf;
      const BarrierValue b = Barrier(gap, dhat_, kappa_);
      energy += b.b;
      if (gradient != nullptr) gradient->segment<2>(2 * i) += (b.db / rho) * r;
    }
  }
  return energy;
}

namespace {
// The smoothed friction potential f0 of a slip y >= 0 with regularisation eps,
// its derivative f1 and f1's derivative.
struct SlipValue {
  double f0, f1, df1;
};
SlipValue Slip(double y, double eps) {
  if (y < eps) {
    return {y * y / eps - y * y * y / (3.0 * eps * eps) + eps / 3.0, 2.0 * y / eps - y * y / (eps * eps),
            2.0 / eps - 2.0 * y / (eps * eps)};
  }
  return {y, 1.0, 0.0};
}
}  // namespace

double System::ContactFrictionEnergy(const Eigen::VectorXd& x, const StepTerms& terms, int disc,
                                     Eigen::VectorXd* gradient) const {
  if (terms.contact_friction_coefficient <= 0.0) return 0.0;
  double energy = 0.0;
  for (const ContactLag& c : terms.contacts) {
    if ((disc >= 0 && c.disc != disc) || fixed_[c.node]) continue;
    const double scale = terms.contact_friction_coefficient * c.normal_force_n;
    const double u = c.tangent.dot(x.segment<2>(2 * c.node) - c.anchor_m);
    const SlipValue v = Slip(std::abs(u), terms.friction_epsilon_m);
    energy += scale * v.f0;
    if (gradient != nullptr) gradient->segment<2>(2 * c.node) += scale * v.f1 * (u < 0.0 ? -1.0 : 1.0) * c.tangent;
  }
  return energy;
}

std::vector<ContactLag> System::Contacts(const Eigen::VectorXd& x, const std::vector<Disc>& discs_m,
                                         const std::vector<Vec2>& disc_motion_m) const {
  std::vector<ContactLag> contacts;
  for (int k = 0; k < static_cast<int>(discs_m.size()); ++k) {
    const Disc& d = discs_m[k];
    for (int i = 0; i < NumNodes(); ++i) {
      if (fixed_[i]) continue;
      const Vec2 r = x.segment<2>(2 * i) - d.centre;
      const double rho = r.norm();
      const double gap = rho - d.radius_px;
      if (!(gap > 0.0) || gap >= dhat_) continue;
      ContactLag c;
      c.node = i;
      c.disc = k;
      c.normal_force_n = -Barrier(gap, dhat_, kappa_).db;
      c.tangent = Vec2(-r.y(), r.x()) / rho;
      c.anchor_m = x.segment<2>(2 * i) + disc_motion_m[k];
      contacts.push_back(c);
    }
  }
  return contacts;
}

double System::Energy(const Eigen::VectorXd& x, const StepTerms& terms) const {
  const double barrier = BarrierEnergy(x, terms.discs_m, -1, nullptr);
  if (!std::isfinite(barrier)) return kInf;
  const double elastic = ElasticEnergy(x, nullptr);
  if (!std::isfinite(elastic)) return kInf;
  double energy = barrier + elastic + FrictionEnergy(x, terms, nullptr) +
                  ContactFrictionEnergy(x, terms, -1, nullptr);
  const Vec2& a = terms.body_acceleration_m_s2;
  const double inv_h2 = terms.inertia ? 1.0 / (terms.inertia_step_s * terms.inertia_step_s) : 0.0;
  for (int i = 0; i < NumNodes(); ++i) {
    if (fixed_[i]) continue;
    const Vec2 xi = x.segment<2>(2 * i);
    energy -= mass_[i] * a.dot(xi);
    if (terms.inertia) {
      energy += 0.5 * inv_h2 * mass_[i] * (xi - terms.inertia_target_m.segment<2>(2 * i)).squaredNorm();
    }
  }
  return energy;
}

void System::AddNodeBlock(int node, const Eigen::Matrix2d& block) {
  double* values = hessian_.valuePtr();
  const auto& s = node_slots_[node];
  if (s[0] < 0) return;
  values[s[0]] += block(0, 0);
  values[s[1]] += block(1, 0);
  values[s[2]] += block(0, 1);
  values[s[3]] += block(1, 1);
}

double System::Assemble(const Eigen::VectorXd& x, const StepTerms& terms,
                        Eigen::VectorXd& gradient) {
  gradient.setZero(x.size());
  double* values = hessian_.valuePtr();
  std::fill(values, values + hessian_.nonZeros(), 0.0);
  double energy = 0.0;

  // Elastic: both branches, projected element Hessians.
  Vec6 g;
  Mat6 h;
  for (size_t t = 0; t < elements_.size(); ++t) {
    const Element& e = elements_[t];
    const Vec6 xe = Gather(x, e.nodes);
    for (int branch = 0; branch < 2; ++branch) {
      const NeoHookeanParameters& p = branch == 0 ? e.elastic : e.viscous;
      if (p.mu_pa == 0.0) continue;
      const Eigen::Matrix2d& B = branch == 0 ? e.elastic_rest_inverse : e.viscous_rest_inverse;
      const double w = TriangleEnergy(density_, xe, B, e.volume_m3, p, &g, &h, true);
      if (!std::isfinite(w)) return kInf;
      energy += w;
      for (int a = 0; a < 3; ++a) gradient.segment<2>(2 * e.nodes[a]) += g.segment<2>(2 * a);
      const auto& slots = element_slots_[t];
      for (int k = 0; k < 36; ++k) {
        if (slots[k] >= 0) values[slots[k]] += h.data()[k];
      }
    }
  }

  // Per node: body force, inertia, friction, contact.
  const Vec2& a = terms.body_acceleration_m_s2;
  const double inv_h2 = terms.inertia ? 1.0 / (terms.inertia_step_s * terms.inertia_step_s) : 0.0;
  const double eps = terms.friction_epsilon_m;
  for (int i = 0; i < NumNodes(); ++i) {
    if (fixed_[i]) continue;
    const Vec2 xi = x.segment<2>(2 * i);
    energy -= mass_[i] * a.dot(xi);
    gradient.segment<2>(2 * i) -= mass_[i] * a;
    Eigen::Matrix2d block = Eigen::Matrix2d::Zero();
    if (terms.inertia) {
      const Vec2 dx = xi - terms.inertia_target_m.segment<2>(2 * i);
      energy += 0.5 * inv_h2 * mass_[i] * dx.squaredNorm();
      gradient.segment<2>(2 * i) += inv_h2 * mass_[i] * dx;
      block.diagonal().array() += inv_h2 * mass_[i];
    }
    if (terms.friction_coefficient > 0.0) {
      const double normal = terms.friction_coefficient * mass_[i] * kTableGravity;
      const Vec2 u = xi - terms.friction_anchor_m.segment<2>(2 * i);
      const double y = u.norm();
      if (y < eps) {
        const double phi = 2.0 / eps - y / (eps * eps);
        energy += normal * (y * y / eps - y * y * y / (3.0 * eps * eps) + eps / 3.0);
        gradient.segment<2>(2 * i) += normal * phi * u;
        block += normal * phi * Eigen::Matrix2d::Identity();
        if (y > 0.0) block -= (normal / (eps * eps * y)) * u * u.transpose();
      } else {
        energy += normal * y;
        gradient.segment<2>(2 * i) += (normal / y) * u;
        block += (normal / y) * (Eigen::Matrix2d::Identity() - u * u.transpose() / (y * y));
      }
    }
    for (const Disc& d : terms.discs_m) {
      const Vec2 r = xi - d.centre;
      const double rho = r.norm();
      const double gap = rho - d.radius_px;
      if (gap >= dhat_) continue;
      if (!(gap > 0.0)) return kInf;
      const BarrierValue b = Barrier(gap, dhat_, kappa_);
      const Vec2 n = r / rho;
      energy += b.b;
      gradient.segment<2>(2 * i) += b.db * n;
      // b' < 0 makes the tangential curvature b'/rho (I - n n^T) negative:
      // dropped (PSD projection); the normal curvature b'' is >= 0.
      block += std::max(b.ddb, 0.0) * n * n.transpose();
    }
    AddNodeBlock(i, block);
  }
  if (terms.contact_friction_coefficient > 0.0) {
    for (const ContactLag& c : terms.contacts) {
      if (fixed_[c.node]) continue;
      const double scale = terms.contact_friction_coefficient * c.normal_force_n;
      const double u = c.tangent.dot(x.segment<2>(2 * c.node) - c.anchor_m);
      const SlipValue v = Slip(std::abs(u), terms.friction_epsilon_m);
      energy += scale * v.f0;
      gradient.segment<2>(2 * c.node) += scale * v.f1 * (u < 0.0 ? -1.0 : 1.0) * c.tangent;
      AddNodeBlock(c.node, scale * v.df1 * c.tangent * c.tangent.transpose());
    }
  }
  for (size_t k = 0; k < fixed_.size(); ++k) {
    if (fixed_[k]) gradient.segment<2>(2 * k).setZero();
  }
  return energy;
}

bool System::PathOutsideDiscs(const Eigen::VectorXd& from, const Eigen::VectorXd& to,
                              const std::vector<Disc>& discs_m) const {
  for (const Disc& d : discs_m) {
    for (int i = 0; i < NumNodes(); ++i) {
      const Vec2 p0 = from.segment<2>(2 * i);
      const Vec2 delta = to.segment<2>(2 * i) - p0;
      const double len2 = delta.squaredNorm();
      double t = len2 > 0.0 ? (d.centre - p0).dot(delta) / len2 : 0.0;
      t = std::clamp(t, 0.0, 1.0);
      if ((p0 + t * delta - d.centre).norm() <= d.radius_px) return false;
    }
  }
  return true;
}

void System::PushOutOfDiscs(Eigen::VectorXd& x, const std::vector<Disc>& discs_m) const {
  for (const Disc& d : discs_m) {
    for (int i = 0; i < NumNodes(); ++i) {
      if (fixed_[i]) continue;
      Vec2 r = x.segment<2>(2 * i) - d.centre;
      const double rho = r.norm();
      if (rho - d.radius_px >= 0.25 * dhat_) continue;
      // A node exactly at the centre has no outward direction: pick +x.
      const Vec2 n = rho > 0.0 ? Vec2(r / rho) : Vec2(1.0, 0.0);
      x.segment<2>(2 * i) = d.centre + (d.radius_px + 0.5 * dhat_) * n;
    }
  }
}

bool System::Factorise() {
  // A tiny diagonal shift keeps rigid modes of a free body on a frictionless
  // table solvable; it grows only when the factorisation is not positive.
  double mean_diagonal = hessian_.diagonal().cwiseAbs().mean();
  if (!(mean_diagonal > 0.0)) mean_diagonal = 1.0;
  double shift = 1e-10 * mean_diagonal;
  if (!analysed_) {
    ldlt_.analyzePattern(hessian_);
    analysed_ = true;
  }
  for (int attempt = 0; attempt < 8; ++attempt, shift *= 100.0) {
    Eigen::SparseMatrix<double> shifted = hessian_;
    shifted.diagonal().array() += shift;
    ldlt_.factorize(shifted);
    if (ldlt_.info() == Eigen::Success && ldlt_.vectorD().minCoeff() > 0.0) {
      factor_shift_ = shift;
      factor_valid_ = true;
      return true;
    }
  }
  factor_valid_ = false;
  return false;
}

bool System::SolveWithStaleFactor(const Eigen::VectorXd& rhs, Eigen::VectorXd& solution) const {
  // Conjugate gradients on (H + shift) s = rhs, preconditioned by the last
  // factorisation: a few iterations while the Hessian changed little.
  constexpr int kMaxIterations = 20;
  constexpr double kRelativeResidual = 1e-8;
  solution = ldlt_.solve(rhs);
  Eigen::VectorXd r = rhs - hessian_ * solution - factor_shift_ * solution;
  const double rhs_norm = rhs.norm();
  if (!(rhs_norm > 0.0)) return true;
  Eigen::VectorXd z = ldlt_.solve(r);
  Eigen::VectorXd p = z;
  double rz = r.dot(z);
  for (int k = 0; k < kMaxIterations; ++k) {
    if (r.norm() <= kRelativeResidual * rhs_norm) return solution.allFinite();
    const Eigen::VectorXd hp = hessian_ * p + factor_shift_ * p;
    const double curvature = p.dot(hp);
    if (!(curvature > 0.0)) return false;
    const double alpha = rz / curvature;
    solution += alpha * p;
    r -= alpha * hp;
    z = ldlt_.solve(r);
    const double rz_new = r.dot(z);
    p = z + (rz_new / rz) * p;
    rz = rz_new;
  }
  return r.norm() <= kRelativeResidual * rhs_norm && solution.allFinite();
}

NewtonResult System::Minimise(Eigen::VectorXd& x, const StepTerms& terms, int max_iterations,
                              double tolerance_m) {
  NewtonResult result;
  Eigen::VectorXd gradient, g_free(num_free_), s_free, step(x.size()), trial(x.size());
  double energy = Assemble(x, terms, gradient);
  if (!std::isfinite(energy)) return result;
  double last_step = std::numeric_limits<double>::infinity();
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    for (size_t k = 0; k < free_index_.size(); ++k) {
      if (free_index_[k] >= 0) g_free[free_index_[k]] = gradient[k];
    }
    // Already balanced (e.g. nothing moved): a Jacobi estimate of the step,
    // far below the tolerance, spares the factorisation.
    const Eigen::VectorXd diagonal = hessian_.diagonal();
    if ((g_free.array().abs() / diagonal.array()).maxCoeff() < 1e-3 * tolerance_m) {
      result.converged = true;
      return result;
    }
    ++result.iterations;
    bool solved = factor_valid_ && SolveWithStaleFactor(-g_free, s_free);
    if (!solved) {
      if (!Factorise()) return result;
      s_free = ldlt_.solve(-g_free);
      solved = s_free.allFinite();
    }
    if (!solved) return result;
    step.setZero();
    double max_node_step = 0.0;
    for (int i = 0; i < NumNodes(); ++i) {
      for (int c = 0; c < 2; ++c) {
        const int f = free_index_[2 * i + c];
        if (f >= 0) step[2 * i + c] = s_free[f];
      }
      max_node_step = std::max(max_node_step, step.segment<2>(2 * i).norm());
    }
    const double slope = gradient.dot(step);
    if (max_node_step < tolerance_m && !(slope < 0.0)) {
      result.converged = true;  // at the minimum to round-off
      return result;
    }
    // Armijo backtracking; infeasible trials (inverted element, a node at or
    // through a disc) have infinite energy and are halved away.
    double alpha = 1.0;
    bool accepted = false;
    while (alpha * max_node_step > 1e-6 * tolerance_m) {
      trial = x + alpha * step;
      if (PathOutsideDiscs(x, trial, terms.discs_m)) {
        const double e = Energy(trial, terms);
        if (e <= energy + 1e-4 * alpha * slope) {
          accepted = true;
          break;
        }
      }
      alpha *= 0.5;
    }
    if (!accepted) {
      // No decrease found: converged to round-off if the step is small.
      result.converged = max_node_step < kLooseFactor * tolerance_m;
      return result;
    }
    x.swap(trial);
    energy = Assemble(x, terms, gradient);
    if (!std::isfinite(energy)) return result;
    last_step = alpha * max_node_step;
    if (alpha == 1.0 && max_node_step < tolerance_m) {
      result.converged = true;
      return result;
    }
  }
  // Out of iterations: a slow tail along a nearly neutral mode (a node
  // sliding round a disc, where the projected Hessian is stiffer than the
  // true one) still moving by less than kLooseFactor tolerances is accepted.
  result.converged = last_step < kLooseFactor * tolerance_m;
  return result;
}

}  // namespace calib::synth::truth_detail
