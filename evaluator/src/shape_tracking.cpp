#include "calib/evaluator/shape_tracking.h"

#include "calib/evaluator/contour.h"
#include "calib/evaluator/nearest_segment.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace calib {
namespace {

// Tolerance of the outline polygon the nodes are matched to: finer than the
// mesher's (the outline here is a target, not a mesh boundary).
constexpr double kOutlineTolerancePx = 0.5;

// A swing's cycle starts where its centre crosses the median upwards after
// having been below it by more than half a pixel: motion under the
// outline's own resolution is no swing.
constexpr double kCycleHysteresisPx = 0.5;

// The rest shape is fitted against the motion over at least this many
// whole cycles (an intercept and a slope, and one more to check them).
constexpr int kMinRestCycles = 3;

// The rotation R maximising sum_e e^T R E over the triangle's three edges
// (E at frame 0, e now): the local step of as-rigid-as-possible.
Eigen::Matrix2d BestRotation(const std::array<Vec2, 3>& rest, const std::array<Vec2, 3>& now) {
  Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
  for (int k = 0; k < 3; ++k) {
    const Vec2 e_rest = rest[k] - rest[(k + 1) % 3];
    const Vec2 e_now = now[k] - now[(k + 1) % 3];
    m += e_rest * e_now.transpose();
  }
  const double angle = std::atan2(m(0, 1) - m(1, 0), m(0, 0) + m(1, 1));
  Eigen::Matrix2d r;
  r << std::cos(angle), -std::sin(angle), std::sin(angle), std::cos(angle);
  return r;
}

class Tracker {
 public:
  Tracker(const Mesh& mesh, std::span<const uint8_t> clamped, std::span<const Vec2> reference,
          const ShapeTrackingOptions& options)
      : mesh_(mesh), reference_(reference), options_(options) {
    const int n = mesh.NumNodes();
    unknown_.assign(n, -1);
    for (int i = 0; i < n; ++i) {
      if (clamped[i] == 0) unknown_[i] = num_unknowns_++;
    }
    for (const std::vector<int>& loop : mesh.boundary_loops) {
      for (size_t k = 0; k < loop.size(); ++k) {
        boundary_segments_.push_back({loop[k], loop[(k + 1) % loop.size()]});
        if (clamped[loop[k]] == 0) boundary_nodes_.push_back(loop[k]);
      }
    }
  }

  // Registers `x` (the prediction on entry) to `outline`. Returns the mean
  // distance of the boundary nodes to the outline.
  double Register(const std::vector<Vec2>& outline, std::vector<Vec2>& x) {
    SampleOutline(outline);
    double distance = 0.0;
    for (int iteration = 0; iteration < options_.max_iterations; ++iteration) {
      const double moved = Step(x);
      if (moved <= options_.tolerance_px) break;
    }
    for (int b : boundary_nodes_) distance += std::sqrt(NearestOnOutline(x[b]).distance2);
    return boundary_nodes_.empty() ? 0.0 : distance / static_cast<double>(boundary_nodes_.size());
  }

 private:
  void SampleOutline(const std::vector<Vec2>& outline) {
    samples_.clear();
    for (size_t k = 0; k < outline.size(); ++k) {
      const Vec2& a = outline[k];
      const Vec2& b = outline[(k + 1) % outline.size()];
      const int pieces = std::max(1, static_cast<int>(std::ceil((b - a).norm() / options_.sample_spacing_px)));
      for (int p = 0; p < pieces; ++p) samples_.push_back(a + (b - a) * (static_cast<double>(p) / pieces));
    }
    outline_segments_.Build(static_cast<int>(outline.size()), [&](int k) {
      return std::pair(outline[k], outline[(k + 1) % outline.size()]);
    });
  }

  // The point of the outline SampleOutline was given nearest p.
  SegmentPoint NearestOnOutline(const Vec2& p) const { return outline_segments_.Nearest(p); }

