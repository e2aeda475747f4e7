#include "calib/evaluator/recording_compare.h"

#include "calib/evaluator/media.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include <filesystem>
#include <fstream>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 6;

struct Take {
  int width = 96;
  int height = 64;
  int frames = kFrames;
  /// From this frame on the disc moves 3 px further right per frame.
  int diverge_from = kFrames;
  std::vector<int> roi;  ///< empty: the whole frame
};

// A yellow disc sliding right on a dark background: a lossless (PNG) image
// sequence, recording.json and track.csv.
fs::path WriteTake(const std::string& name, const Take& take) {
  const fs::path dir = testing::ScratchDir("recording_compare_" + name);
  fs::create_directories(dir / "frames");
  std::string track = "frame\n";
  for (int i = 0; i < take.frames; ++i) {
    cv::Mat frame(take.height, take.width, CV_8UC3, cv::Scalar(60, 30, 20));
    const int x = 30 + 2 * i + (i >= take.diverge_from ? 3 * (i - take.diverge_from + 1) : 0);
    cv::circle(frame, cv::Point(x, take.height / 2), 12, cv::Scalar(40, 200, 220), cv::FILLED);
    char file[32];
    std::snprintf(file, sizeof(file), "%06d.png", i);
    EXPECT_TRUE(WriteImage(dir / "frames" / file, frame));
    track += std::to_string(i) + "\n";
  }
  nlohmann::json doc = {{"format", "sponge-recording/1"},
                        {"video", "frames/%06d.png"},
                        {"track", "track.csv"},
                        {"fps", 30},
                        {"object", {{"color_hsv_lower", {20, 90, 90}}, {"color_hsv_upper", {40, 255, 255}}}}};
  if (!take.roi.empty()) doc["roi"] = take.roi;
  std::ofstream(dir / "recording.json") << doc.dump(2);
  std::ofstream(dir / "track.csv") << track;
  return dir;
}

RecordingDifference Compare(const fs::path& a, const fs::path& b) {
  return CompareRecordings(LoadRecording(a), LoadRecording(b), SegmentationOptions{}, fs::path());
}

std::string CompareError(const fs::path& a, const fs::path& b) {
  try {
    Compare(a, b);
  } catch (const RecordingError& e) {
    return e.what();
  }
  ADD_FAILURE() << "comparing " << a << " with " << b << " did not throw";
  return "";
}

#define EXPECT_HAS(message, part) \
  EXPECT_NE(std::string(message).find(part), std::string::npos) << "message: " << (message)

TEST(CompareRecordings, ARecordingDoesNotDifferFromItself) {
  const fs::path a = WriteTake("self", {});
  const RecordingDifference d = Compare(a, a);
  ASSERT_EQ(d.frames.size(), static_cast<size_t>(kFrames));
  for (const FrameDifference& f : d.frames) {
    EXPECT_EQ(f.xor_px, 0);
    EXPECT_GT(f.a_px, 400);  // a disc of radius 12: ~450 px
    EXPECT_EQ(f.a_px, f.b_px);
    EXPECT_DOUBLE_EQ(f.iou, 1.0);
  }
  EXPECT_EQ(d.XorSum(), 0);
  EXPECT_DOUBLE_EQ(d.MeanIou(), 1.0);
}

TEST(CompareRecordings, CountsTheFramesWhereTheTakesDivergeAndIsSymmetric) {
  const fs::path a = WriteTake("take_a", {});
  Take diverging;
  diverging.diverge_from = 3;
  const fs::path b = WriteTake("take_b", diverging);
  const RecordingDifference ab = Compare(a, b);
  const RecordingDifference ba = Compare(b, a);
  ASSERT_EQ(ab.frames.size(), static_cast<size_t>(kFrames));
  for (int f = 0; f < kFrames; ++f) {
    const FrameDifference& x = ab.frames[f];
    if (f < 3) {
      EXPECT_EQ(x.xor_px, 0) << "frame " << f;
    } else {
      // b's disc is 3 (f - 2) px to the right: a crescent on each side.
      EXPECT_GT(x.only_a_px, 0) << "frame " << f;
      EXPECT_GT(x.only_b_px, 0) << "frame " << f;
      EXPECT_GT(x.xor_px, ab.frames[f - 1].xor_px) << "frame " << f;
      EXPECT_LT(x.iou, 1.0);
    }
    EXPECT_EQ(x.xor_px, x.only_a_px + x.only_b_px);
    EXPECT_EQ(x.xor_px, ba.frames[f].xor_px);
    EXPECT_EQ(x.only_a_px, ba.frames[f].only_b_px);
    EXPECT_EQ(x.a_px, ba.frames[f].b_px);
  }
  EXPECT_GT(ab.XorSum(), 0);
  EXPECT_EQ(ab.XorSum(), ba.XorSum());
}

TEST(CompareRecordings, TakesWithDifferentRoisAreComparedOverTheWholeFrame) {
  const fs::path a = WriteTake("roi_whole", {});
  Take part;
  part.roi = {4, 8, 80, 50};
  const fs::path b = WriteTake("roi_part", part);
  const RecordingDifference d = Compare(a, b);
  EXPECT_EQ(d.XorSum(), 0);
  EXPECT_GT(d.frames.front().b_px, 400);
}

TEST(CompareRecordingsError, DifferentFrameCountsNameBothRecordings) {
  const fs::path a = WriteTake("count_a", {});
  Take shorter;
  shorter.frames = kFrames - 2;
  const fs::path b = WriteTake("count_b", shorter);
  const std::string message = CompareError(a, b);
  EXPECT_HAS(message, a.filename().string());
  EXPECT_HAS(message, b.filename().string());
  EXPECT_HAS(message, "6 frames");
  EXPECT_HAS(message, "4 frames");
}

TEST(CompareRecordingsError, DifferentFrameSizesNameBothSizes) {
  const fs::path a = WriteTake("size_a", {});
  Take narrower;
  narrower.width = 80;
  const fs::path b = WriteTake("size_b", narrower);
  const std::string message = CompareError(a, b);
  EXPECT_HAS(message, "96x64");
  EXPECT_HAS(message, "80x64");
  EXPECT_HAS(message, b.filename().string());
}

}  // namespace
}  // namespace calib
