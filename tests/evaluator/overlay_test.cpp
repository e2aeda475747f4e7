#include "calib/evaluator/overlay.h"

#include "calib/evaluator/media.h"
#include "calib/evaluator/rasterizer.h"
#include "calib/evaluator/scoring.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace calib {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;

cv::Mat GradientFrame(int shift = 0) {
  cv::Mat frame(kHeight, kWidth, CV_8UC3);
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      frame.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uint8_t>(x + shift), static_cast<uint8_t>(y),
                                            static_cast<uint8_t>(40));
    }
  }
  return frame;
}

cv::Vec3b ToVec3b(const cv::Scalar& s) {
  return cv::Vec3b(static_cast<uint8_t>(s[0]), static_cast<uint8_t>(s[1]),
                   static_cast<uint8_t>(s[2]));
}

std::string Str(const cv::Vec3b& v) {
  return "(" + std::to_string(v[0]) + ", " + std::to_string(v[1]) + ", " + std::to_string(v[2]) +
         ")";
}

// Masks over a region of interest at frame (20, 30), 100 x 70 pixels:
// object: frame rows 40..79, columns 30..79; mesh: rows 40..79, columns 60..109.
struct OverlayScene {
  BitMask object{100, 70, 20, 30};
  BitMask mesh_mask{100, 70, 20, 30};
  Mesh mesh = testing::MakeGridMesh(4, 2, 12.5, Vec2(60, 40));
  std::vector<Disc> obstacles = {{Vec2(130.3, 100.6), 9.5}};
  OverlayScene() {
    for (int y = 40; y < 80; ++y) {
      object.SetSpan(y - 30, 30 - 20, 80 - 20);
      mesh_mask.SetSpan(y - 30, 60 - 20, 110 - 20);
    }
  }
};

TEST(RenderOverlay, IsATwoByTwoPanelOfTwiceTheFrameSize) {
  const OverlayScene s;
  const cv::Mat frame = GradientFrame();
  OverlayOptions options;
  options.frame_index = 7;
  const FrameScore score = CompareMasks(s.object, s.mesh_mask);
  options.xor_px = score.xor_px;
  options.iou = score.iou;
  const cv::Mat panel =
      RenderOverlay(frame, s.mesh, s.mesh.rest_positions, s.obstacles, s.object, s.mesh_mask,
                    options);
  ASSERT_EQ(panel.type(), CV_8UC3);
  EXPECT_EQ(panel.cols, 2 * kWidth);
  EXPECT_EQ(panel.rows, 2 * kHeight);

  // Top left: the frame, with mesh lines drawn over it.
  EXPECT_EQ(panel.at<cv::Vec3b>(110, 20), frame.at<cv::Vec3b>(110, 20)) << "far from drawings";
  // The vertical mesh edge at frame x = 85 runs between pixel columns 84 and
  // 85 (centres 84.5 and 85.5): antialiased, it tints both, and is gone two
  // pixels away.
  for (int col : {84, 85}) {
    EXPECT_NE(panel.at<cv::Vec3b>(60, col), frame.at<cv::Vec3b>(60, col))
        << "column " << col << ": " << Str(panel.at<cv::Vec3b>(60, col));
  }
  EXPECT_EQ(panel.at<cv::Vec3b>(60, 87), frame.at<cv::Vec3b>(60, 87));
  // The obstacle circle passes through (130.3 + 9.5, 100.6).
  EXPECT_NE(panel.at<cv::Vec3b>(100, 139), frame.at<cv::Vec3b>(100, 139));
  EXPECT_EQ(panel.at<cv::Vec3b>(100, 130), frame.at<cv::Vec3b>(100, 130)) << "disc centre";

  // The text labels stay within the top rows of each tile.
  const cv::Vec3b on = ToVec3b(options.mask_colour);
  const cv::Vec3b black(0, 0, 0);
  // Top right: object mask.
  EXPECT_EQ(panel.at<cv::Vec3b>(50, kWidth + 40), on);
  EXPECT_EQ(panel.at<cv::Vec3b>(50, kWidth + 90), black);
  EXPECT_EQ(panel.at<cv::Vec3b>(100, kWidth + 10), black) << "outside the masks";
  // Bottom left: mesh mask.
  EXPECT_EQ(panel.at<cv::Vec3b>(kHeight + 50, 40), black);
  EXPECT_EQ(panel.at<cv::Vec3b>(kHeight + 50, 90), on);
}

TEST(RenderOverlay, DifferencePanelShowsMissedAndExtraPixels) {
  const OverlayScene s;
  OverlayOptions options;
  const cv::Mat panel = RenderOverlay(GradientFrame(), s.mesh, s.mesh.rest_positions, {},
                                      s.object, s.mesh_mask, options);
  const auto diff = [&](int x, int y) { return panel.at<cv::Vec3b>(kHeight + y, kWidth + x); };
  const cv::Vec3b missed = ToVec3b(options.missed_colour);
  const cv::Vec3b extra = ToVec3b(options.extra_colour);
  const cv::Vec3b agreement = ToVec3b(options.agreement_colour);
  const cv::Vec3b black(0, 0, 0);
  for (int y = 40; y < 80; ++y) {
    for (int x = 20; x < 120; ++x) {
      const bool o = x >= 30 && x < 80;
      const bool m = x >= 60 && x < 110;
      const cv::Vec3b expected = o ? (m ? agreement : missed) : (m ? extra : black);
      ASSERT_EQ(diff(x, y), expected) << "frame pixel (" << x << ", " << y << ")";
    }
  }
  EXPECT_EQ(diff(125, 60), black) << "outside the masks";
  EXPECT_EQ(diff(50, 35), black) << "inside the masks, neither on";
}

