// `calib synth` end to end on small scenarios: the written folder reads back
// as a recording, frame counts match, the segmentation of the decoded video
// matches the truth mask away from the finger, truth.json is there, and the
// same scenario gives the same track and truth.

#include "calib/synth/synthesize.h"

#include "calib/evaluator/media.h"
#include "calib/evaluator/rasterizer.h"
#include "calib/evaluator/recording.h"
#include "calib/evaluator/segmentation.h"

#include "support/test_support.h"

#include "support/process_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

namespace calib::synth {
namespace {

// 12 frames, a coarse fine mesh: seconds, not minutes.
Scenario SmallPush() {
  return ParseScenario(R"(
name: small_push
kind: push
fps: 30
frames: 12
seed: 5
push: {depth_mm: 6, start_gap_mm: 1, delay_s: 0, approach_s: 0.2, hold_s: 0.1, retract_s: 0.06}
effects:
  viscoelastic: {fraction: 0.3, relaxation_time_s: 0.5}
simulation: {fine_edge_px: 12, substeps: 4}
)",
                       "small_push.yaml");
}

TEST(Synthesize, PushRoundTrip) {
  const auto dir = testing::ScratchDir("synth_push");
  const Scenario scenario = SmallPush();
  TruthRecord truth;
  const SynthesisSummary summary = Synthesize(scenario, dir / "rec", &truth);
  EXPECT_EQ(summary.num_frames, 12);
  EXPECT_GT(summary.bytes, 0u);
  ASSERT_EQ(truth.frames.size(), 12u);

  const Recording rec = LoadRecording(dir / "rec");
  EXPECT_EQ(rec.num_frames, 12);
  EXPECT_EQ(rec.frame_width, 640);
  EXPECT_EQ(rec.frame_height, 480);
  EXPECT_EQ(rec.fps, 30.0);
  ASSERT_EQ(rec.obstacles.size(), 2u);
  EXPECT_EQ(rec.obstacles[0].name, "finger");
  EXPECT_EQ(rec.obstacles[1].name, "pencil");
  ASSERT_EQ(rec.ForceObstacleIndex(), 0);
  ASSERT_EQ(rec.forces.size(), 12u);
  for (int f = 0; f < 12; ++f) {  // reading = truth + bias + noise (5 sigma)
    const Vec2 error = rec.forces[f] - truth.frames[f].contact_force_n - scenario.sensor.bias_n;
    EXPECT_LT(error.cwiseAbs().maxCoeff(), 5.0 * scenario.sensor.noise_n + 1e-5) << "frame " << f;
    EXPECT_NEAR(rec.obstacles[0].discs[f].centre.y(), truth.obstacles[f][0].centre.y(), 1e-3);
  }

  // Segment every decoded frame with the recording's HSV range and compare
  // with the truth mask, leaving out pixels within 4 px of the finger disc.
  VideoReader video(rec.video_path);
  ASSERT_TRUE(video.IsOpen());
  Rasterizer rasterizer;
  BitMask truth_mask(640, 480);
  cv::Mat frame;
  int decoded = 0;
  while (video.Read(frame)) {
    ASSERT_LT(decoded, 12);
    const BitMask seg = SegmentFrame(frame, rec.object_hsv, rec.roi, SegmentationOptions{});
    rasterizer.RasterizeTriangles(truth.rest_mesh, truth.frames[decoded].positions_px, truth_mask);
    const Disc& finger = truth.obstacles[decoded][0];
    int64_t inter = 0, uni = 0;
    for (int y = 0; y < 480; ++y) {
      for (int x = 0; x < 640; ++x) {
        if (std::hypot(x + 0.5 - finger.centre.x(), y + 0.5 - finger.centre.y()) < finger.radius_px + 4.0) {
          continue;
        }
        const bool a = seg.Get(x, y), b = truth_mask.Get(x, y);
        inter += a && b;
        uni += a || b;
      }
    }
    const double iou = static_cast<double>(inter) / std::max<int64_t>(1, uni);
    EXPECT_GE(iou, 0.98) << "frame " << decoded;
    ++decoded;
  }
  EXPECT_EQ(decoded, 12);

  // truth.json: the scenario, the effects on, per-frame figures.
  ASSERT_TRUE(std::filesystem::exists(dir / "rec" / "truth.json"));
  const auto doc = nlohmann::json::parse(testing::ReadText(dir / "rec" / "truth.json"));
  EXPECT_EQ(doc["scenario"]["name"], "small_push");
  EXPECT_EQ(doc["effects"], nlohmann::json::array({"viscoelastic"}));
  EXPECT_EQ(doc["material"]["viscous_fraction"], 0.3);
  EXPECT_EQ(doc["frames"].size(), 12u);

  // Same scenario, same seed: the same track and truth.
  Synthesize(scenario, dir / "again");
  EXPECT_EQ(testing::ReadText(dir / "rec" / "track.csv"), testing::ReadText(dir / "again" / "track.csv"));
  EXPECT_EQ(testing::ReadText(dir / "rec" / "truth.json"), testing::ReadText(dir / "again" / "truth.json"));
}

TEST(Synthesize, HangHasClampsAndNoForce) {
  const auto dir = testing::ScratchDir("synth_hang");
  const Scenario scenario = ParseScenario(R"(
name: small_hang
kind: hang
frames: 6
object: {waist_mm: 3}
simulation: {fine_edge_px: 12, substeps: 4}
)",
                                          "small_hang.yaml");
  Synthesize(scenario, dir / "rec");
  const Recording rec = LoadRecording(dir / "rec");
  EXPECT_EQ(rec.num_frames, 6);
  EXPECT_EQ(rec.fps, 240.0);
  EXPECT_FALSE(rec.force_obstacle.has_value());
  EXPECT_TRUE(rec.obstacles.empty());
  ASSERT_EQ(rec.clamps.size(), 1u);
  const RectPx object = ObjectRectPx(scenario);
  EXPECT_LT(rec.clamps[0].y, object.y);
  EXPECT_GT(rec.clamps[0].y + rec.clamps[0].height, object.y);
}

TEST(Synthesize, InvalidScenarioIsNamed) {
  Scenario scenario = SmallPush();
  scenario.push.depth_mm = -1.0;
  try {
    Synthesize(scenario, testing::ScratchDir("synth_bad") / "rec");
    FAIL() << "accepted a negative depth";
  } catch (const ScenarioError& e) {
    EXPECT_NE(std::string(e.what()).find("push.depth_mm = -1"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace calib::synth
