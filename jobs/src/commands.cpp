#include "calib/jobs/commands.h"

#include "calib/core/parameters.h"
#include "calib/evaluator/mask_geometry.h"
#include "calib/evaluator/media.h"
#include "calib/evaluator/overlay.h"
#include "calib/results/frame_report.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include <fstream>
#include <stdexcept>

namespace calib {
namespace {

void CheckSettings(const CommandSettings& settings) {
  std::string error;
  if (!settings.IsValid(&error)) throw std::invalid_argument(error);
}

void WriteMeshJson(const std::filesystem::path& path, const PreparedRecording& prepared,
                   const std::vector<uint8_t>& clamped) {
  const Mesh& mesh = prepared.mesh;
  nlohmann::json doc;
  doc["recording"] = prepared.recording.folder.string();
  auto& nodes = doc["nodes"] = nlohmann::json::array();
  for (const Vec2& p : mesh.rest_positions) nodes.push_back({p.x(), p.y()});
  doc["triangles"] = mesh.triangles;
  doc["edges"] = mesh.edges;
  doc["boundary_loops"] = mesh.boundary_loops;
  auto& clamped_ids = doc["clamped_nodes"] = nlohmann::json::array();
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    if (clamped[i]) clamped_ids.push_back(i);
  }
  const MeshQuality& q = prepared.mesh_quality;
  doc["quality"] = {{"nodes", q.num_nodes},
                    {"triangles", q.num_triangles},
                    {"min_angle_deg", q.min_angle_deg},
                    {"max_angle_deg", q.max_angle_deg},
                    {"mean_edge_px", q.mean_edge_px},
                    {"min_edge_px", q.min_edge_px},
                    {"max_edge_px", q.max_edge_px},
                    {"worst_radius_ratio", q.worst_radius_ratio},
                    {"area_px2", q.area_px2}};
  std::ofstream out(path);
  out << doc.dump(1) << '\n';
  if (!out) throw std::runtime_error(fmt::format("{}: cannot write", path.string()));
}

// Reads frame images in order alongside the simulation.
class FrameReader {
 public:
  explicit FrameReader(const Recording& recording) : path_(recording.video_path.string()) {
    if (!capture_.Open(path_)) {
      throw RecordingError(fmt::format("{}: cannot open video", path_));
    }
  }
  const cv::Mat& Next(int frame) {
    if (!capture_.Read(image_)) {
      throw RecordingError(fmt::format("{}: cannot decode frame {}", path_, frame));
    }
    return image_;
  }

 private:
  std::string path_;
  VideoReader capture_;
  cv::Mat image_;
};

PreparedRecording Prepare(const std::filesystem::path& recording_dir,
                          const CommandSettings& settings) {
  CheckSettings(settings);
  return PrepareRecording(LoadRecording(recording_dir), settings.preparation);
}

}  // namespace

bool CommandSettings::IsValid(std::string* error) const {
  return preparation.IsValid(error) && simulation.IsValid(error) && model.IsValid(error);
}

MeshSummary RunMesh(const std::filesystem::path& recording_dir,
                    const std::filesystem::path& out_dir, const CommandSettings& settings) {
  const PreparedRecording prepared = Prepare(recording_dir, settings);
  std::filesystem::create_directories(out_dir);
  const Simulator simulator(prepared.mesh, prepared.scene, settings.simulation);

  MeshSummary summary;
  summary.quality = prepared.mesh_quality;
  for (uint8_t c : simulator.clamped()) summary.clamped_nodes += c;
  summary.mesh_json = out_dir / "mesh.json";
  WriteMeshJson(summary.mesh_json, prepared, simulator.clamped());

  FrameReader reader(prepared.recording);
  const cv::Mat& frame0 = reader.Next(0);
  BitMask mesh_mask(prepared.object_masks[0]);
  Rasterizer rasterizer;
  rasterizer.RasterizeMesh(prepared.mesh, prepared.mesh.rest_positions, mesh_mask);
  OverlayOptions overlay;
  overlay.frame_index = 0;
  const cv::Mat image =
      RenderOverlay(frame0, prepared.mesh, prepared.mesh.rest_positions,
                    std::vector<Disc>(prepared.scene.ObstaclesAt(0),
                                      prepared.scene.ObstaclesAt(0) + prepared.scene.num_obstacles),
                    prepared.object_masks[0], mesh_mask, overlay);
  summary.mesh_png = out_dir / "mesh.png";
  WriteOverlayPng(summary.mesh_png, image);
  return summary;
}

