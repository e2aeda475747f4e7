#pragma once
// What the world does to the object over a recording: obstacle discs per
// frame, the measured push, and the clamps. Built from a recording by the
// evaluator; the simulator only reads it.

#include "calib/core/mesh.h"
#include "calib/core/types.h"

#include <cstdint>

#include <vector>

namespace calib {

struct Scene {
  double frame_time_s = 1.0 / 30.0;
  int num_frames = 0;
  int num_obstacles = 0;
  /// num_frames x num_obstacles discs, frame-major.
  std::vector<Disc> obstacle_discs;
  /// Index of the obstacle whose sensor measured `forces`, or -1.
  int force_obstacle = -1;
  /// Force on the object by the force obstacle, one per frame (empty when
  /// force_obstacle is -1).
  std::vector<Vec2> forces;
  /// Nodes inside these rectangles in frame 0 are held fixed.
  std::vector<RectPx> clamps;

  /// The object's own motion as the video shows it, for a model with
  /// inertia: a clamped object that swings freely is already out of its
  /// equilibrium, and moving, in frame 0. Estimated by the evaluator from
  /// the segmentation of a recording with clamps and no obstacles
  /// (EstimateObservedMotion); unknown otherwise.
  struct ObservedMotion {
    bool known = false;
    /// Time-mean object centroid minus its frame-0 centroid: where the
    /// object swings about, relative to where it starts.
    Vec2 equilibrium_offset_px = Vec2::Zero();
    /// Velocity of the object's centroid in frame 0.
    Vec2 initial_velocity_px_s = Vec2::Zero();
    /// Per node of the prepared mesh (#N), where the evaluator tracked the
    /// mesh through the video (evaluator/shape_tracking.h): the shape the
    /// object moves about and every node's velocity at frame 0. Empty
    /// otherwise; when set they replace the estimate from the centroid.
    std::vector<Vec2> node_rest_px;
    std::vector<Vec2> node_velocity_px_s;
    /// Per node (#N), where a model started from the tracked shape starts
    /// in frame 0: the rest shape posed on frame 0's outline
    /// (evaluator/evaluation.h, SetStartPose). Empty: the mesh's positions.
    std::vector<Vec2> node_start_px;
    /// Per triangle of the prepared mesh (#T), where the mesh was carried
    /// from another recording of the object (evaluator/object_transfer.h):
    /// the triangles' areas there, px^2, which weight the masses and
    /// stiffnesses of an area-weighted model. Empty: the mesh's own.
    std::vector<double> element_area_px2;
  };
  ObservedMotion motion;

  const Disc* ObstaclesAt(int frame) const {
    return obstacle_discs.data() + static_cast<size_t>(frame) * num_obstacles;
  }
};

/// 1 for the nodes of `mesh` that lie in one of the scene's clamps in
/// frame 0 (the mesh's rest positions), 0 for the others.
std::vector<uint8_t> ClampedNodes(const Mesh& mesh, const Scene& scene);

}  // namespace calib
