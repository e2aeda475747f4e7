#pragma once
// The object's shape in every frame: the frame-0 mesh tracked through the
// video's segmentation.
//
// A clamped object released from a bent pose is, in frame 0, neither at rest
// nor still. What a model with inertia needs to start from (its rest shape,
// every node's velocity at frame 0) is in the video: TrackMesh follows the
// mesh's nodes from frame to frame by registering the mesh to each frame's
// object outline, and EstimateNodeMotion derives the start from the tracked
// shapes.
//
// Registration, per frame (as-rigid-as-possible deformation with an
// outline-matching term, alternated to convergence):
//
//   E(x) = sum_t sum_{edges ij of t} |(x_i - x_j) - R_t (X_i - X_j)|^2
//        + w / |B| sum_{b in boundary nodes} |x_b - nearest outline point|^2
//        + w / |S| sum_{s in outline samples} |nearest mesh-outline point - s|^2
//
// X the frame-0 mesh, R_t each triangle's best rotation (the local step,
// closed form in 2D), the clamped nodes held where frame 0 has them. Both
// outline terms are needed: the first puts every boundary node on the
// outline, the second makes the mesh reach every part of it (a tip the
// nodes fell short of). The global step is one sparse symmetric solve for x
// and y together. Each frame starts from the previous frame's shape moved
// on by its velocity, so a swing of ~10 px a frame stays within reach of
// the nearest-point matches.

#include "calib/core/mesh.h"
#include "calib/core/types.h"
#include "calib/evaluator/bit_mask.h"

#include <cstdint>
#include <span>
#include <vector>

namespace calib {

struct ShapeTrackingOptions {
  /// Weight w of the outline terms against the rigidity term (whose edges
  /// each weigh 1 per px^2), scaled by the number of mesh edges so that it
  /// does not depend on the mesh's resolution.
  double outline_weight = 4.0;
  /// Local/global alternations per frame at most.
  int max_iterations = 40;
  /// A frame's registration has converged when no node moved more than
  /// this in one alternation, px.
  double tolerance_px = 0.01;
  /// Spacing of the outline samples, px.
  double sample_spacing_px = 1.0;
};

/// The mesh's node positions in frames [0, count) of `masks`.
struct TrackedShapes {
  std::vector<std::vector<Vec2>> positions;  ///< [frame][node], px; frame 0 = the mesh
  /// Mean distance of the boundary nodes to the frame's outline, px (0 for
  /// frame 0; -1 for a frame without object pixels, whose shape is the
  /// previous one moved on).
  std::vector<double> outline_distance_px;
};

/// Tracks `mesh` (frame 0's) through the first `count` frames of `masks`
/// (count <= masks.size()); nodes with clamped[i] != 0 stay put. Throws
/// std::invalid_argument for options out of range or `clamped` of the wrong
/// size.
TrackedShapes TrackMesh(const Mesh& mesh, std::span<const uint8_t> clamped,
                        std::span<const BitMask> masks, int count,
                        const ShapeTrackingOptions& options = {});

/// One registration of the mesh onto an outline.
struct MeshRegistration {
  std::vector<Vec2> positions;        ///< #N, px
  /// Mean distance of the boundary nodes to the outline, px; -1 for a mask
  /// without object pixels (the positions are then the start).
  double outline_distance_px = -1.0;
};

/// Registers `mesh` onto the outline of `mask`, from the positions `start`
/// (#N; nodes with clamped[i] != 0 stay there), the rigidity term holding
/// each triangle to its shape in `reference` (#N), rotated: TrackMesh's
/// registration of one frame, with another rest shape than frame 0's.
/// Throws std::invalid_argument as TrackMesh does, and for `start` or
/// `reference` of the wrong size.
MeshRegistration RegisterMesh(const Mesh& mesh, std::span<const uint8_t> clamped,
                              std::span<const Vec2> start, std::span<const Vec2> reference,
                              const BitMask& mask, const ShapeTrackingOptions& options = {});

/// One cycle of a swing in tracked shapes: frames [begin, end), from one
/// upward crossing of its centre through the median to the next.
struct MotionCycle {
  int begin = 0;
  int end = 0;
  /// Mean over the cycle's frames and the free nodes of the squared step
  /// from one frame to the next, px^2: a swing's energy, up to a factor.
  double mean_square_step_px2 = 0.0;
};

/// The whole cycles of the motion in `frames` (each #N positions; nodes
/// with clamped[i] != 0 left out): the free nodes' mean position projected
/// on its principal direction of motion, cut where it crosses its median
/// upwards after having been at least half a pixel below it. Empty for
/// fewer than two such crossings. Throws std::invalid_argument for a frame
/// of another size than `clamped`.
std::vector<MotionCycle> MotionCycles(std::span<const std::vector<Vec2>> frames,
                                      std::span<const uint8_t> clamped);

/// The start of a free motion, per node, from tracked shapes.
struct NodeMotion {
  /// The shape the object moves about, at rest: the shape whose edge
  /// lengths are nearest (least squares) the tracked edges' lengths at no
  /// motion, found from the tracked positions at no motion. A swing's
  /// stretch and squeeze cancel in the mean lengths to first order; a mean
  /// of positions would also shrink every part that turns back and forth
  /// (the mean of a turning vector is shorter than the vector). To second
  /// order both move with the swing's energy (a swinging strip is
  /// stretched by its own momentum, and its mean pose rises with its
  /// amplitude), so over at least three whole cycles (MotionCycles) whose
  /// energies differ (the slowest moving at most half as much as the
  /// fastest: a decaying swing) each node's mean position and each edge's
  /// mean length per cycle are fitted linearly against the cycle's mean
  /// squared step, and their intercepts at no motion are taken. Otherwise
  /// the means over the window.
  std::vector<Vec2> rest_shape_px;
  /// Each node's velocity at frame 0: slope at 0 of the least-squares
  /// quadratic through its first `velocity_frames` tracked positions.
  std::vector<Vec2> velocity_px_s;
};

/// Estimates NodeMotion from `shapes` of `mesh` (frames 0..) at `fps`: the
/// rest shape from frames [0, mean_frames), clamped nodes where they are;
/// the velocity from the first `velocity_frames` (>= 2; a line through
/// two). Throws std::invalid_argument when the shapes have fewer frames than
/// either needs or do not fit the mesh.
NodeMotion EstimateNodeMotion(const Mesh& mesh, std::span<const uint8_t> clamped,
                              const TrackedShapes& shapes, double fps, int mean_frames,
                              int velocity_frames = 5);

}  // namespace calib