TEST(RenderOverlay, RejectsBadInput) {
  const OverlayScene s;
  const std::vector<Vec2> too_few(3, Vec2::Zero());
  EXPECT_THROW(RenderOverlay(GradientFrame(), s.mesh, too_few, {}, s.object, s.mesh_mask, {}),
               std::invalid_argument);
  EXPECT_THROW(RenderOverlay(GradientFrame(), s.mesh, s.mesh.rest_positions, {}, s.object,
                             BitMask(100, 70), {}),
               std::invalid_argument);
  EXPECT_THROW(RenderOverlay(cv::Mat(), s.mesh, s.mesh.rest_positions, {}, s.object, s.mesh_mask,
                             {}),
               std::invalid_argument);
  OverlayOptions bad;
  bad.line_thickness_px = 0;
  std::string error;
  EXPECT_FALSE(bad.IsValid(&error));
  EXPECT_EQ(error, "OverlayOptions::line_thickness_px = 0. Violated: line_thickness_px >= 1.");
}

TEST(RenderOverlay, AcceptsGreyFramesAndBlownUpStates) {
  const OverlayScene s;
  cv::Mat grey(kHeight, kWidth, CV_8UC1, cv::Scalar(90));
  std::vector<Vec2> x = s.mesh.rest_positions;
  x[0] = Vec2(std::nan(""), 1e300);
  x[1] = Vec2(-1e200, 5.0);
  const cv::Mat panel = RenderOverlay(grey, s.mesh, x, s.obstacles, s.object, s.mesh_mask, {});
  EXPECT_EQ(panel.size(), cv::Size(2 * kWidth, 2 * kHeight));
  EXPECT_EQ(panel.at<cv::Vec3b>(110, 20), cv::Vec3b(90, 90, 90));
}

TEST(OverlayVideoWriter, WritesAnMp4ThatReopensWithAllFrames) {
  const auto dir = testing::ScratchDir("overlay_video");
  const auto path = dir / "overlay.mp4";
  OverlayScene s;
  Rasterizer rasterizer;
  OverlayVideoWriter video;
  ASSERT_TRUE(video.Open(path, 10.0, cv::Size(2 * kWidth, 2 * kHeight)));
  EXPECT_TRUE(video.codec() == "avc1" || video.codec() == "mp4v") << video.codec();
  constexpr int kFrames = 6;
  for (int f = 0; f < kFrames; ++f) {
    std::vector<Vec2> x = s.mesh.rest_positions;
    for (Vec2& p : x) p += Vec2(2.0 * f, 0.5 * f);
    rasterizer.RasterizeMesh(s.mesh, x, s.mesh_mask);
    OverlayOptions options;
    options.frame_index = f;
    video.Write(RenderOverlay(GradientFrame(10 * f), s.mesh, x, s.obstacles, s.object,
                              s.mesh_mask, options));
  }
  EXPECT_EQ(video.frames_written(), kFrames);
  EXPECT_THROW(video.Write(GradientFrame()), std::invalid_argument) << "wrong size";
  video.Close();

  ASSERT_TRUE(std::filesystem::exists(path));
  EXPECT_GT(std::filesystem::file_size(path), 0u);
  VideoReader capture(path);
  ASSERT_TRUE(capture.IsOpen()) << path;
  EXPECT_EQ(static_cast<int>(capture.StatedWidth()), 2 * kWidth);
  EXPECT_EQ(static_cast<int>(capture.StatedHeight()), 2 * kHeight);
  EXPECT_EQ(static_cast<int>(capture.StatedFrameCount()), kFrames);
  int decoded = 0;
  cv::Mat image;
  while (capture.Read(image)) ++decoded;
  EXPECT_EQ(decoded, kFrames);
}

TEST(OverlayVideoWriter, UnopenablePathThrowsNamingIt) {
  const auto path = testing::ScratchDir("overlay_video_bad") / "missing" / "overlay.mp4";
  OverlayVideoWriter video;
  try {
    video.Open(path, 10.0, cv::Size(64, 48));
    FAIL() << "expected std::runtime_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
  EXPECT_FALSE(video.is_open());
  EXPECT_THROW(video.Write(cv::Mat(48, 64, CV_8UC3)), std::logic_error);
}

TEST(WriteOverlayPng, RoundTripsLosslessly) {
  const auto path = testing::ScratchDir("overlay_png") / "panel.png";
  const cv::Mat image = GradientFrame();
  WriteOverlayPng(path, image);
  const cv::Mat back = ReadImage(path, ImageMode::kColour);
  ASSERT_EQ(back.size(), image.size());
  EXPECT_EQ(cv::norm(back, image, cv::NORM_INF), 0.0);
}

TEST(WriteOverlayPng, UnwritablePathThrowsNamingIt) {
  const auto path = testing::ScratchDir("overlay_png_bad") / "missing" / "panel.png";
  try {
    WriteOverlayPng(path, GradientFrame());
    FAIL() << "expected std::runtime_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace calib
