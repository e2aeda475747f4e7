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
#include <utility>
#include <vector>

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
  if (cut.registered_iou.size() > static_cast<size_t>(n)) cut.registered_iou.resize(n);
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
  // The tracked shapes scored as a model's are: the most a model moving
  // this mesh can match in each frame.
  Rasterizer rasterizer;
  BitMask interior(prepared.object_masks[0]);
  std::vector<PixelCoverage> boundary;
  prepared.registered_iou.clear();
  for (int f = 0; f < window; ++f) {
    rasterizer.RasterizeMeshCoverage(mesh, tracked.positions[f], interior, boundary);
    prepared.registered_iou.push_back(
        CompareCoverage(prepared.object_masks[f], interior, boundary).iou);
  }
}

void SetStartPose(PreparedRecording& prepared) {
  Scene::ObservedMotion& motion = prepared.scene.motion;
  const Mesh& mesh = prepared.mesh;
  motion.node_start_px.clear();
  if (motion.node_rest_px.size() != static_cast<size_t>(mesh.NumNodes()) ||
      prepared.object_masks.empty() || !(prepared.motion_blur_frames > 0.0)) {
    return;
  }
  ShapeTrackingOptions options;
  options.outline_weight = kStartPoseOutlineWeight;
  const std::vector<uint8_t> clamped = ClampedNodes(mesh, prepared.scene);
  MeshRegistration registered = RegisterMesh(mesh, clamped, mesh.rest_positions,
                                             motion.node_rest_px, prepared.object_masks[0], options);
  motion.node_start_px = std::move(registered.positions);
}

PreparedRecording PrepareRecording(const Recording& recording, const PreparationOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  std::vector<BitMask> masks = SegmentRecording(recording, options.segmentation, options.cache_dir);
  return PrepareSegmented(recording, std::move(masks), options);
}

PreparedRecording PrepareSegmented(const Recording& recording, std::vector<BitMask> masks,
                                   const PreparationOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  const std::string& name = recording.video_path.string();
  if (std::ssize(masks) != recording.num_frames) {
    throw std::invalid_argument(fmt::format("{}: {} masks for its {} frames", name, masks.size(),
                                            recording.num_frames));
  }
  const PixelRect& roi = recording.roi;
  for (size_t f = 0; f < masks.size(); ++f) {
    const BitMask& m = masks[f];
    if (m.width() != roi.width || m.height() != roi.height || m.origin_x() != roi.x ||
        m.origin_y() != roi.y) {
      throw std::invalid_argument(fmt::format(
          "{}: the mask of frame {} is {}x{} at ({}, {}), its roi {}x{} at ({}, {})", name, f,
          m.width(), m.height(), m.origin_x(), m.origin_y(), roi.width, roi.height, roi.x, roi.y));
    }
  }
  PreparedRecording prepared;
  prepared.recording = recording;
  prepared.object_masks = std::move(masks);
  if (prepared.object_masks.empty() || prepared.object_masks[0].Count() == 0) {
    throw std::invalid_argument(fmt::format(
        "{}: no object found in frame 0 with the HSV range of recording.json (object.color_hsv_*)",
        name));
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
    prepared.motion_blur_frames = EstimateMotionBlur(prepared.object_masks);
    SetStartPose(prepared);
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
      mesh_mask_(prepared.object_masks.at(0)),
      object_px_(prepared.object_masks.size(), -1) {}

Evaluator::Evaluator(const PreparedRecording& prepared, const SimulationOptions& options,
                     const ModelDefinition& model)
    : prepared_(prepared),
      simulator_(prepared.mesh, prepared.scene, options, model),
      mesh_mask_(prepared.object_masks.at(0)),
      object_px_(prepared.object_masks.size(), -1) {}

FrameScore Evaluator::ScoreFrame(int frame) {
  const Vec2* x = prepared_.motion_blur_frames > 0.0 ? Blurred(frame).data()
                                                     : simulator_.positions().data();
  rasterizer_.RasterizeMeshCoverage(prepared_.mesh, x, mesh_mask_, boundary_);
  // The mesh covers a band of the mask's rows: only those are compared word
  // by word, the object's pixels elsewhere are all missed.
  const BitMask& object = prepared_.object_masks[frame];
  if (object_px_[frame] < 0) object_px_[frame] = object.Count();
  const auto [row_begin, row_end] = rasterizer_.covered_rows();
  return CompareCoverageInRows(object, object_px_[frame], mesh_mask_, row_begin, row_end,
                               boundary_);
}

std::span<const Vec2> Evaluator::Blurred(int frame) {
  const std::vector<Vec2>& x = simulator_.positions();
  const size_t n = x.size();
  if (last_positions_.size() != n) {
    last_positions_.resize(n);
    seen_positions_.resize(n);
    outline_normal_.resize(n);
  }
  if (frame == 0) {
    const std::span<const Vec2> v0 = simulator_.initial_velocities();
    const double dt = prepared_.scene.frame_time_s;
    for (size_t i = 0; i < n; ++i) {
      last_positions_[i] = v0.empty() ? x[i] : Vec2(x[i] - v0[i] * dt);
    }
  }
  // Outward normals of the outline at its nodes: the sum of its two edges'
  // outward normals, each as long as its edge (the loops keep the interior
  // on a positive triangle's side).
  for (const std::vector<int>& loop : prepared_.mesh.boundary_loops) {
    for (int i : loop) outline_normal_[i] = Vec2::Zero();
    for (size_t k = 0; k < loop.size(); ++k) {
      const int a = loop[k], b = loop[(k + 1) % loop.size()];
      const Vec2 e = x[b] - x[a];
      const Vec2 outward(e.y(), -e.x());
      outline_normal_[a] += outward;
      outline_normal_[b] += outward;
    }
  }
  std::copy(x.begin(), x.end(), seen_positions_.begin());
  const double blur = prepared_.motion_blur_frames;
  for (const std::vector<int>& loop : prepared_.mesh.boundary_loops) {
    for (int i : loop) {
      const double norm = outline_normal_[i].norm();
      if (!(norm > 0.0)) continue;
      const Vec2 normal = outline_normal_[i] / norm;
      const double across = std::abs((x[i] - last_positions_[i]).dot(normal));  // px a frame
      seen_positions_[i] += (blur * across) * normal;
    }
  }
  std::copy(x.begin(), x.end(), last_positions_.begin());
  return seen_positions_;
}

double EstimateMotionBlur(std::span<const BitMask> masks) {
  const int n = static_cast<int>(masks.size());
  if (n < 4) return 0.0;
  // Least squares of area = a + b sweep over frames [1, n - 1).
  double s = 0.0, a = 0.0, ss = 0.0, sa = 0.0, aa = 0.0;
  const double m = n - 2;
  for (int f = 1; f + 1 < n; ++f) {
    const double sweep = 0.5 * static_cast<double>(CountXorShifted(masks[f - 1], masks[f + 1], 0, 0));
    const double area = static_cast<double>(masks[f].Count());
    s += sweep;
    a += area;
    ss += sweep * sweep;
    sa += sweep * area;
    aa += area * area;
  }
  const double var_s = ss - s * s / m;
  const double var_a = aa - a * a / m;
  const double cov = sa - s * a / m;
  if (!(var_s > 0.0) || !(var_a > 0.0)) return 0.0;
  const double slope = cov / var_s;
  const double r2 = cov * cov / (var_s * var_a);
  if (!(slope >= kMotionBlurMinFrames) || r2 < kMotionBlurMinR2) return 0.0;
  return std::min(slope, kMotionBlurMaxFrames);
}

}  // namespace calib
