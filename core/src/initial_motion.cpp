#include "calib/core/initial_motion.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace calib {
namespace {

// Conjugate gradients stop at this residual relative to the load; after the
// iteration cap a residual below kAcceptedResidual still counts as solved.
constexpr double kTolerance = 1e-9;
constexpr double kAcceptedResidual = 1e-5;

// The dense fallback's limit: 1500 free coordinates (750 free nodes) cost
// 3000 force evaluations and an LU of about 1e9 operations.
constexpr int kMaxDenseDofs = 1500;

double Dot(std::span<const Vec2> a, std::span<const Vec2> b) {
  double sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) sum += a[i].dot(b[i]);
  return sum;
}

}  // namespace

InitialMotion::InitialMotion(const Mesh& mesh, std::span<const uint8_t> clamped)
    : mesh_(mesh),
      movable_(mesh.NumNodes(), 1.0),
      node_area_(mesh.NumNodes(), 0.0),
      response_x_(mesh.NumNodes(), Vec2::Zero()),
      response_y_(mesh.NumNodes(), Vec2::Zero()),
      rest_(mesh.rest_positions),
      velocity_(mesh.NumNodes(), Vec2::Zero()),
      residual_(mesh.NumNodes(), Vec2::Zero()),
      direction_(mesh.NumNodes(), Vec2::Zero()),
      k_direction_(mesh.NumNodes(), Vec2::Zero()),
      probe_(mesh.NumNodes(), Vec2::Zero()),
      force_plus_(mesh.NumNodes(), Vec2::Zero()),
      force_minus_(mesh.NumNodes(), Vec2::Zero()),
      zero_velocity_(mesh.NumNodes(), Vec2::Zero()),
      load_field_(mesh.NumNodes(), Vec2::Zero()),
      candidate_rest_(mesh.NumNodes(), Vec2::Zero()) {
  const auto& p = mesh.rest_positions;
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    for (int corner : mesh.triangles[t]) node_area_[corner] += mesh.rest_area_px2[t] / 3.0;
    total_area_ += mesh.rest_area_px2[t];
  }
  Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  int num_clamped = 0;
  Vec2 first_clamped = Vec2::Zero();
  bool distinct = false;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    lo = lo.cwiseMin(p[i]);
    hi = hi.cwiseMax(p[i]);
    if (clamped[i] == 0) continue;
    movable_[i] = 0.0;
    if (num_clamped++ == 0) {
      first_clamped = p[i];
    } else if (p[i] != first_clamped) {
      distinct = true;
    }
  }
  applicable_ = distinct && total_area_ > 0.0;
  // A probe of 1e-5 of the mesh's size: truncation (probe / edge)^2 and
  // rounding (1e-16 x coordinates / probe) both far below the tolerance.
  probe_px_ = 1e-5 * std::max((hi - lo).norm(), 1.0);
}

Vec2 InitialMotion::AreaMean(std::span<const Vec2> field) const {
  Vec2 sum = Vec2::Zero();
  for (size_t i = 0; i < field.size(); ++i) sum += node_area_[i] * field[i];
  return sum / total_area_;
}

void InitialMotion::ApplyStiffness(const Model& model, const ModelParameters& params,
                                   std::span<const Vec2> at, std::span<const Vec2> direction,
                                   ForceWorkspace& workspace, std::span<Vec2> out) {
  double largest = 0.0;
  for (const Vec2& d : direction) largest = std::max(largest, d.cwiseAbs().maxCoeff());
  if (largest == 0.0) {
    for (Vec2& o : out) o.setZero();
    return;
  }
  const double step = probe_px_ / largest;
  const std::span<const Vec2> x0 = at;
  for (size_t i = 0; i < x0.size(); ++i) probe_[i] = x0[i] + step * direction[i];
  model.ComputeForces(params, probe_, zero_velocity_, force_plus_, workspace);
  for (size_t i = 0; i < x0.size(); ++i) probe_[i] = x0[i] - step * direction[i];
  model.ComputeForces(params, probe_, zero_velocity_, force_minus_, workspace);
  // K d = -dF/dx d, by central differences.
  const double scale = 0.5 / step;
  for (size_t i = 0; i < x0.size(); ++i) {
    out[i] = movable_[i] * scale * (force_minus_[i] - force_plus_[i]);
  }
}

bool InitialMotion::SolveResponse(const Model& model, const ModelParameters& params,
                                  std::span<const Vec2> at, const Vec2& load,
                                  ForceWorkspace& workspace, std::vector<Vec2>& u) {
  for (size_t i = 0; i < load_field_.size(); ++i) load_field_[i] = movable_[i] * load;
  return SolveLoad(model, params, at, load_field_, workspace, u);
}

