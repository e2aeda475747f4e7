// `calib segment --preview`'s work: the chosen frames' masks are the ones
// the score uses, drawn over the frames; other bounds can be tried; a frame
// out of range or bounds out of range are named.

#include "calib/evaluator/segmentation_preview.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace calib {
namespace {

const std::filesystem::path kRecording =
    std::filesystem::path(CALIB_SOURCE_DIR) / "examples" / "push_centre";

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "text: " << (text) << "\nmissing: " << (part)

TEST(SegmentationPreview, TheMasksAreTheScoresDrawnOverTheFrames) {
  const Recording rec = LoadRecording(kRecording);
  const SegmentationOptions options;
  const std::vector<SegmentationPreview> previews =
      PreviewSegmentation(rec, {120, 0}, rec.object_hsv, options);
  const std::vector<BitMask> masks = SegmentRecording(rec, options, {});
  ASSERT_EQ(previews.size(), 2u);
  for (const SegmentationPreview& p : previews) {
    SCOPED_TRACE(p.frame);
    EXPECT_EQ(p.object_px, masks.at(p.frame).Count()) << "the mask the score uses";
    EXPECT_GT(p.object_px, 50000) << "the sponge";
    EXPECT_EQ(p.image.cols, rec.frame_width);
    EXPECT_EQ(p.image.rows, rec.frame_height);
    EXPECT_EQ(p.image.type(), CV_8UC3);
  }
  EXPECT_EQ(previews[0].frame, 120) << "in the order asked";
  EXPECT_EQ(previews[1].frame, 0);
}

TEST(SegmentationPreview, OtherBoundsCanBeTried) {
  const Recording rec = LoadRecording(kRecording);
  HsvRange everything;  // the whole HSV cube: every pixel of the roi
  const std::vector<SegmentationPreview> all =
      PreviewSegmentation(rec, {0}, everything, SegmentationOptions{});
  EXPECT_EQ(all.at(0).object_px, static_cast<int64_t>(rec.roi.width) * rec.roi.height);
  HsvRange nothing;
  nothing.lower = {0, 0, 0};
  nothing.upper = {0, 0, 0};  // black only: no pixel of the bundled scene
  EXPECT_EQ(PreviewSegmentation(rec, {0}, nothing, SegmentationOptions{}).at(0).object_px, 0);
}

TEST(SegmentationPreview, AFrameOrBoundsOutOfRangeAreNamed) {
  const Recording rec = LoadRecording(kRecording);
  try {
    PreviewSegmentation(rec, {0, 999}, rec.object_hsv, SegmentationOptions{});
    ADD_FAILURE() << "frame 999 was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "frame 999 is out of range: the recording has 330 frames (0..329)");
  }
  HsvRange bad = rec.object_hsv;
  bad.upper[2] = 300;
  try {
    PreviewSegmentation(rec, {0}, bad, SegmentationOptions{});
    ADD_FAILURE() << "V up to 300 was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_CONTAINS(e.what(), "hsv V bounds");
    EXPECT_CONTAINS(e.what(), "<= 255");
  }
}

}  // namespace
}  // namespace calib