  // One local/global alternation; returns the largest node move, px.
  double Step(std::vector<Vec2>& x) {
    triplets_.clear();
    rhs_.setZero(num_unknowns_, 2);
    // Adds weight * (sum_k c_k x_{n_k} - target)^2 for up to two nodes.
    auto add_point_term = [&](const std::array<int, 2>& nodes, const std::array<double, 2>& c,
                              const Vec2& target, double weight) {
      Vec2 fixed = target;
      for (int k = 0; k < 2; ++k) {
        if (nodes[k] >= 0 && unknown_[nodes[k]] < 0) fixed -= c[k] * x[nodes[k]];
      }
      for (int k = 0; k < 2; ++k) {
        if (nodes[k] < 0 || unknown_[nodes[k]] < 0) continue;
        const int row = unknown_[nodes[k]];
        rhs_.row(row) += weight * c[k] * fixed.transpose();
        for (int l = 0; l < 2; ++l) {
          if (nodes[l] < 0 || unknown_[nodes[l]] < 0) continue;
          triplets_.emplace_back(row, unknown_[nodes[l]], weight * c[k] * c[l]);
        }
      }
    };

    // Rigidity: every triangle edge (i, j) wants x_i - x_j = R_t (X_i - X_j),
    // X the reference shape.
    for (const std::array<int, 3>& t : mesh_.triangles) {
      const std::array<Vec2, 3> rest{reference_[t[0]], reference_[t[1]], reference_[t[2]]};
      const std::array<Vec2, 3> now{x[t[0]], x[t[1]], x[t[2]]};
      const Eigen::Matrix2d r = BestRotation(rest, now);
      for (int k = 0; k < 3; ++k) {
        const int i = t[k], j = t[(k + 1) % 3];
        add_point_term({i, j}, {1.0, -1.0}, r * (rest[k] - rest[(k + 1) % 3]), 1.0);
      }
    }
    const double scale = options_.outline_weight * mesh_.NumEdges();
    // Every boundary node onto the outline.
    if (!boundary_nodes_.empty()) {
      const double weight = scale / static_cast<double>(boundary_nodes_.size());
      for (int b : boundary_nodes_) {
        add_point_term({b, -1}, {1.0, 0.0}, NearestOnOutline(x[b]).point, weight);
      }
    }
    // The mesh's outline onto every outline sample.
    if (!samples_.empty()) {
      const double weight = scale / static_cast<double>(samples_.size());
      mesh_segments_.Build(static_cast<int>(boundary_segments_.size()), [&](int k) {
        return std::pair(x[boundary_segments_[k][0]], x[boundary_segments_[k][1]]);
      });
      for (const Vec2& s : samples_) {
        const SegmentPoint q = mesh_segments_.Nearest(s);
        const std::array<int, 2>& seg = boundary_segments_[q.segment];
        add_point_term(seg, {1.0 - q.share, q.share}, s, weight);
      }
    }

    matrix_.resize(num_unknowns_, num_unknowns_);
    matrix_.setFromTriplets(triplets_.begin(), triplets_.end());
    if (!analysed_) {
      solver_.analyzePattern(matrix_);
      analysed_ = true;
    }
    solver_.factorize(matrix_);
    if (solver_.info() != Eigen::Success) return 0.0;  // keep x: nothing anchors it
    const Eigen::MatrixXd solution = solver_.solve(rhs_);
    double moved = 0.0;
    for (size_t i = 0; i < x.size(); ++i) {
      if (unknown_[i] < 0) continue;
      const Vec2 next = solution.row(unknown_[i]).transpose();
      moved = std::max(moved, (next - x[i]).norm());
      x[i] = next;
    }
    return moved;
  }