bool InitialMotion::SolveLoad(const Model& model, const ModelParameters& params,
                              std::span<const Vec2> at, std::span<const Vec2> load,
                              ForceWorkspace& workspace, std::vector<Vec2>& u) {
  const size_t n = u.size();
  for (size_t i = 0; i < n; ++i) {
    u[i].setZero();
    residual_[i] = movable_[i] * load[i];
    direction_[i] = residual_[i];
  }
  double rr = Dot(residual_, residual_);
  const double load_norm = std::sqrt(rr);
  if (load_norm == 0.0) return true;
  const int max_iterations = static_cast<int>(4 * 2 * n) + 50;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    ApplyStiffness(model, params, at, direction_, workspace, k_direction_);
    const double curvature = Dot(direction_, k_direction_);
    if (!(curvature > 0.0)) return SolveLoadDense(model, params, at, load, workspace, u);
    const double alpha = rr / curvature;
    for (size_t i = 0; i < n; ++i) {
      u[i] += alpha * direction_[i];
      residual_[i] -= alpha * k_direction_[i];
    }
    const double rr_next = Dot(residual_, residual_);
    if (std::sqrt(rr_next) <= kTolerance * load_norm) return true;
    const double beta = rr_next / rr;
    rr = rr_next;
    for (size_t i = 0; i < n; ++i) direction_[i] = residual_[i] + beta * direction_[i];
  }
  if (std::sqrt(rr) <= kAcceptedResidual * load_norm) return true;
  return SolveLoadDense(model, params, at, load, workspace, u);
}

bool InitialMotion::SolveLoadDense(const Model& model, const ModelParameters& params,
                                   std::span<const Vec2> at, std::span<const Vec2> load,
                                   ForceWorkspace& workspace, std::vector<Vec2>& u) {
  std::vector<int> free_nodes;
  for (size_t i = 0; i < movable_.size(); ++i) {
    if (movable_[i] != 0.0) free_nodes.push_back(static_cast<int>(i));
  }
  const int dofs = 2 * static_cast<int>(free_nodes.size());
  if (dofs == 0 || dofs > kMaxDenseDofs) return false;
  Eigen::MatrixXd k(dofs, dofs);
  Eigen::VectorXd b(dofs);
  for (Vec2& d : direction_) d.setZero();
  for (int c = 0; c < dofs; ++c) {
    const int node = free_nodes[c / 2], axis = c % 2;
    direction_[node][axis] = 1.0;
    ApplyStiffness(model, params, at, direction_, workspace, k_direction_);
    direction_[node][axis] = 0.0;
    for (int r = 0; r < dofs; ++r) k(r, c) = k_direction_[free_nodes[r / 2]][r % 2];
    b(c) = load[node][axis];
  }
  const Eigen::FullPivLU<Eigen::MatrixXd> lu(k);
  if (!lu.isInvertible()) return false;
  const Eigen::VectorXd x = lu.solve(b);
  if (!x.allFinite() || !((k * x - b).norm() <= kAcceptedResidual * b.norm())) return false;
  for (Vec2& v : u) v.setZero();
  for (int c = 0; c < dofs; ++c) u[free_nodes[c / 2]][c % 2] = x(c);
  return true;
}

