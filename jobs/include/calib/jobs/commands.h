#pragma once
// The work behind `calib mesh`, `calib simulate` and `calib score`: each takes
// plain options, does its job and returns a summary; the command-line front
// end only parses and prints. Bad input throws (RecordingError,
// ParameterError, std::invalid_argument, std::runtime_error) with a message
// naming the file, key or value.

#include "calib/core/model_definition.h"
#include "calib/evaluator/evaluation.h"

#include <filesystem>
#include <string>
#include <vector>

namespace calib {

/// Settings every command shares.
struct CommandSettings {
  PreparationOptions preparation;
  SimulationOptions simulation;
  /// The base model plus these effects; parameter files must name exactly
  /// ModelParameterSpecs(model).
  ModelDefinition model;
  bool IsValid(std::string* error) const;
};

struct MeshSummary {
  std::filesystem::path mesh_json;
  std::filesystem::path mesh_png;
  MeshQuality quality;
  int clamped_nodes = 0;
};

/// Meshes the frame-0 object of a recording; writes mesh.json (nodes,
/// triangles, edges, boundary loops, clamped nodes, quality) and mesh.png (the
/// mesh over frame 0) into out_dir.
MeshSummary RunMesh(const std::filesystem::path& recording_dir,
                    const std::filesystem::path& out_dir, const CommandSettings& settings);

struct SimulateOptions {
  /// Frames to write as overlay PNGs (out of range ones are an error); the
  /// worst frame is always written too.
  std::vector<int> png_frames;
  bool write_video = true;
};

struct SimulateSummary {
  EvaluationResult result;
  std::filesystem::path frames_csv;
  std::filesystem::path overlay_video;  ///< empty when not written
  std::vector<std::filesystem::path> overlay_pngs;
  int worst_frame = -1;
};

/// Simulates the recording with the parameter file and writes frames.csv,
/// overlay.mp4 and overlay PNGs into out_dir.
SimulateSummary RunSimulate(const std::filesystem::path& recording_dir,
                            const std::filesystem::path& params_file,
                            const std::filesystem::path& out_dir, const SimulateOptions& options,
                            const CommandSettings& settings);

/// Simulates and scores without writing anything.
EvaluationResult RunScore(const std::filesystem::path& recording_dir,
                          const std::filesystem::path& params_file,
                          const CommandSettings& settings);

}  // namespace calib