  const Mesh& mesh_;
  std::span<const Vec2> reference_;  // #N: the shape each triangle is held to
  ShapeTrackingOptions options_;
  std::vector<int> unknown_;  // node -> unknown index, -1 for clamped nodes
  int num_unknowns_ = 0;
  std::vector<std::array<int, 2>> boundary_segments_;
  std::vector<int> boundary_nodes_;  // boundary nodes that are not clamped
  std::vector<Vec2> samples_;
  NearestSegment outline_segments_;  // the outline's, as SampleOutline last had it
  NearestSegment mesh_segments_;     // the mesh boundary's, at this Step's positions
  std::vector<Eigen::Triplet<double>> triplets_;
  Eigen::MatrixXd rhs_;
  Eigen::SparseMatrix<double> matrix_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver_;
  bool analysed_ = false;
};

// Throws std::invalid_argument, naming the culprit, for options out of
// range or a clamp list that does not fit the mesh.
void CheckTrackingArguments(const Mesh& mesh, std::span<const uint8_t> clamped,
                            const ShapeTrackingOptions& options) {
  if (!(options.outline_weight > 0.0) || !std::isfinite(options.outline_weight)) {
    throw std::invalid_argument(fmt::format(
        "shape tracking: outline_weight must be positive and finite, got {}", options.outline_weight));
  }
  if (options.max_iterations < 1) {
    throw std::invalid_argument(fmt::format(
        "shape tracking: max_iterations must be at least 1, got {}", options.max_iterations));
  }
  if (!(options.sample_spacing_px > 0.0) || !std::isfinite(options.sample_spacing_px)) {
    throw std::invalid_argument(fmt::format(
        "shape tracking: sample_spacing_px must be positive and finite, got {}",
        options.sample_spacing_px));
  }
  if (clamped.size() != static_cast<size_t>(mesh.NumNodes())) {
    throw std::invalid_argument(fmt::format("shape tracking: {} clamp flags for a mesh of {} nodes",
                                            clamped.size(), mesh.NumNodes()));
  }
}

}  // namespace

MeshRegistration RegisterMesh(const Mesh& mesh, std::span<const uint8_t> clamped,
                              std::span<const Vec2> start, std::span<const Vec2> reference,
                              const BitMask& mask, const ShapeTrackingOptions& options) {
  CheckTrackingArguments(mesh, clamped, options);
  const size_t n = static_cast<size_t>(mesh.NumNodes());
  if (start.size() != n || reference.size() != n) {
    throw std::invalid_argument(fmt::format(
        "shape registration: a start of {} and a reference shape of {} nodes for a mesh of {} nodes",
        start.size(), reference.size(), n));
  }
  MeshRegistration result;
  result.positions.assign(start.begin(), start.end());
  if (mask.Count() == 0) return result;
  Tracker tracker(mesh, clamped, reference, options);
  result.outline_distance_px =
      tracker.Register(ObjectOutline(mask, kOutlineTolerancePx), result.positions);
  return result;
}

TrackedShapes TrackMesh(const Mesh& mesh, std::span<const uint8_t> clamped,
                        std::span<const BitMask> masks, int count,
                        const ShapeTrackingOptions& options) {
  CheckTrackingArguments(mesh, clamped, options);
  if (count < 1 || static_cast<size_t>(count) > masks.size()) {
    throw std::invalid_argument(
        fmt::format("shape tracking: {} frames asked of a recording of {}", count, masks.size()));
  }
  TrackedShapes tracked;
  tracked.positions.reserve(count);
  tracked.outline_distance_px.reserve(count);
  tracked.positions.push_back(mesh.rest_positions);
  tracked.outline_distance_px.push_back(0.0);
  Tracker tracker(mesh, clamped, mesh.rest_positions, options);
  for (int f = 1; f < count; ++f) {
    const std::vector<Vec2>& last = tracked.positions[f - 1];
    std::vector<Vec2> x = last;
    if (f >= 2) {  // moved on by the last frame's velocity
      const std::vector<Vec2>& before = tracked.positions[f - 2];
      for (size_t i = 0; i < x.size(); ++i) {
        if (clamped[i] == 0) x[i] += last[i] - before[i];
      }
    }
    double distance = -1.0;
    if (masks[f].Count() > 0) {
      distance = tracker.Register(ObjectOutline(masks[f], kOutlineTolerancePx), x);
    }
    tracked.positions.push_back(std::move(x));
    tracked.outline_distance_px.push_back(distance);
  }
  return tracked;
}