bool InitialMotion::Compute(const Model& model, const ModelParameters& params,
                            const Scene::ObservedMotion& motion, ForceWorkspace& workspace,
                            std::string* error) {
  const auto& x0 = mesh_.rest_positions;
  std::copy(x0.begin(), x0.end(), rest_.begin());
  for (Vec2& v : velocity_) v.setZero();
  from_tracked_shape_ = false;
  if (!applicable_ || !motion.known) return true;
  if (motion.node_rest_px.size() == x0.size() && motion.node_velocity_px_s.size() == x0.size()) {
    from_tracked_shape_ = true;
    std::copy(motion.node_rest_px.begin(), motion.node_rest_px.end(), rest_.begin());
    std::copy(motion.node_velocity_px_s.begin(), motion.node_velocity_px_s.end(), velocity_.begin());
    return true;
  }

  for (const auto& [load, response] :
       {std::pair{Vec2(1.0, 0.0), &response_x_}, std::pair{Vec2(0.0, 1.0), &response_y_}}) {
    if (!SolveResponse(model, params, mesh_.rest_positions, load, workspace, *response)) {
      if (error != nullptr) {
        *error = fmt::format(
            "inertia: no static response of the clamped mesh to a load along ({}, {}) (the "
            "stiffnesses k_distance = {}, k_area = {}, k_angle = {} do not hold it)",
            load.x(), load.y(), params.k_distance, params.k_area, params.k_angle);
      }
      return false;
    }
  }

  // Mean displacement per unit load, and its truncated pseudo-inverse.
  Eigen::Matrix2d compliance;
  compliance.col(0) = AreaMean(response_x_);
  compliance.col(1) = AreaMean(response_y_);
  const Eigen::JacobiSVD<Eigen::Matrix2d> svd(compliance, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector2d sigma = svd.singularValues();
  Eigen::Matrix2d inverse = Eigen::Matrix2d::Zero();
  for (int k = 0; k < 2; ++k) {
    if (sigma[k] > 0.0 && sigma[k] >= kMinRelativeCompliance * sigma[0]) {
      inverse += svd.matrixV().col(k) * svd.matrixU().col(k).transpose() / sigma[k];
    }
  }
  const Eigen::Vector2d shift = inverse * motion.equilibrium_offset_px;
  const Eigen::Vector2d speed = inverse * motion.initial_velocity_px_s;
  for (size_t i = 0; i < x0.size(); ++i) {
    rest_[i] = x0[i] + shift.x() * response_x_[i] + shift.y() * response_y_[i];
    velocity_[i] = speed.x() * response_x_[i] + speed.y() * response_y_[i];
  }
  return true;
}

bool InitialMotion::SubtractStaticResponse(Model& model, const ModelParameters& params,
                                           const Vec2& load, std::span<const double> mass_weight,
                                           ForceWorkspace& workspace, std::string* error) {
  if (load.norm() == 0.0) return true;
  // Newton's method on the rest shape R for F(S; R) + load = 0 at the seen
  // shape S (rest_ on entry): the forces' derivative in R is the stiffness
  // K at S, so each step solves K d = F(S; R) + load and moves R by -d. The
  // first step (from R = S, where F = 0) is the linear sag; the next take
  // up its nonlinearity.
  constexpr int kNewtonSteps = 3;
  constexpr double kSettledPx = 1e-3;
  const std::vector<Vec2>& seen = rest_;
  std::copy(seen.begin(), seen.end(), candidate_rest_.begin());
  for (int step = 0; step < kNewtonSteps; ++step) {
    model.ComputeForces(params, seen, zero_velocity_, force_plus_, workspace);
    for (size_t i = 0; i < seen.size(); ++i) {
      const Vec2 node_load = mass_weight.empty() ? load : mass_weight[i] * load;
      load_field_[i] = movable_[i] * (force_plus_[i] + node_load);
    }
    if (!SolveLoad(model, params, seen, load_field_, workspace, response_x_)) {
      if (error != nullptr) {
        *error = fmt::format(
            "inertia: no static response of the clamped mesh to gravity (the stiffnesses "
            "k_distance = {}, k_area = {}, k_angle = {} do not hold it)",
            params.k_distance, params.k_area, params.k_angle);
      }
      return false;
    }
    double moved = 0.0;
    for (size_t i = 0; i < seen.size(); ++i) {
      candidate_rest_[i] -= response_x_[i];
      moved = std::max(moved, response_x_[i].norm());
    }
    // A rest shape that turns a triangle over ends the steps (the halving
    // below takes over); so does one that no longer moves.
    if (model.SetRestShape(candidate_rest_) >= 0 || moved < kSettledPx) break;
  }
  // A sag so large that resting above it turns a triangle over (springs
  // too soft for the gravity): the largest share, by halves, that keeps
  // every triangle; none at all leaves the rest at the seen shape.
  constexpr int kHalvings = 10;
  double share = 1.0;
  for (int k = 0; k <= kHalvings; ++k, share *= 0.5) {
    for (size_t i = 0; i < seen.size(); ++i) {
      probe_[i] = seen[i] + share * (candidate_rest_[i] - seen[i]);
    }
    if (model.SetRestShape(probe_) < 0) {
      std::copy(probe_.begin(), probe_.end(), rest_.begin());
      return true;
    }
  }
  model.SetRestShape(rest_);
  return true;
}

double InitialMotion::LimitDeflection(Model& model) {
  const auto& x0 = mesh_.rest_positions;
  constexpr int kHalvings = 10;
  double share = 1.0;
  for (int k = 0; k < kHalvings; ++k) {
    share *= 0.5;
    for (size_t i = 0; i < x0.size(); ++i) {
      rest_[i] = x0[i] + 0.5 * (rest_[i] - x0[i]);
      velocity_[i] *= 0.5;
    }
    if (model.SetRestShape(rest_) < 0) return share;
  }
  std::copy(x0.begin(), x0.end(), rest_.begin());
  for (Vec2& v : velocity_) v.setZero();
  model.ResetRestShape();
  return 0.0;
}

}  // namespace calib
