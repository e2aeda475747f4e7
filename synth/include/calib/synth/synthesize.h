#pragma once
// Making a synthetic recording from a scenario: mesh the rest outline finely,
// run the truth model (SimulateTruth), render every frame and write the
// recording folder in the format of shared/spec/dataset.md, plus truth.json.

#include "calib/core/mesh.h"
#include "calib/synth/scenario.h"
#include "calib/synth/truth_simulator.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace calib::synth {

/// What Synthesize wrote and how long it took. Unset: negative times, empty paths.
struct SynthesisSummary {
  std::filesystem::path folder;
  std::filesystem::path video;          ///< video.mp4
  std::string video_codec;              ///< fourcc used: "avc1" (H.264) or "mp4v"
  int num_frames = 0;
  int width_px = 0;
  int height_px = 0;
  int fine_nodes = 0;
  int fine_triangles = 0;
  double simulation_s = -1.0;           ///< wall time of SimulateTruth
  double rendering_s = -1.0;            ///< rendering and encoding
  double total_s = -1.0;
  uint64_t bytes = 0;                   ///< all files written into the folder
  std::vector<std::string> effects;     ///< effects switched on

  std::string BriefReport() const;
};

/// The truth behind a synthetic recording, for tests and scoring.
struct TruthRecord {
  Mesh rest_mesh;                              ///< the fine mesh, px
  std::vector<TruthFrame> frames;              ///< one per video frame
  std::vector<std::vector<Disc>> obstacles;    ///< per frame, ObstacleNames order
};

/// Writes the recording of `scenario` into `out_dir` (created; existing files
/// recording.json, video.mp4, track.csv, truth.json are replaced):
///   - recording.json: format, video, track, fps, mm_per_px, the object's HSV
///     range (ObjectHsvRange), force_obstacle ("finger" for push, null for
///     hang), roi (the whole frame), clamps (hang), notes;
///   - video.mp4: H.264 ('avc1', quality camera.video_crf); 'mp4v' when this
///     OpenCV build cannot write H.264;
///   - track.csv: frame, then x, y, r (px) of every obstacle, then force_x,
///     force_y (N, image axes, on the object by the finger) = truth contact
///     force + gaussian sensor.noise_n + sensor.bias_n (push only);
///   - truth.json: the scenario, the effects on, the truth material and
///     environment as simulated, per-frame truth figures (true force, object
///     area and centroid, elastic energy) and summary figures.
/// All randomness derives from scenario.seed: the same scenario gives the
/// same truth, track and frames. When `truth` is not null it receives the
/// truth. Throws ScenarioError for an invalid scenario or colours that do not
/// separate (ColoursSeparate), std::runtime_error when the truth model fails
/// or a file cannot be written (naming it).
SynthesisSummary Synthesize(const Scenario& scenario, const std::filesystem::path& out_dir,
                            TruthRecord* truth = nullptr);

}  // namespace calib::synth
