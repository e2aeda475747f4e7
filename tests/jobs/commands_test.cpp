// The commands end to end on the bundled example recording: mesh, simulate
// (per-frame CSV, overlay video and PNGs) and score agree with each other and
// are deterministic; bad parameter files and options are named.

#include "calib/jobs/commands.h"

#include "calib/evaluator/media.h"
#include "support/csv_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <sstream>
#include <string>

namespace calib {
namespace {

const std::filesystem::path kExample = std::filesystem::path(CALIB_SOURCE_DIR) / "examples";

CommandSettings Settings(const std::filesystem::path& cache) {
  CommandSettings settings;
  settings.preparation.cache_dir = cache;
  return settings;
}

TEST(Commands, MeshWritesMeshJsonAndPng) {
  const auto dir = testing::ScratchDir("mesh");
  const MeshSummary summary = RunMesh(kExample / "push_centre", dir / "out", Settings(dir / "cache"));
  ASSERT_TRUE(std::filesystem::exists(summary.mesh_json));
  ASSERT_TRUE(std::filesystem::exists(summary.mesh_png));
  std::ifstream in(summary.mesh_json);
  const auto doc = nlohmann::json::parse(in);
  EXPECT_EQ(doc["nodes"].size(), static_cast<size_t>(summary.quality.num_nodes));
  EXPECT_EQ(doc["triangles"].size(), static_cast<size_t>(summary.quality.num_triangles));
  // The example's sponge is 400 x 256 px.
  EXPECT_NEAR(summary.quality.area_px2, 400.0 * 256.0, 0.03 * 400.0 * 256.0);
  EXPECT_GT(summary.quality.min_angle_deg, 20.0);
}

TEST(Commands, SimulateWritesReportsThatAgreeWithScore) {
  const auto dir = testing::ScratchDir("simulate");
  const CommandSettings settings = Settings(dir / "cache");
  SimulateOptions options;
  options.png_frames = {0, 150};
  const SimulateSummary summary = RunSimulate(kExample / "push_centre",
                                              kExample / "params_push.json", dir / "out", options,
                                              settings);
  ASSERT_TRUE(summary.result.ok()) << summary.result.failure_reason;
  EXPECT_EQ(summary.result.num_frames, 330);
  EXPECT_GT(summary.result.mean_iou, 0.9);

  // frames.csv: a header and one row per frame.
  const testing::CsvRows rows = testing::ParseCsvFile(summary.frames_csv);
  ASSERT_EQ(rows.size(), 331u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"frame", "xor", "missed", "extra", "iou", "status",
                                               "reason", "mesh_cx", "mesh_cy", "object_cx",
                                               "object_cy"}));
  // Frame 0's mesh is the object's frame-0 outline: their centroids agree
  // within a pixel.
  ASSERT_EQ(rows[1].size(), 11u);
  EXPECT_NEAR(std::stod(rows[1][7]), std::stod(rows[1][9]), 1.0);
  EXPECT_NEAR(std::stod(rows[1][8]), std::stod(rows[1][10]), 1.0);

  VideoReader video(summary.overlay_video);
  ASSERT_TRUE(video.IsOpen());
  EXPECT_EQ(static_cast<int>(video.StatedFrameCount()), 330);
  EXPECT_EQ(summary.overlay_pngs.size(), 3u);  // frames 0, 150 and the worst

  // Scoring alone gives the same bits (and reads the segmentation cache).
  const EvaluationResult scored = RunScore(kExample / "push_centre", kExample / "params_push.json",
                                           settings);
  EXPECT_EQ(scored.xor_sum, summary.result.xor_sum);
  EXPECT_EQ(scored.mean_iou, summary.result.mean_iou);
}

TEST(Commands, BadParameterFileIsNamed) {
  const auto dir = testing::ScratchDir("badparams");
  std::ofstream(dir / "p.json") << R"({"k_D": 1, "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 1})";
  try {
    RunScore(kExample / "push_centre", dir / "p.json", Settings(dir / "cache"));
    FAIL() << "accepted a parameter file without tau";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("p.json: missing parameter 'tau'"), std::string::npos)
        << e.what();
  }
}

TEST(Commands, BadSettingsAreNamed) {
  const auto dir = testing::ScratchDir("badsettings");
  CommandSettings settings = Settings(dir / "cache");
  settings.simulation.substeps = 0;
  try {
    RunScore(kExample / "push_centre", kExample / "params_push.json", settings);
    FAIL() << "accepted substeps = 0";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("substeps = 0"), std::string::npos) << e.what();
  }
}

TEST(Commands, OverlayFrameOutOfRangeIsNamed) {
  const auto dir = testing::ScratchDir("badframe");
  SimulateOptions options;
  options.png_frames = {400};
  try {
    RunSimulate(kExample / "push_centre", kExample / "params_push.json", dir / "out", options,
                Settings(dir / "cache"));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("overlay frame 400"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace calib
