#include "calib/evaluator/object_transfer.h"

#include "calib/evaluator/shape_tracking.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

namespace calib {
namespace {

// Registration from a start a few pixels off: more local/global rounds than
// frame-to-frame tracking needs.
constexpr int kRegistrationIterations = 400;

// Where each point of `points` lies in the triangles of `mesh` at
// `reference` (barycentric coordinates in the triangle that holds it, or,
// outside every one, in the one it is least outside of), evaluated at
// `target`: a map from one pose of the mesh to another.
std::vector<Vec2> MapThroughTriangles(const Mesh& mesh, const std::vector<Vec2>& reference,
                                      const std::vector<Vec2>& target,
                                      const std::vector<Vec2>& points) {
  std::vector<Vec2> mapped(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Vec2& p = points[i];
    double best = -std::numeric_limits<double>::infinity();
    for (const std::array<int, 3>& t : mesh.triangles) {
      const Vec2 &a = reference[t[0]], &b = reference[t[1]], &c = reference[t[2]];
      const double area = SignedArea(a, b, c);
      if (!(area > 0.0)) continue;
      const double l0 = SignedArea(p, b, c) / area;
      const double l1 = SignedArea(a, p, c) / area;
      const double l2 = 1.0 - l0 - l1;
      const double inside = std::min({l0, l1, l2});  // >= 0 inside
      if (inside > best) {
        best = inside;
        mapped[i] = l0 * target[t[0]] + l1 * target[t[1]] + l2 * target[t[2]];
      }
    }
    if (best == -std::numeric_limits<double>::infinity()) mapped[i] = p;
  }
  return mapped;
}

std::string Name(const PreparedRecording& p) { return p.recording.folder.filename().string(); }

double TotalArea(const Mesh& mesh, const std::vector<Vec2>& x) {
  double area = 0.0;
  for (const std::array<int, 3>& t : mesh.triangles) area += SignedArea(x[t[0]], x[t[1]], x[t[2]]);
  return area;
}

}  // namespace

ObjectTransfer CarryObjectModel(const PreparedRecording& from, PreparedRecording& to,
                                double motion_window_s) {
  ObjectTransfer result;
  const auto refuse = [&](const std::string& why) {
    result.reason = fmt::format("{}: its own mesh and rest shape ({})", Name(to), why);
    return result;
  };
  const Scene::ObservedMotion& source = from.scene.motion;
  const int n = from.mesh.NumNodes();
  if (source.node_rest_px.size() != static_cast<size_t>(n)) {
    return refuse(fmt::format("{} has no tracked rest shape to carry", Name(from)));
  }
  if (to.scene.motion.node_rest_px.empty()) {
    return refuse("its motion was not tracked: not an object moving by itself");
  }
  const auto same_clamps = [&] {
    if (from.scene.clamps.size() != to.scene.clamps.size()) return false;
    for (size_t k = 0; k < from.scene.clamps.size(); ++k) {
      const RectPx &a = from.scene.clamps[k], &b = to.scene.clamps[k];
      if (a.x != b.x || a.y != b.y || a.width != b.width || a.height != b.height) return false;
    }
    return true;
  };
  if (from.scene.clamps.empty() || !same_clamps()) {
    return refuse(fmt::format("not held in the clamps of {}", Name(from)));
  }
  if (to.object_masks.empty() || to.object_masks[0].Count() == 0) {
    return refuse("no object in frame 0");
  }
  // The same object rests in the same shape: each recording's own estimate
  // of its rest shape has the same area, within the estimates' spread.
  const double own_area = TotalArea(to.mesh, to.scene.motion.node_rest_px);
  const double carried_area = TotalArea(from.mesh, source.node_rest_px);
  result.rest_area_change = own_area / carried_area - 1.0;
  if (!(std::abs(result.rest_area_change) <= kMaxCarriedRestAreaChange)) {
    return refuse(fmt::format(
        "its own rest shape's area, {:.0f} px^2, is {:+.1f} % of the {:.0f} px^2 of {}'s, beyond the "
        "{:.0f} % of another recording of the same object",
        own_area, 100.0 * result.rest_area_change, carried_area, Name(from),
        100.0 * kMaxCarriedRestAreaChange));
  }

  // The start: each node of `from`'s rest shape where the same point of the
  // object lies in `to`'s own rest shape, carried to `to`'s frame 0 through
  // `to`'s own mesh. Clamped nodes stay where the clamps hold them.
  const std::vector<Vec2>& rest = source.node_rest_px;
  const std::vector<uint8_t> clamped = ClampedNodes(from.mesh, from.scene);
  std::vector<Vec2> start = MapThroughTriangles(to.mesh, to.scene.motion.node_rest_px,
                                                to.mesh.rest_positions, rest);
  for (int i = 0; i < n; ++i) {
    if (clamped[i] != 0) start[i] = rest[i];
  }
  // Registered onto `to`'s frame-0 outline, each triangle held to its rest
  // shape.
  ShapeTrackingOptions options;
  options.max_iterations = kRegistrationIterations;
  const MeshRegistration registered =
      RegisterMesh(from.mesh, clamped, start, rest, to.object_masks[0], options);
  result.outline_distance_px = registered.outline_distance_px;
  if (!(result.outline_distance_px <= kMaxCarriedOutlineDistancePx)) {
    return refuse(fmt::format(
        "the mesh of {} reaches its frame-0 outline only within {:.2f} px on average, over the {} px "
        "of another recording of the same object",
        Name(from), result.outline_distance_px, kMaxCarriedOutlineDistancePx));
  }
  const std::vector<Vec2>& x = registered.positions;
  for (int t = 0; t < from.mesh.NumTriangles(); ++t) {
    const auto& tri = from.mesh.triangles[t];
    if (!(SignedArea(x[tri[0]], x[tri[1]], x[tri[2]]) > 0.0)) {
      return refuse(fmt::format("the mesh of {} registered onto its frame 0 turns triangle {} over",
                                Name(from), t));
    }
  }

  PreparedRecording carried = to;
  carried.mesh = BuildMesh(x, from.mesh.triangles);
  carried.mesh_quality = MeasureQuality(carried.mesh);
  if (ClampedNodes(carried.mesh, carried.scene) != clamped) {
    return refuse(fmt::format("the clamps hold other nodes of the mesh of {} there", Name(from)));
  }
  TrackObservedMotion(carried, motion_window_s);
  carried.scene.motion.node_rest_px = rest;
  SetStartPose(carried);  // on the carried rest shape; the blur is `to`'s own
  carried.scene.motion.element_area_px2 =
      source.element_area_px2.empty() ? from.mesh.rest_area_px2 : source.element_area_px2;
  to = std::move(carried);
  result.carried = true;
  result.reason = fmt::format(
      "{}: another recording of the object of {} (its mesh, registered onto frame 0, reaches the "
      "outline within {:.2f} px on average): simulated with that mesh, rest shape and element "
      "areas, from its own frame-0 pose and tracked velocities",
      Name(to), Name(from), result.outline_distance_px);
  return result;
}

}  // namespace calib
