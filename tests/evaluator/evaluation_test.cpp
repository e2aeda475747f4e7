// Evaluating candidates on the reference scene: the score is the sum of the
// per-frame XOR of pixel areas with the mesh's sub-pixel coverage (on_frame
// gets the pixels covered at least half as a bit mask), identical input gives
// bit-identical results, a blow-up is a failed result with its reason and
// frame (never an exception) whose mean IoU counts the frames it did not
// simulate as 0, and the scene is built from the recording as the spec says.

#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/mask_geometry.h"
#include "calib/evaluator/recording.h"
#include "calib/evaluator/segmentation.h"

#include "reference_scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {
namespace {

const PreparedRecording& Reference() { return bench::ShortReferenceScene(); }

TEST(Evaluator, RestShapeMatchesItsOwnMaskInFrameZero) {
  Evaluator evaluator(Reference(), {});
  const EvaluationResult result = evaluator.Evaluate(bench::ReferenceParameters());
  ASSERT_TRUE(result.ok()) << result.failure_reason;
  ASSERT_EQ(result.frames.size(), 60u);
  // Its outline runs along pixel edges, so it covers whole pixels.
  EXPECT_EQ(result.frames[0].xor_px, 0.0);
  EXPECT_DOUBLE_EQ(result.frames[0].iou, 1.0);
  // The finger dents the mesh later on, so later frames disagree with the
  // (static) object mask.
  EXPECT_GT(result.frames.back().xor_px, 0);
}

TEST(Evaluator, ScoreIsTheSumOfPerFrameXor) {
  Evaluator evaluator(Reference(), {});
  const EvaluationResult result = evaluator.Evaluate(bench::ReferenceParameters());
  double sum = 0.0;  // in frame order, as the evaluator sums
  double iou = 0.0;
  for (const FrameScore& f : result.frames) {
    sum += f.xor_px;
    iou += f.iou;
    EXPECT_EQ(f.xor_px, f.missed_px + f.extra_px);
    EXPECT_GE(f.iou, 0.0);
    EXPECT_LE(f.iou, 1.0);
  }
  EXPECT_EQ(result.xor_sum, sum);
  EXPECT_NEAR(result.mean_iou, iou / result.frames.size(), 1e-15);
  EXPECT_EQ(result.num_frames, 60);
}

TEST(Evaluator, ScoresTheCoverageAndHandsOnTheHalfCoveredPixels) {
  const PreparedRecording& prepared = Reference();
  Evaluator evaluator(prepared, {});
  Rasterizer rasterizer;
  BitMask interior(prepared.object_masks[0]);
  std::vector<PixelCoverage> boundary;
  bool any_fraction = false;
  const EvaluationResult result = evaluator.Evaluate(
      bench::ReferenceParameters(),
      [&](int frame, const Simulator& sim, const BitMask& mesh_mask, const FrameScore& score) {
        const BitMask& object = prepared.object_masks[frame];
        rasterizer.RasterizeMeshCoverage(prepared.mesh, sim.positions(), interior, boundary);
        const FrameScore expected = CompareCoverage(object, interior, boundary);
        EXPECT_EQ(score.xor_px, expected.xor_px) << "frame " << frame;
        EXPECT_EQ(score.iou, expected.iou) << "frame " << frame;
        any_fraction |= score.xor_px != std::floor(score.xor_px);
        AddHalfCovered(boundary, interior);
        EXPECT_TRUE(mesh_mask == interior) << "frame " << frame;
        // Rounding a pixel's coverage moves its XOR by at most a half.
        EXPECT_NEAR(CompareMasks(object, mesh_mask).xor_px, score.xor_px,
                    0.5 * static_cast<double>(boundary.size()))
            << "frame " << frame;
      });
  ASSERT_TRUE(result.ok()) << result.failure_reason;
  EXPECT_TRUE(any_fraction) << "the dented mesh covers pixels in part";
  // Without a callback (no bit mask made): the same scores.
  const EvaluationResult plain = evaluator.Evaluate(bench::ReferenceParameters());
  ASSERT_EQ(plain.frames.size(), result.frames.size());
  for (size_t f = 0; f < plain.frames.size(); ++f) {
    EXPECT_EQ(plain.frames[f].xor_px, result.frames[f].xor_px) << "frame " << f;
  }
  EXPECT_EQ(plain.xor_sum, result.xor_sum);
}

TEST(FarthestPixelFrom, IsTheTipOfAHangingStrip) {
  // A 10 px wide strip hanging from (50, 0) to row 79, its foot turned right.
  BitMask mask(100, 100, 20, 10);
  for (int y = 0; y < 80; ++y) mask.SetSpan(y, 25, 35);
  for (int x = 35; x < 60; ++x) mask.Set(x, 79);
  const Vec2 clamp(50.0, 10.0);  // frame pixels: the mask's origin is (20, 10)
  const Vec2 tip = FarthestPixelFrom(mask, clamp);
  EXPECT_EQ(tip, Vec2(20 + 59 + 0.5, 10 + 79 + 0.5));
  EXPECT_TRUE(std::isnan(FarthestPixelFrom(BitMask(10, 10), clamp).x()));
}

TEST(FirstFrames, ScoresTheFirstFramesExactlyAsTheWholeRecordingDoes) {
  const PreparedRecording cut = FirstFrames(Reference(), 25);
  EXPECT_EQ(cut.scene.num_frames, 25);
  EXPECT_EQ(cut.recording.num_frames, 25);
  EXPECT_EQ(cut.object_masks.size(), 25u);
  EXPECT_EQ(cut.scene.forces.size(), Reference().scene.forces.empty() ? 0u : 25u);
  EXPECT_EQ(cut.scene.obstacle_discs.size(), 25u * static_cast<size_t>(cut.scene.num_obstacles));
  Evaluator whole(Reference(), {});
  Evaluator first(cut, {});
  const EvaluationResult a = whole.Evaluate(bench::ReferenceParameters());
  const EvaluationResult b = first.Evaluate(bench::ReferenceParameters());
  ASSERT_EQ(b.frames.size(), 25u);
  for (size_t f = 0; f < b.frames.size(); ++f) EXPECT_EQ(b.frames[f].xor_px, a.frames[f].xor_px) << f;
  EXPECT_EQ(FirstFrames(Reference(), 1000).scene.num_frames, Reference().scene.num_frames)
      << "more frames than it has: all of them";
  EXPECT_THROW(FirstFrames(Reference(), 0), std::invalid_argument);
}

TEST(PrepareSegmented, IsPrepareRecordingAfterItsSegmentation) {
  const Recording recording =
      LoadRecording(std::filesystem::path(CALIB_SOURCE_DIR) / "examples" / "push_centre");
  PreparationOptions options;
  options.cache_dir = CALIB_TEST_CACHE_DIR;
  const PreparedRecording whole = PrepareRecording(recording, options);
  const PreparedRecording again = PrepareSegmented(
      recording, SegmentRecording(recording, options.segmentation, options.cache_dir), options);
  EXPECT_EQ(again.object_masks, whole.object_masks);
  EXPECT_EQ(again.outline, whole.outline);
  EXPECT_EQ(again.mesh.rest_positions, whole.mesh.rest_positions);
  EXPECT_EQ(again.mesh.triangles, whole.mesh.triangles);
  EXPECT_EQ(again.scene.obstacle_discs.size(), whole.scene.obstacle_discs.size());
  EXPECT_EQ(again.scene.forces, whole.scene.forces);
  EXPECT_EQ(again.motion_blur_frames, whole.motion_blur_frames);
  EXPECT_TRUE(whole.registered_iou.empty()) << "a pushed object is not tracked";
}

TEST(PrepareSegmented, MasksThatDoNotFitTheRecordingAreNamed) {
  const PreparedRecording& reference = Reference();
  const std::string video = reference.recording.video_path.string();
  auto message = [&](std::vector<BitMask> masks) -> std::string {
    try {
      PrepareSegmented(reference.recording, std::move(masks), {});
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "no error";
  };
  std::vector<BitMask> fewer = reference.object_masks;
  fewer.pop_back();
  const std::string count = message(fewer);
  EXPECT_NE(count.find(video), std::string::npos) << count;
  EXPECT_NE(count.find("59 masks for its 60 frames"), std::string::npos) << count;

  std::vector<BitMask> resized = reference.object_masks;
  resized[3] = BitMask(resized[3].width() + 1, resized[3].height(), resized[3].origin_x(),
                       resized[3].origin_y());
  const std::string size = message(resized);
  EXPECT_NE(size.find("the mask of frame 3"), std::string::npos) << size;

  std::vector<BitMask> empty = reference.object_masks;
  empty[0].Clear();
  const std::string none = message(empty);
  EXPECT_NE(none.find("no object found in frame 0"), std::string::npos) << none;
}

TEST(Evaluator, IdenticalInputGivesBitIdenticalScore) {
  Evaluator a(Reference(), {});
  Evaluator b(Reference(), {});
  const ModelParameters p = bench::ReferenceParameters();
  const EvaluationResult first = a.Evaluate(p);
  ModelParameters other = p;
  other.k_distance *= 3.0;
  a.Evaluate(other);  // a reused evaluator carries nothing over
  const EvaluationResult again = a.Evaluate(p);
  const EvaluationResult fresh = b.Evaluate(p);
  ASSERT_EQ(first.frames.size(), again.frames.size());
  for (size_t f = 0; f < first.frames.size(); ++f) {
    EXPECT_EQ(first.frames[f].xor_px, again.frames[f].xor_px) << "frame " << f;
    EXPECT_EQ(first.frames[f].xor_px, fresh.frames[f].xor_px) << "frame " << f;
  }
  EXPECT_EQ(first.xor_sum, again.xor_sum);
  EXPECT_EQ(first.mean_iou, fresh.mean_iou);
}

TEST(Evaluator, BlowUpIsAFailedResultWithReasonAndFrame) {
  Evaluator evaluator(Reference(), {});
  ModelParameters p = bench::ReferenceParameters();
  p.k_distance = 1e12;
  p.mass = 1e-9;
  EvaluationResult result;
  ASSERT_NO_THROW(result = evaluator.Evaluate(p));
  EXPECT_EQ(result.status, EvaluationStatus::kFailed);
  EXPECT_FALSE(result.failure_reason.empty());
  EXPECT_GE(result.failure_frame, 1);
  EXPECT_EQ(static_cast<int>(result.frames.size()), result.failure_frame);
  // The same evaluator still scores the next candidate normally.
  EXPECT_TRUE(evaluator.Evaluate(bench::ReferenceParameters()).ok());
}

TEST(Evaluator, AFailedResultsMeanIouCountsTheFramesNotSimulatedAsZero) {
  Evaluator evaluator(Reference(), {});
  ModelParameters p = bench::ReferenceParameters();
  p.k_distance = 1e12;
  p.mass = 1e-9;
  const EvaluationResult result = evaluator.Evaluate(p);
  ASSERT_FALSE(result.ok());
  ASSERT_FALSE(result.frames.empty());
  ASSERT_LT(result.frames.size(), 60u);
  double iou = 0.0;
  for (const FrameScore& f : result.frames) iou += f.iou;
  // Frame 0 is the rest shape (IoU 1): averaged over the frames simulated
  // alone, the failure would look as good as a perfect fit.
  EXPECT_NEAR(result.mean_iou, iou / 60.0, 1e-15);
  EXPECT_LT(result.mean_iou, 0.5 * iou / static_cast<double>(result.frames.size()))
      << "a failure at frame " << result.failure_frame << " of 60";
}

TEST(BuildScene, TakesObstaclesForceAndClampsFromTheRecording) {
  Recording rec;
  rec.fps = 25.0;
  rec.num_frames = 3;
  rec.obstacles = {{"finger", {{Vec2(1, 2), 3}, {Vec2(4, 5), 3}, {Vec2(7, 8), 3}}},
                   {"pencil", {{Vec2(9, 9), 1}, {Vec2(9, 9), 1}, {Vec2(9, 9), 1}}}};
  rec.force_obstacle = "pencil";
  rec.forces = {Vec2(0, 1), Vec2(0, 2), Vec2(0, 3)};
  rec.clamps = {{10, 20, 30, 40}};
  const Scene scene = BuildScene(rec);
  EXPECT_DOUBLE_EQ(scene.frame_time_s, 0.04);
  EXPECT_EQ(scene.num_obstacles, 2);
  EXPECT_EQ(scene.force_obstacle, 1);
  EXPECT_EQ(scene.ObstaclesAt(1)[0].centre, Vec2(4, 5));
  EXPECT_EQ(scene.ObstaclesAt(2)[1].centre, Vec2(9, 9));
  ASSERT_EQ(scene.forces.size(), 3u);
  ASSERT_EQ(scene.clamps.size(), 1u);
  EXPECT_TRUE(scene.clamps[0].Contains(Vec2(25, 45)));
  EXPECT_FALSE(scene.clamps[0].Contains(Vec2(5, 45)));
}

}  // namespace
}  // namespace calib