namespace {

// The positions whose edge lengths are nearest `lengths` in least squares,
// from `x` (clamped nodes stay): stress majorisation (SMACOF; Gansner,
// Koren & North 2004), which lowers sum_e (|x_i - x_j| - L_e)^2 every
// round. Each round is one solve with the mesh's edge Laplacian.
void EmbedLengths(const Mesh& mesh, std::span<const uint8_t> clamped,
                  const std::vector<double>& lengths, std::vector<Vec2>& x) {
  constexpr int kRounds = 200;
  constexpr double kTolerancePx = 1e-6;
  const int n = mesh.NumNodes();
  std::vector<int> unknown(n, -1);
  int num_unknowns = 0;
  for (int i = 0; i < n; ++i) {
    if (clamped[i] == 0) unknown[i] = num_unknowns++;
  }
  if (num_unknowns == 0) return;
  std::vector<Eigen::Triplet<double>> triplets;
  for (const std::array<int, 2>& e : mesh.edges) {
    for (int k = 0; k < 2; ++k) {
      const int row = unknown[e[k]];
      if (row < 0) continue;
      triplets.emplace_back(row, row, 1.0);
      if (unknown[e[1 - k]] >= 0) triplets.emplace_back(row, unknown[e[1 - k]], -1.0);
    }
  }
  Eigen::SparseMatrix<double> laplacian(num_unknowns, num_unknowns);
  laplacian.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(laplacian);
  if (solver.info() != Eigen::Success) return;  // a part no clamp holds: keep x
  Eigen::MatrixXd rhs(num_unknowns, 2);
  for (int round = 0; round < kRounds; ++round) {
    rhs.setZero();
    for (size_t k = 0; k < mesh.edges.size(); ++k) {
      const int i = mesh.edges[k][0], j = mesh.edges[k][1];
      const Vec2 d = x[i] - x[j];
      const double length = d.norm();
      const Vec2 target = length > 0.0 ? Vec2(d * (lengths[k] / length)) : Vec2(Vec2::Zero());
      // Row i: x_i - x_j = target; row j: x_j - x_i = -target.
      if (unknown[i] >= 0) {
        rhs.row(unknown[i]) += target.transpose();
        if (unknown[j] < 0) rhs.row(unknown[i]) += x[j].transpose();
      }
      if (unknown[j] >= 0) {
        rhs.row(unknown[j]) -= target.transpose();
        if (unknown[i] < 0) rhs.row(unknown[j]) += x[i].transpose();
      }
    }
    const Eigen::MatrixXd solution = solver.solve(rhs);
    double moved = 0.0;
    for (int i = 0; i < n; ++i) {
      if (unknown[i] < 0) continue;
      const Vec2 next = solution.row(unknown[i]).transpose();
      moved = std::max(moved, (next - x[i]).norm());
      x[i] = next;
    }
    if (moved < kTolerancePx) break;
  }
}

// The mean positions and edge lengths over `frames`.
void MeanShape(const Mesh& mesh, std::span<const std::vector<Vec2>> frames,
               std::vector<Vec2>& positions, std::vector<double>& lengths) {
  std::fill(positions.begin(), positions.end(), Vec2::Zero());
  std::fill(lengths.begin(), lengths.end(), 0.0);
  for (const std::vector<Vec2>& x : frames) {
    for (size_t i = 0; i < positions.size(); ++i) positions[i] += x[i];
    for (size_t k = 0; k < lengths.size(); ++k) {
      lengths[k] += (x[mesh.edges[k][0]] - x[mesh.edges[k][1]]).norm();
    }
  }
  const double count = static_cast<double>(frames.size());
  for (Vec2& p : positions) p /= count;
  for (double& l : lengths) l /= count;
}

}  // namespace

