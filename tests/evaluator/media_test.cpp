// Video and image files through the media module (evaluator/media.h): what
// a reader or writer does when nothing is open or the file is missing, an
// image and a video read back as written, and the codes of codecs.
// Recordings, overlays and synthetic videos use it end to end
// (recording_test, overlay_test, synthesize_test).

#include "calib/evaluator/media.h"

#include "support/test_support.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

namespace calib {
namespace {

// cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), as OpenCV documents the code:
// the first character in the low byte.
static_assert(FourCC("MJPG") == 0x47504A4D);
static_assert(FourCC("mp4v") == ('m' | 'p' << 8 | '4' << 16 | 'v' << 24));

TEST(Media, FourCCOfAnythingButFourCharactersIsZero) {
  EXPECT_EQ(FourCC(""), 0);
  EXPECT_EQ(FourCC("avc"), 0);
  EXPECT_EQ(FourCC("avc1x"), 0);
}

TEST(Media, NothingOpenReadsAndWritesNothing) {
  VideoReader reader;
  EXPECT_FALSE(reader.IsOpen());
  cv::Mat frame;
  EXPECT_FALSE(reader.Read(frame));
  EXPECT_FALSE(reader.Grab());
  EXPECT_EQ(reader.StatedFrameCount(), 0.0);
  EXPECT_EQ(reader.StatedWidth(), 0.0);
  VideoWriter writer;
  EXPECT_FALSE(writer.IsOpen());
  writer.Write(cv::Mat(4, 4, CV_8UC3));  // dropped, as OpenCV drops it
  writer.Release();
  EXPECT_FALSE(writer.IsOpen());
}

TEST(Media, AMissingFileOpensNoVideoAndReadsNoImage) {
  const auto dir = testing::ScratchDir("media_missing");
  VideoReader reader(dir / "absent.avi");
  EXPECT_FALSE(reader.IsOpen());
  cv::Mat frame;
  EXPECT_FALSE(reader.Read(frame));
  EXPECT_TRUE(ReadImage(dir / "absent.png").empty());
  EXPECT_FALSE(WriteImage(dir / "no_such_folder" / "image.png", cv::Mat(4, 4, CV_8UC3)));
}

TEST(Media, AnImageReadsBackAsWrittenInColourOrGrey) {
  const auto dir = testing::ScratchDir("media_image");
  cv::Mat image(24, 32, CV_8UC3, cv::Scalar(10, 20, 30));
  cv::circle(image, {16, 12}, 6, cv::Scalar(200, 100, 50), cv::FILLED);
  ASSERT_TRUE(WriteImage(dir / "image.png", image));
  const cv::Mat back = ReadImage(dir / "image.png");
  ASSERT_EQ(back.type(), CV_8UC3);
  EXPECT_EQ(cv::norm(back, image, cv::NORM_INF), 0.0) << "PNG is lossless";
  const cv::Mat grey = ReadImage(dir / "image.png", ImageMode::kGrey);
  EXPECT_EQ(grey.type(), CV_8UC1);
  EXPECT_EQ(grey.size(), image.size());
}

TEST(Media, AVideoReadsBackItsFramesAndStatesItsSize) {
  const auto dir = testing::ScratchDir("media_video");
  const cv::Size size(64, 48);
  {
    VideoWriter writer;
    ASSERT_TRUE(writer.Open(dir / "video.avi", FourCC("MJPG"), 10.0, size));
    for (int f = 0; f < 6; ++f) writer.Write(cv::Mat(size, CV_8UC3, cv::Scalar(40 * f, 0, 0)));
  }  // the destructor finishes the file
  VideoReader reader(dir / "video.avi");
  ASSERT_TRUE(reader.IsOpen());
  EXPECT_EQ(reader.StatedWidth(), 64.0);
  EXPECT_EQ(reader.StatedHeight(), 48.0);
  EXPECT_EQ(reader.StatedFrameCount(), 6.0);
  EXPECT_TRUE(reader.Grab());  // frame 0 skipped
  cv::Mat frame;
  int frames = 1;
  while (reader.Read(frame)) {
    EXPECT_EQ(frame.size(), size);
    EXPECT_NEAR(cv::mean(frame)[0], 40.0 * frames, 3.0) << "frame " << frames << " (JPEG)";
    ++frames;
  }
  EXPECT_EQ(frames, 6);
  VideoReader moved = std::move(reader);
  EXPECT_TRUE(moved.IsOpen());
  EXPECT_FALSE(moved.Read(frame)) << "the end stays the end";
}

}  // namespace
}  // namespace calib
