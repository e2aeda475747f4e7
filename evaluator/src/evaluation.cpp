#include "calib/evaluator/evaluation.h"

#include "calib/core/enum_names.h"
#include "calib/evaluator/contour.h"
#include "calib/evaluator/mask_geometry.h"
#include "calib/evaluator/shape_tracking.h"

#include <Eigen/QR>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace calib {

bool PreparationOptions::IsValid(std::string* error) const {
  if (!segmentation.IsValid(error) || !mesher.IsValid(error)) return false;
  if (!(outline_tolerance_px >= 0.0)) {
    if (error != nullptr) {
      *error = fmt::format(
          "PreparationOptions::outline_tolerance_px = {}. Violated: outline_tolerance_px >= 0.",
          outline_tolerance_px);
    }
    return false;
  }
  if (max_frames < 0) {
    if (error != nullptr) {
      *error = fmt::format("PreparationOptions::max_frames = {}. Violated: max_frames >= 0.", max_frames);
    }
    return false;
  }
  if (!(motion_window_s > 0.0) || !std::isfinite(motion_window_s)) {
    if (error != nullptr) {
      *error = fmt::format(
          "PreparationOptions::motion_window_s = {}. Violated: motion_window_s > 0 and finite.",
          motion_window_s);
    }
    return false;
  }
  return true;
}

Scene BuildScene(const Recording& recording) {
  Scene scene;
  scene.frame_time_s = 1.0 / recording.fps;
  scene.num_frames = recording.num_frames;
  scene.num_obstacles = static_cast<int>(recording.obstacles.size());
  scene.obstacle_discs.reserve(static_cast<size_t>(scene.num_frames) * scene.num_obstacles);
  for (int f = 0; f < scene.num_frames; ++f) {
    for (const ObstacleTrack& track : recording.obstacles) {
      scene.obstacle_discs.push_back(track.discs[f]);
    }
  }
  scene.force_obstacle = recording.ForceObstacleIndex();
  if (scene.force_obstacle >= 0) scene.forces = recording.forces;
  for (const PixelRect& c : recording.clamps) {
    scene.clamps.push_back({static_cast<double>(c.x), static_cast<double>(c.y),
                            static_cast<double>(c.width), static_cast<double>(c.height)});
  }
  return scene;
}

Scene::ObservedMotion EstimateObservedMotion(const Recording& recording,
                                             std::span<const BitMask> masks) {
  Scene::ObservedMotion motion;
  if (recording.clamps.empty() || !recording.obstacles.empty() || masks.empty()) return motion;
  std::vector<std::pair<double, Vec2>> centroids;  // (frame, centroid)
  centroids.reserve(masks.size());
  for (size_t f = 0; f < masks.size(); ++f) {
    const MaskMoments moments = ComputeMoments(masks[f]);
    if (moments.area_px > 0) centroids.emplace_back(static_cast<double>(f), moments.centroid_px);
  }
  if (centroids.empty() || centroids.front().first != 0.0) return motion;
  const Vec2 start = centroids.front().second;
  Vec2 mean = Vec2::Zero();
  for (const auto& [frame, c] : centroids) mean += c - start;
  motion.equilibrium_offset_px = mean / static_cast<double>(centroids.size());

  // Centroid(t) ~ c0 + c1 t + c2 t^2 over the first frames; velocity = c1 fps.
  const int num_fit = static_cast<int>(std::min<size_t>(5, centroids.size()));
  if (num_fit >= 2) {
    const int degree = num_fit >= 3 ? 2 : 1;
    Eigen::MatrixXd basis(num_fit, degree + 1);
    Eigen::MatrixXd values(num_fit, 2);
    for (int k = 0; k < num_fit; ++k) {
      const double t = centroids[k].first;
      for (int d = 0; d <= degree; ++d) basis(k, d) = std::pow(t, d);
      values.row(k) = centroids[k].second.transpose();
    }
    const Eigen::MatrixXd coefficients = basis.colPivHouseholderQr().solve(values);
    motion.initial_velocity_px_s = coefficients.row(1).transpose() * recording.fps;
  }
  motion.known = true;
  return motion;
}