SimulateSummary RunSimulate(const std::filesystem::path& recording_dir,
                            const std::filesystem::path& params_file,
                            const std::filesystem::path& out_dir, const SimulateOptions& options,
                            const CommandSettings& settings) {
  const ParameterValues values = LoadParameterFile(params_file, ModelParameterSpecs(settings.model));
  const PreparedRecording prepared = Prepare(recording_dir, settings);
  const int num_frames = prepared.scene.num_frames;
  for (int f : options.png_frames) {
    if (f < 0 || f >= num_frames) {
      throw std::invalid_argument(
          fmt::format("overlay frame {} is out of range: the recording has frames 0..{}", f,
                      num_frames - 1));
    }
  }
  std::filesystem::create_directories(out_dir);

  SimulateSummary summary;
  FrameReader reader(prepared.recording);
  OverlayVideoWriter video;
  if (options.write_video) {
    summary.overlay_video = out_dir / "overlay.mp4";
    const cv::Size panel(2 * prepared.recording.frame_width, 2 * prepared.recording.frame_height);
    video.Open(summary.overlay_video, prepared.recording.fps, panel);
  }
  double worst_xor = -1.0;
  cv::Mat worst_image;
  std::vector<Disc> discs;
  FrameCentroids centroids;
  for (const BitMask& mask : prepared.object_masks) {
    centroids.object_px.push_back(ComputeMoments(mask).centroid_px);
  }
  const auto on_frame = [&](int frame, const Simulator& sim, const BitMask& mesh_mask,
                            const FrameScore& score) {
    centroids.mesh_px.push_back(AreaCentroid(prepared.mesh, sim.positions()));
    const cv::Mat& image = reader.Next(frame);
    const bool wanted =
        std::find(options.png_frames.begin(), options.png_frames.end(), frame) !=
        options.png_frames.end();
    const bool worst = score.xor_px > worst_xor;
    if (!options.write_video && !wanted && !worst) return;
    const Disc* d = prepared.scene.ObstaclesAt(frame);
    discs.assign(d, d + prepared.scene.num_obstacles);
    OverlayOptions overlay;
    overlay.frame_index = frame;
    overlay.xor_px = score.xor_px;
    overlay.iou = score.iou;
    const cv::Mat panel = RenderOverlay(image, prepared.mesh, sim.positions(), discs,
                                        prepared.object_masks[frame], mesh_mask, overlay);
    if (options.write_video) video.Write(panel);
    if (wanted) {
      const auto png = out_dir / fmt::format("overlay_{:06d}.png", frame);
      WriteOverlayPng(png, panel);
      summary.overlay_pngs.push_back(png);
    }
    if (worst) {
      worst_xor = score.xor_px;
      summary.worst_frame = frame;
      panel.copyTo(worst_image);
    }
  };
  Evaluator evaluator(prepared, settings.simulation, settings.model);
  summary.result = evaluator.Evaluate(values, on_frame);
  if (options.write_video) video.Close();
  if (!worst_image.empty()) {
    const auto png = out_dir / fmt::format("overlay_worst_{:06d}.png", summary.worst_frame);
    WriteOverlayPng(png, worst_image);
    summary.overlay_pngs.push_back(png);
  }
  summary.frames_csv = out_dir / "frames.csv";
  WriteFrameReportCsv(summary.frames_csv, summary.result, num_frames, &centroids);
  return summary;
}

EvaluationResult RunScore(const std::filesystem::path& recording_dir,
                          const std::filesystem::path& params_file,
                          const CommandSettings& settings) {
  const ParameterValues values = LoadParameterFile(params_file, ModelParameterSpecs(settings.model));
  const PreparedRecording prepared = Prepare(recording_dir, settings);
  Evaluator evaluator(prepared, settings.simulation, settings.model);
  return evaluator.Evaluate(values);
}

}  // namespace calib