std::vector<MotionCycle> MotionCycles(std::span<const std::vector<Vec2>> frames,
                                      std::span<const uint8_t> clamped) {
  const int count = static_cast<int>(frames.size());
  for (int f = 0; f < count; ++f) {
    if (frames[f].size() != clamped.size()) {
      throw std::invalid_argument(fmt::format("motion cycles: frame {} has {} nodes and {} clamp flags",
                                              f, frames[f].size(), clamped.size()));
    }
  }
  if (count < 3) return {};
  // The free nodes' mean position per frame, and its principal direction.
  std::vector<Vec2> centre(count, Vec2::Zero());
  for (int f = 0; f < count; ++f) {
    int free = 0;
    for (size_t i = 0; i < frames[f].size(); ++i) {
      if (clamped[i] != 0) continue;
      centre[f] += frames[f][i];
      ++free;
    }
    if (free > 0) centre[f] /= static_cast<double>(free);
  }
  Vec2 mean = Vec2::Zero();
  for (const Vec2& c : centre) mean += c / static_cast<double>(count);
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  for (const Vec2& c : centre) covariance += (c - mean) * (c - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(covariance);
  const Vec2 axis = eigen.eigenvectors().col(1);  // the larger eigenvalue's
  std::vector<double> along(count);
  for (int f = 0; f < count; ++f) along[f] = (centre[f] - mean).dot(axis);
  std::vector<double> sorted = along;
  std::nth_element(sorted.begin(), sorted.begin() + count / 2, sorted.end());
  const double middle = sorted[count / 2];
  // Upward crossings of the median, each after the motion went below it by
  // the hysteresis (a jitter about the median is no cycle).
  std::vector<int> crossings;
  bool below = false;
  for (int f = 0; f < count; ++f) {
    const double a = along[f] - middle;
    if (a < -kCycleHysteresisPx) below = true;
    if (below && a >= 0.0) {
      crossings.push_back(f);
      below = false;
    }
  }
  std::vector<MotionCycle> cycles;
  for (size_t k = 0; k + 1 < crossings.size(); ++k) {
    MotionCycle cycle;
    cycle.begin = crossings[k];
    cycle.end = crossings[k + 1];
    double sum = 0.0;
    int steps = 0;
    for (int f = cycle.begin; f < cycle.end; ++f) {  // f + 1 <= end < count
      double step = 0.0;
      int free = 0;
      for (size_t i = 0; i < frames[f].size(); ++i) {
        if (clamped[i] != 0) continue;
        step += (frames[f + 1][i] - frames[f][i]).squaredNorm();
        ++free;
      }
      if (free > 0) sum += step / free;
      ++steps;
    }
    cycle.mean_square_step_px2 = steps > 0 ? sum / steps : 0.0;
    cycles.push_back(cycle);
  }
  return cycles;
}

namespace {

// Each node's mean position and each edge's mean length per cycle, fitted
// against the cycle's mean squared step: the values at no motion are the
// fit's intercepts. False (nothing written) with fewer than
// kMinRestCycles cycles, or where the slowest cycle moves more than half as
// much as the fastest (the intercept would be an extrapolation beyond the
// motion's own range).
bool RestAtNoMotion(const Mesh& mesh, std::span<const std::vector<Vec2>> frames,
                    const std::vector<MotionCycle>& cycles, std::vector<Vec2>& positions,
                    std::vector<double>& lengths) {
  if (static_cast<int>(cycles.size()) < kMinRestCycles) return false;
  double slowest = std::numeric_limits<double>::infinity(), fastest = 0.0, mean_s = 0.0;
  for (const MotionCycle& c : cycles) {
    slowest = std::min(slowest, c.mean_square_step_px2);
    fastest = std::max(fastest, c.mean_square_step_px2);
    mean_s += c.mean_square_step_px2 / static_cast<double>(cycles.size());
  }
  if (!(slowest <= 0.5 * fastest)) return false;
  double spread = 0.0;
  for (const MotionCycle& c : cycles) spread += std::pow(c.mean_square_step_px2 - mean_s, 2);
  if (!(spread > 0.0)) return false;  // no motion in any cycle: nothing to fit against
  // Intercept of y against s by least squares: mean(y) - slope mean(s),
  // slope = sum (s - mean s) y / spread; so each cycle weighs
  // 1 / m - mean(s) (s_c - mean s) / spread.
  const size_t n = positions.size();
  std::vector<Vec2> cycle_positions(n);
  std::vector<double> cycle_lengths(lengths.size());
  std::fill(positions.begin(), positions.end(), Vec2::Zero());
  std::fill(lengths.begin(), lengths.end(), 0.0);
  for (const MotionCycle& c : cycles) {
    MeanShape(mesh, frames.subspan(c.begin, c.end - c.begin), cycle_positions, cycle_lengths);
    const double weight = 1.0 / static_cast<double>(cycles.size()) -
                          mean_s * (c.mean_square_step_px2 - mean_s) / spread;
    for (size_t i = 0; i < n; ++i) positions[i] += weight * cycle_positions[i];
    for (size_t k = 0; k < lengths.size(); ++k) lengths[k] += weight * cycle_lengths[k];
  }
  return true;
}

}  // namespace

NodeMotion EstimateNodeMotion(const Mesh& mesh, std::span<const uint8_t> clamped,
                              const TrackedShapes& shapes, double fps, int mean_frames,
                              int velocity_frames) {
  const int available = static_cast<int>(shapes.positions.size());
  if (mean_frames < 1 || mean_frames > available) {
    throw std::invalid_argument(fmt::format(
        "node motion: a mean over {} frames asked of {} tracked frames", mean_frames, available));
  }
  if (velocity_frames < 2 || velocity_frames > available) {
    throw std::invalid_argument(fmt::format(
        "node motion: a velocity from {} frames asked of {} tracked frames (at least 2)",
        velocity_frames, available));
  }
  if (!(fps > 0.0) || !std::isfinite(fps)) {
    throw std::invalid_argument(fmt::format("node motion: fps must be positive, got {}", fps));
  }
  const size_t n = shapes.positions.front().size();
  if (n != static_cast<size_t>(mesh.NumNodes()) || clamped.size() != n) {
    throw std::invalid_argument(fmt::format(
        "node motion: shapes of {} nodes and {} clamp flags for a mesh of {} nodes", n,
        clamped.size(), mesh.NumNodes()));
  }
  NodeMotion motion;
  motion.rest_shape_px.assign(n, Vec2::Zero());
  std::vector<double> lengths(mesh.edges.size(), 0.0);
  const std::span<const std::vector<Vec2>> frames(shapes.positions.data(),
                                                  static_cast<size_t>(mean_frames));
  const std::vector<MotionCycle> cycles = MotionCycles(frames, clamped);
  if (!RestAtNoMotion(mesh, frames, cycles, motion.rest_shape_px, lengths)) {
    // No swing that dies down to tell its share from the rest: the means
    // over the window.
    MeanShape(mesh, frames, motion.rest_shape_px, lengths);
  }
  EmbedLengths(mesh, clamped, lengths, motion.rest_shape_px);

  // Position(t) ~ c0 + c1 t + c2 t^2 per node; the velocity is c1 fps.
  const int degree = velocity_frames >= 3 ? 2 : 1;
  Eigen::MatrixXd basis(velocity_frames, degree + 1);
  for (int k = 0; k < velocity_frames; ++k) {
    for (int d = 0; d <= degree; ++d) basis(k, d) = std::pow(static_cast<double>(k), d);
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(basis);
  Eigen::MatrixXd values(velocity_frames, 2 * static_cast<Eigen::Index>(n));
  for (int k = 0; k < velocity_frames; ++k) {
    for (size_t i = 0; i < n; ++i) {
      values(k, 2 * i) = shapes.positions[k][i].x();
      values(k, 2 * i + 1) = shapes.positions[k][i].y();
    }
  }
  const Eigen::MatrixXd coefficients = qr.solve(values);
  motion.velocity_px_s.resize(n);
  for (size_t i = 0; i < n; ++i) {
    motion.velocity_px_s[i] = Vec2(coefficients(1, 2 * i), coefficients(1, 2 * i + 1)) * fps;
  }
  return motion;
}

}  // namespace calib