PreparedRecording FirstFrames(const PreparedRecording& prepared, int frames) {
  if (frames < 1) {
    throw std::invalid_argument(fmt::format("FirstFrames: {} frames asked; at least 1", frames));
  }
  PreparedRecording cut = prepared;
  const int n = std::min(frames, prepared.scene.num_frames);
  cut.object_masks.resize(n);
  cut.scene.num_frames = n;
  cut.scene.obstacle_discs.resize(static_cast<size_t>(n) * cut.scene.num_obstacles);
  if (!cut.scene.forces.empty()) cut.scene.forces.resize(n);
  Recording& rec = cut.recording;
  rec.num_frames = n;
  for (ObstacleTrack& track : rec.obstacles) {
    if (track.discs.size() > static_cast<size_t>(n)) track.discs.resize(n);
  }
  if (rec.forces.size() > static_cast<size_t>(n)) rec.forces.resize(n);
  return cut;
}

void TrackObservedMotion(PreparedRecording& prepared, double window_s) {
  Scene::ObservedMotion& motion = prepared.scene.motion;
  const Mesh& mesh = prepared.mesh;
  const std::vector<uint8_t> clamped = ClampedNodes(mesh, prepared.scene);
  const double fps = prepared.recording.fps;
  const int available = static_cast<int>(prepared.object_masks.size());
  if (available < 2) return;
  const int window = std::clamp(static_cast<int>(std::lround(window_s * fps)), 2, available);
  const TrackedShapes tracked = TrackMesh(mesh, clamped, prepared.object_masks, window);
  NodeMotion node = EstimateNodeMotion(mesh, clamped, tracked, fps, window, std::min(window, 5));
  motion.node_rest_px = std::move(node.rest_shape_px);
  motion.node_velocity_px_s = std::move(node.velocity_px_s);
}

PreparedRecording PrepareRecording(const Recording& recording, const PreparationOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  PreparedRecording prepared;
  prepared.recording = recording;
  prepared.object_masks = SegmentRecording(recording, options.segmentation, options.cache_dir);
  if (prepared.object_masks.empty() || prepared.object_masks[0].Count() == 0) {
    throw std::invalid_argument(fmt::format(
        "{}: no object found in frame 0 with the HSV range of recording.json (object.color_hsv_*)",
        recording.video_path.string()));
  }
  prepared.outline = ObjectOutline(prepared.object_masks[0], options.outline_tolerance_px);
  prepared.scene = BuildScene(recording);
  // The clamps' edges are lines of the mesh: what a clamp holds ends on them.
  MesherOptions mesher = options.mesher;
  mesher.held_regions.insert(mesher.held_regions.end(), prepared.scene.clamps.begin(),
                             prepared.scene.clamps.end());
  prepared.mesh = MeshPolygon(prepared.outline, mesher);
  prepared.mesh_quality = MeasureQuality(prepared.mesh);
  prepared.scene.motion = EstimateObservedMotion(recording, prepared.object_masks);
  if (prepared.scene.motion.known && options.track_motion) {
    TrackObservedMotion(prepared, options.motion_window_s);
  }
  if (options.max_frames > 0 && options.max_frames < prepared.scene.num_frames) {
    prepared = FirstFrames(prepared, options.max_frames);
  }
  return prepared;
}

namespace {

constexpr auto kEvaluationStatusNames = std::to_array<EnumName<EvaluationStatus>>({
    {EvaluationStatus::kOk, "ok"},
    {EvaluationStatus::kFailed, "failed"},
    {EvaluationStatus::kStopped, "stopped"},
});

}  // namespace

std::string ToString(EvaluationStatus status) { return EnumToString(kEvaluationStatusNames, status); }

Evaluator::Evaluator(const PreparedRecording& prepared, const SimulationOptions& options)
    : prepared_(prepared),
      simulator_(prepared.mesh, prepared.scene, options),
      mesh_mask_(prepared.object_masks.at(0)) {}

Evaluator::Evaluator(const PreparedRecording& prepared, const SimulationOptions& options,
                     const ModelDefinition& model)
    : prepared_(prepared),
      simulator_(prepared.mesh, prepared.scene, options, model),
      mesh_mask_(prepared.object_masks.at(0)) {}

FrameScore Evaluator::ScoreFrame(int frame) {
  rasterizer_.RasterizeMeshCoverage(prepared_.mesh, simulator_.positions(), mesh_mask_, boundary_);
  return CompareCoverage(prepared_.object_masks[frame], mesh_mask_, boundary_);
}

}  // namespace calib
