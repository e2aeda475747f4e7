#include "reference_scene.h"

#include <algorithm>
#include <cmath>

namespace calib::bench {

PreparedRecording MakeReferenceScene(const ReferenceSceneOptions& options) {
  PreparedRecording prepared;
  Recording& rec = prepared.recording;
  rec.fps = 30.0;
  rec.frame_width = options.width;
  rec.frame_height = options.height;
  rec.num_frames = options.num_frames;
  rec.roi = {0, 0, options.width, options.height};
  rec.force_obstacle = "finger";

  const double x0 = 0.5 * (options.width - options.sponge_width_px);
  const double y0 = 0.5 * (options.height - options.sponge_height_px);
  const double x1 = x0 + options.sponge_width_px;
  const double y1 = y0 + options.sponge_height_px;
  prepared.outline = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  MesherOptions mesher;
  mesher.edge_length_px = options.edge_length_px;
  prepared.mesh = MeshPolygon(prepared.outline, mesher);
  prepared.mesh_quality = MeasureQuality(prepared.mesh);

  // The finger comes down the middle of the top side, pushes 40 px in over
  // the first 40% of the video, holds, and retracts over the last 30%; the
  // pencil stands against the bottom side.
  Scene& scene = prepared.scene;
  scene.frame_time_s = 1.0 / rec.fps;
  scene.num_frames = options.num_frames;
  scene.num_obstacles = 2;
  scene.force_obstacle = 0;
  const double finger_r = 14.0, pencil_r = 9.0;
  const double cx = 0.5 * (x0 + x1);
  for (int f = 0; f < options.num_frames; ++f) {
    const double t = static_cast<double>(f) / (options.num_frames - 1);
    const double depth = 40.0 * std::clamp(std::min(t / 0.4, (1.0 - t) / 0.3), 0.0, 1.0);
    scene.obstacle_discs.push_back({Vec2(cx, y0 - finger_r + depth), finger_r});
    scene.obstacle_discs.push_back({Vec2(cx, y1 + pencil_r), pencil_r});
    scene.forces.push_back(Vec2(0.0, 0.05 * depth));
  }
  rec.obstacles = {{"finger", {}}, {"pencil", {}}};
  for (int f = 0; f < options.num_frames; ++f) {
    rec.obstacles[0].discs.push_back(scene.obstacle_discs[2 * f]);
    rec.obstacles[1].discs.push_back(scene.obstacle_discs[2 * f + 1]);
  }
  rec.forces = scene.forces;

  BitMask mask(options.width, options.height);
  Rasterizer rasterizer;
  rasterizer.RasterizeMesh(prepared.mesh, prepared.mesh.rest_positions, mask);
  prepared.object_masks.assign(options.num_frames, mask);
  return prepared;
}

const PreparedRecording& ReferenceScene() {
  static const PreparedRecording prepared = MakeReferenceScene();
  return prepared;
}

const PreparedRecording& ShortReferenceScene() {
  static const PreparedRecording prepared = [] {
    ReferenceSceneOptions options;
    options.num_frames = 60;
    return MakeReferenceScene(options);
  }();
  return prepared;
}

ModelParameters ReferenceParameters() {
  ModelParameters p;
  p.k_distance = 400.0;
  p.k_damping = 2.0;
  p.k_area = 200.0;
  p.k_angle = 50.0;
  p.mass = 1.0;
  p.translation = 0.1;
  return p;
}

}  // namespace calib::bench
