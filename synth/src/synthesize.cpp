#include "calib/synth/synthesize.h"

#include "calib/core/mesher.h"
#include "calib/evaluator/json_number.h"
#include "calib/evaluator/media.h"
#include "calib/synth/renderer.h"
#include "random.h"
#include "text_file.h"
#include "yaml_json.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <optional>

namespace calib::synth {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

nlohmann::json Json(const Vec2& v) { return nlohmann::json::array({v.x(), v.y()}); }

// Sets an environment variable for the lifetime of the guard. OpenCV's FFmpeg
// writer takes encoder options (here the H.264 quality) only from
// OPENCV_FFMPEG_WRITER_OPTIONS; the previous value is restored.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_) {
      setenv(name_, old_->c_str(), 1);
    } else {
      unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

// Area (px^2) and centroid (px) of the deformed mesh: the sums over its
// triangles.
std::pair<double, Vec2> AreaAndCentroid(const Mesh& mesh, const std::vector<Vec2>& p) {
  double area = 0.0;
  Vec2 moment = Vec2::Zero();
  for (const auto& t : mesh.triangles) {
    const double a = SignedArea(p[t[0]], p[t[1]], p[t[2]]);
    area += a;
    moment += a * (p[t[0]] + p[t[1]] + p[t[2]]) / 3.0;
  }
  return {area, area != 0.0 ? Vec2(moment / area) : Vec2::Zero()};
}

nlohmann::json MaterialJson(const TruthMaterial& m) {
  nlohmann::json regions = nlohmann::json::array();
  for (const auto& r : m.stiffness_regions) {
    regions.push_back({{"centre_px", Json(r.centre_px)}, {"radius_px", r.radius_px}, {"factor", r.factor}});
  }
  return {{"law", ToString(m.law)},
          {"youngs_modulus_pa", m.youngs_modulus_pa},
          {"poisson_ratio", m.poisson_ratio},
          {"thickness_m", m.thickness_m},
          {"density_kg_m3", m.density_kg_m3},
          {"stiffness_gradient", m.stiffness_gradient},
          {"stiffness_gradient_direction", Json(m.stiffness_gradient_direction)},
          {"stiffness_regions", regions},
          {"stiffening_coefficient", m.stiffening_coefficient},
          {"plastic_yield_strain", JsonNumber(m.plastic_yield_strain)},
          {"plastic_flow_rate_per_s", m.plastic_flow_rate_per_s},
          {"viscous_fraction", m.viscous_fraction},
          {"viscous_relaxation_time_s", m.viscous_relaxation_time_s}};
}

nlohmann::json EnvironmentJson(const TruthEnvironment& e) {
  return {{"friction_coefficient", e.friction_coefficient},
          {"friction_regularisation_m_s", e.friction_regularisation_m_s},
          {"gravity_m_s2", Json(e.gravity_m_s2)},
          {"inertia", e.inertia},
          {"initial_bend_m_s2", Json(e.initial_bend_m_s2)}};
}

}  // namespace

std::string SynthesisSummary::BriefReport() const {
  return fmt::format(
      "{} frames {}x{} ({}), fine mesh {} nodes / {} triangles, effects: {}; simulation {:.1f} s, "
      "rendering {:.1f} s, total {:.1f} s; {:.2f} MB",
      num_frames, width_px, height_px, video_codec, fine_nodes, fine_triangles,
      effects.empty() ? std::string("none") : fmt::format("{}", fmt::join(effects, ", ")),
      simulation_s, rendering_s, total_s, bytes / 1e6);
}

