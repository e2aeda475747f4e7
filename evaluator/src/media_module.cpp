// libcalib_media.so: OpenCV's videoio and imgcodecs behind the entry points
// of media_module.h, loaded by media.cpp on first use.

#include "media_module.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

namespace calib::media_module {
namespace {

static_assert(kFrameWidth == cv::CAP_PROP_FRAME_WIDTH);
static_assert(kFrameHeight == cv::CAP_PROP_FRAME_HEIGHT);
static_assert(kFrameCount == cv::CAP_PROP_FRAME_COUNT);
static_assert(kAnyApi == cv::CAP_ANY);
static_assert(kFfmpegApi == cv::CAP_FFMPEG);

class OpenCvCapture final : public Capture {
 public:
  explicit OpenCvCapture(const std::string& path) : capture_(path) {}
  bool IsOpened() const override { return capture_.isOpened(); }
  bool Read(cv::Mat& frame) override { return capture_.read(frame); }
  bool Grab() override { return capture_.grab(); }
  double Get(int property) override { return capture_.get(property); }

 private:
  cv::VideoCapture capture_;
};

class OpenCvWriter final : public Writer {
 public:
  OpenCvWriter(const std::string& path, int api, int fourcc, double fps, cv::Size size,
               bool colour) {
    writer_.open(path, api, fourcc, fps, size, colour);
  }
  bool IsOpened() const override { return writer_.isOpened(); }
  void Write(const cv::Mat& frame) override { writer_.write(frame); }
  void Release() override { writer_.release(); }

 private:
  cv::VideoWriter writer_;
};

std::unique_ptr<Capture> OpenCapture(const std::string& path) {
  return std::make_unique<OpenCvCapture>(path);
}

std::unique_ptr<Writer> OpenWriter(const std::string& path, int api, int fourcc, double fps,
                                   cv::Size size, bool colour) {
  return std::make_unique<OpenCvWriter>(path, api, fourcc, fps, size, colour);
}

bool WriteImage(const std::string& path, const cv::Mat& image) { return cv::imwrite(path, image); }

cv::Mat ReadImage(const std::string& path, int flags) { return cv::imread(path, flags); }

constexpr EntryPoints kEntryPoints{kVersion, OpenCapture, OpenWriter, WriteImage, ReadImage};

}  // namespace
}  // namespace calib::media_module

extern "C" __attribute__((visibility("default"))) const calib::media_module::EntryPoints*
calib_media_entry_points() {
  return &calib::media_module::kEntryPoints;
}