namespace calib {
namespace {

// A 20 x 60 px block whose top-left corner is at x(f) in frame f.
std::vector<BitMask> MovingBlock(int frames, const std::function<double(int)>& x) {
  std::vector<BitMask> masks;
  for (int f = 0; f < frames; ++f) {
    BitMask mask(400, 200);
    const int left = static_cast<int>(std::lround(x(f)));
    for (int y = 50; y < 110; ++y) mask.SetSpan(y, left, left + 20);
    masks.push_back(std::move(mask));
  }
  return masks;
}

Recording HangingRecording() {
  Recording recording;
  recording.fps = 240.0;
  recording.clamps.push_back({150, 40, 30, 12});
  return recording;
}

TEST(EstimateObservedMotion, MeanOffsetAndStartVelocityOfASwing) {
  // x(f) = 150 + 80 cos(w f) + 100 sin(w f), period 96 frames, over 5 whole
  // periods: mean offset -80 px from the start, start velocity 100 w px/frame.
  const double w = 2.0 * M_PI / 96.0;
  const std::vector<BitMask> masks = MovingBlock(
      480, [&](int f) { return 150.0 + 80.0 * std::cos(w * f) + 100.0 * std::sin(w * f); });
  const Scene::ObservedMotion motion = EstimateObservedMotion(HangingRecording(), masks);
  ASSERT_TRUE(motion.known);
  EXPECT_NEAR(motion.equilibrium_offset_px.x(), -80.0, 0.1);
  EXPECT_NEAR(motion.equilibrium_offset_px.y(), 0.0, 1e-12);
  // Pixel rounding of the block's position limits the slope's accuracy.
  const double velocity = 100.0 * w * 240.0;
  EXPECT_NEAR(motion.initial_velocity_px_s.x(), velocity, 0.1 * velocity);
  EXPECT_NEAR(motion.initial_velocity_px_s.y(), 0.0, 1e-9);
}

TEST(EstimateObservedMotion, AStraightMotionHasItsExactVelocity) {
  const std::vector<BitMask> masks = MovingBlock(9, [](int f) { return 100.0 + 2.0 * f; });
  const Scene::ObservedMotion motion = EstimateObservedMotion(HangingRecording(), masks);
  ASSERT_TRUE(motion.known);
  EXPECT_NEAR(motion.initial_velocity_px_s.x(), 2.0 * 240.0, 1e-9);
  EXPECT_NEAR(motion.equilibrium_offset_px.x(), 8.0, 1e-9);  // mean of 0, 2, ..., 16
}

TEST(EstimateObservedMotion, UnknownWithoutClampsWithObstaclesOrWithoutAnObjectInFrameZero) {
  const std::vector<BitMask> masks = MovingBlock(9, [](int f) { return 100.0 + 2.0 * f; });
  Recording free_object = HangingRecording();
  free_object.clamps.clear();
  EXPECT_FALSE(EstimateObservedMotion(free_object, masks).known);

  Recording pushed = HangingRecording();
  pushed.obstacles.push_back({"finger", std::vector<Disc>(masks.size())});
  EXPECT_FALSE(EstimateObservedMotion(pushed, masks).known);

  std::vector<BitMask> late = masks;
  late[0] = BitMask(400, 200);
  EXPECT_FALSE(EstimateObservedMotion(HangingRecording(), late).known);
}

// Motion blur: the mesh's outline nodes are moved outwards by the blur
// times their speed across the outline. The area the mesh covers grows by
// that displacement times each node's share of the outline (to first
// order), and not at all where nothing moves.
TEST(Evaluator, ScoresTheMeshAsTheCameraSeesItWithMotionBlur) {
  PreparedRecording blurred = Reference();
  blurred.motion_blur_frames = 0.5;
  const Mesh& mesh = blurred.mesh;
  std::vector<double> sharp_area, seen_area, expected_growth;
  std::vector<Vec2> last;
  const auto area = [&](const PreparedRecording& p, int f, const FrameScore& score) {
    return static_cast<double>(p.object_masks[f].Count()) - score.missed_px + score.extra_px;
  };
  Evaluator sharp(Reference(), {});
  ASSERT_TRUE(sharp.Evaluate(bench::ReferenceParameters(),
                             [&](int f, const Simulator& sim, const BitMask&, const FrameScore& score) {
                               sharp_area.push_back(area(Reference(), f, score));
                               const std::vector<Vec2>& x = sim.positions();
                               double growth = 0.0;
                               for (const std::vector<int>& loop : mesh.boundary_loops) {
                                 const size_t n = loop.size();
                                 for (size_t k = 0; k < n; ++k) {
                                   const Vec2& prev = x[loop[(k + n - 1) % n]];
                                   const Vec2& next = x[loop[(k + 1) % n]];
                                   const Vec2 chord = next - prev;
                                   const Vec2 normal = Vec2(chord.y(), -chord.x()).normalized();
                                   const Vec2 step = f == 0 ? Vec2::Zero() : Vec2(x[loop[k]] - last[loop[k]]);
                                   const double moved = blurred.motion_blur_frames * std::abs(step.dot(normal));
                                   growth += moved * 0.5 * chord.norm();  // the node's share of the outline
                                 }
                               }
                               expected_growth.push_back(growth);
                               last = x;
                             })
                  .ok());
  Evaluator seen(blurred, {});
  ASSERT_TRUE(seen.Evaluate(bench::ReferenceParameters(),
                            [&](int f, const Simulator&, const BitMask&, const FrameScore& score) {
                              seen_area.push_back(area(blurred, f, score));
                            })
                  .ok());
  ASSERT_EQ(seen_area.size(), sharp_area.size());
  EXPECT_EQ(seen_area[0], sharp_area[0]) << "nothing moves before frame 0";
  double growth = 0.0, expected = 0.0;
  for (size_t f = 1; f < seen_area.size(); ++f) {
    EXPECT_GE(seen_area[f], sharp_area[f] - 1e-9) << "frame " << f;
    growth += seen_area[f] - sharp_area[f];
    expected += expected_growth[f];
  }
  ASSERT_GT(expected, 1.0) << "the finger moves the outline";
  EXPECT_NEAR(growth, expected, 0.05 * expected);
}

// A block that swings and whose mask is widened by 0.3 frames times its
// speed on each side (blur) gives a blur of 0.3; the same swing unwidened
// or widened by too little to show, and a still block, give none.
TEST(EstimateMotionBlur, TheMasksWideningWithSpeedIsTheBlur) {
  const double w = 2.0 * M_PI / 48.0;
  const auto swing = [&](double b) {
    std::vector<BitMask> masks;
    for (int f = 0; f < 480; ++f) {
      const double x = 150.0 + 60.0 * std::sin(w * f);
      const double widen = b * std::abs(60.0 * w * std::cos(w * f));
      BitMask mask(400, 200);
      for (int y = 50; y < 110; ++y) {
        mask.SetSpan(y, static_cast<int>(std::lround(x - widen)),
                     static_cast<int>(std::lround(x + 20.0 + widen)));
      }
      masks.push_back(std::move(mask));
    }
    return masks;
  };
  EXPECT_NEAR(EstimateMotionBlur(swing(0.3)), 0.3, 0.03);
  EXPECT_EQ(EstimateMotionBlur(swing(0.0)), 0.0);
  EXPECT_EQ(EstimateMotionBlur(swing(0.02)), 0.0) << "under a twentieth of a frame: not shown";
  const std::vector<BitMask> still = MovingBlock(100, [](int) { return 100.0; });
  EXPECT_EQ(EstimateMotionBlur(still), 0.0);
  EXPECT_EQ(EstimateMotionBlur({}), 0.0);
}

}  // namespace
}  // namespace calib