SynthesisSummary Synthesize(const Scenario& s, const fs::path& out_dir, TruthRecord* truth) {
  const auto start = Clock::now();
  std::string error;
  if (!s.IsValid(&error)) throw ScenarioError(fmt::format("scenario '{}': {}", s.name, error));
  if (!ColoursSeparate(s.camera, &error)) throw ScenarioError(fmt::format("scenario '{}': {}", s.name, error));

  // The truth.
  MesherOptions mesher;
  mesher.edge_length_px = s.simulation.fine_edge_px;
  TruthScene scene;
  scene.rest_mesh = MeshPolygon(RestPolygonPx(s), mesher);
  scene.mm_per_px = s.mm_per_px;
  scene.fps = s.fps;
  scene.num_frames = s.frames;
  scene.substeps = s.simulation.substeps;
  scene.obstacles = ObstacleTracksPx(s);
  scene.force_obstacle = s.kind == ScenarioKind::kPush ? 0 : -1;
  scene.clamps = ClampRectsPx(s);
  const TruthMaterial material = ToTruthMaterial(s);
  const TruthEnvironment environment = ToTruthEnvironment(s);
  TruthOptions truth_options;
  truth_options.max_newton_iterations = s.simulation.max_newton_iterations;
  const auto sim_start = Clock::now();
  std::vector<TruthFrame> frames = SimulateTruth(scene, material, environment, truth_options);
  SynthesisSummary summary;
  summary.simulation_s = Seconds(sim_start);
  if (static_cast<int>(frames.size()) != s.frames) {
    throw std::runtime_error(fmt::format("truth model returned {} frames, expected {}", frames.size(), s.frames));
  }

  // The video.
  const auto render_start = Clock::now();
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir)) {
    throw std::runtime_error(fmt::format("{}: cannot create the output folder", out_dir.string()));
  }
  const fs::path video_path = out_dir / "video.mp4";
  fs::remove(video_path, ec);
  const cv::Size size(s.camera.width_px, s.camera.height_px);
  VideoWriter writer;
  {
    const ScopedEnv quality("OPENCV_FFMPEG_WRITER_OPTIONS", fmt::format("crf;{}", s.camera.video_crf));
    summary.video_codec = "avc1";
    writer.Open(video_path, FourCC("avc1"), s.fps, size, VideoWriter::Backend::kFfmpeg);
    if (!writer.IsOpen()) {
      summary.video_codec = "mp4v";
      writer.Open(video_path, FourCC("mp4v"), s.fps, size, VideoWriter::Backend::kFfmpeg);
    }
  }
  if (!writer.IsOpen()) throw std::runtime_error(fmt::format("{}: cannot open a video writer", video_path.string()));
  const FrameRenderer renderer(s.camera, scene.rest_mesh, s.seed);
  for (int f = 0; f < s.frames; ++f) {
    std::vector<DrawnDisc> discs;
    if (s.kind == ScenarioKind::kPush) {  // pencil (opaque) below the finger
      discs.push_back({scene.obstacles[f][1], s.camera.pencil_rgb, 1.0});
      discs.push_back({scene.obstacles[f][0], s.camera.finger_rgb, s.camera.finger_opacity});
    }
    writer.Write(renderer.Render(f, frames[f].positions_px, discs));
  }
  writer.Release();
  summary.rendering_s = Seconds(render_start);

  // track.csv: the obstacles and the sensor's reading.
  const std::vector<std::string> names = ObstacleNames(s);
  std::string track = "frame";
  for (const auto& name : names) track += fmt::format(",{0}_x,{0}_y,{0}_r", name);
  const bool has_force = s.kind == ScenarioKind::kPush;
  if (has_force) track += ",force_x,force_y";
  track += "\n";
  SplitMix64 sensor_rng(DeriveSeed(s.seed, 0x5e45u));
  std::vector<Vec2> readings;
  for (int f = 0; f < s.frames; ++f) {
    track += fmt::format("{}", f);
    for (const Disc& d : scene.obstacles[f]) {
      track += fmt::format(",{:.3f},{:.3f},{:.3f}", d.centre.x(), d.centre.y(), d.radius_px);
    }
    if (has_force) {
      const Vec2 noise(sensor_rng.Normal(), sensor_rng.Normal());
      const Vec2 reading = frames[f].contact_force_n + s.sensor.noise_n * noise + s.sensor.bias_n;
      readings.push_back(reading);
      track += fmt::format(",{:.5f},{:.5f}", reading.x(), reading.y());
    }
    track += "\n";
  }
  WriteText(out_dir / "track.csv", track);

  // recording.json.
  const HsvRange hsv = ObjectHsvRange(s.camera);
  nlohmann::json clamps = nlohmann::json::array();
  for (const RectPx& c : scene.clamps) {
    clamps.push_back({static_cast<int>(c.x), static_cast<int>(c.y), static_cast<int>(c.width),
                      static_cast<int>(c.height)});
  }
  nlohmann::ordered_json recording = {
      {"format", "sponge-recording/1"},
      {"video", "video.mp4"},
      {"track", "track.csv"},
      {"fps", s.fps},
      {"mm_per_px", s.mm_per_px},
      {"object", {{"color_hsv_lower", hsv.lower}, {"color_hsv_upper", hsv.upper}}},
      {"force_obstacle", has_force ? nlohmann::json("finger") : nlohmann::json(nullptr)},
      {"roi", {0, 0, s.camera.width_px, s.camera.height_px}}};
  if (!clamps.empty()) recording["clamps"] = clamps;
  recording["notes"] = fmt::format("Synthetic recording '{}' made by `calib synth` from a scenario ({} kind){}{}",
                                   s.name, ToString(s.kind), s.notes.empty() ? "" : ": ", s.notes);
  WriteText(out_dir / "recording.json", recording.dump(2) + "\n");

  // truth.json: what scoring may compare against.
  nlohmann::json per_frame = nlohmann::json::array();
  double max_force = 0.0, max_displacement = 0.0;
  const auto& rest = scene.rest_mesh.rest_positions;
  for (int f = 0; f < s.frames; ++f) {
    const auto [area, centroid] = AreaAndCentroid(scene.rest_mesh, frames[f].positions_px);
    for (size_t i = 0; i < rest.size(); ++i) {
      max_displacement = std::max(max_displacement, (frames[f].positions_px[i] - rest[i]).norm());
    }
    max_force = std::max(max_force, frames[f].contact_force_n.norm());
    per_frame.push_back({{"frame", f},
                         {"force_true_n", Json(frames[f].contact_force_n)},
                         {"area_px2", area},
                         {"centroid_px", Json(centroid)},
                         {"elastic_energy_j", frames[f].elastic_energy_j}});
  }
  double final_set = 0.0;
  for (size_t i = 0; i < rest.size(); ++i) final_set += (frames.back().positions_px[i] - rest[i]).norm();
  final_set /= std::max<size_t>(1, rest.size());
  const auto [rest_area, rest_centroid] = AreaAndCentroid(scene.rest_mesh, rest);
  const auto [final_area, final_centroid] = AreaAndCentroid(scene.rest_mesh, frames.back().positions_px);
  const std::string yaml = ScenarioToYaml(s);
  nlohmann::ordered_json truth_json = {
      {"format", "sponge-truth/1"},
      {"generator", "calib synth"},
      {"scenario", YamlToJson(YAML::Load(yaml))},
      {"effects", s.effects.EnabledNames()},
      {"material", MaterialJson(material)},
      {"environment", EnvironmentJson(environment)},
      {"mesh", {{"fine_edge_px", s.simulation.fine_edge_px},
                {"nodes", scene.rest_mesh.NumNodes()},
                {"triangles", scene.rest_mesh.NumTriangles()},
                {"substeps", s.simulation.substeps}}},
      {"rest_polygon_px", nlohmann::json::array()},
      {"obstacles", names},
      {"force_obstacle", has_force ? nlohmann::json("finger") : nlohmann::json(nullptr)},
      {"sensor", {{"noise_n", s.sensor.noise_n}, {"bias_n", Json(s.sensor.bias_n)}}},
      {"figures", {{"rest_area_px2", rest_area},
                   {"final_area_px2", final_area},
                   {"rest_centroid_px", Json(rest_centroid)},
                   {"final_centroid_px", Json(final_centroid)},
                   {"final_mean_displacement_px", final_set},
                   {"max_displacement_px", max_displacement},
                   {"max_true_force_n", max_force}}},
      {"frames", per_frame}};
  for (const Vec2& p : RestPolygonPx(s)) truth_json["rest_polygon_px"].push_back({p.x(), p.y()});
  WriteText(out_dir / "truth.json", truth_json.dump(1) + "\n");

  summary.folder = out_dir;
  summary.video = video_path;
  summary.num_frames = s.frames;
  summary.width_px = s.camera.width_px;
  summary.height_px = s.camera.height_px;
  summary.fine_nodes = scene.rest_mesh.NumNodes();
  summary.fine_triangles = scene.rest_mesh.NumTriangles();
  summary.effects = s.effects.EnabledNames();
  for (const char* name : {"recording.json", "video.mp4", "track.csv", "truth.json"}) {
    const auto bytes = fs::file_size(out_dir / name, ec);
    if (!ec) summary.bytes += bytes;
  }
  summary.total_s = Seconds(start);
  if (truth) {
    truth->rest_mesh = std::move(scene.rest_mesh);
    truth->frames = std::move(frames);
    truth->obstacles = std::move(scene.obstacles);
  }
  return summary;
}

}  // namespace calib::synth
