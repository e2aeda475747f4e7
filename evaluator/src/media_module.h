#pragma once
// The interface between the evaluator and its media module
// (libcalib_media.so, media_module.cpp): the few calls of OpenCV's videoio
// and imgcodecs that the product makes, behind a table of entry points that
// media.cpp loads with dlopen on first use (media.h says why).
//
// Both sides are built by the same compiler from this one header, so the
// table passes C++ types; kVersion guards against a module left over from
// another build of the interface.

#include <opencv2/core.hpp>

#include <memory>
#include <string>

namespace calib::media_module {

inline constexpr int kVersion = 1;

/// cv::VideoCapture, opened.
class Capture {
 public:
  virtual ~Capture() = default;
  virtual bool IsOpened() const = 0;
  virtual bool Read(cv::Mat& frame) = 0;
  virtual bool Grab() = 0;
  /// cv::VideoCapture::get of a cv::CAP_PROP_* value.
  virtual double Get(int property) = 0;
};

/// cv::VideoWriter.
class Writer {
 public:
  virtual ~Writer() = default;
  virtual bool IsOpened() const = 0;
  virtual void Write(const cv::Mat& frame) = 0;
  virtual void Release() = 0;
};

/// The properties Capture::Get is asked for (cv::CAP_PROP_*; the module
/// checks that they are OpenCV's).
inline constexpr int kFrameWidth = 3;
inline constexpr int kFrameHeight = 4;
inline constexpr int kFrameCount = 7;

/// Capture back-ends: OpenCV's choice, or FFmpeg (cv::CAP_ANY, cv::CAP_FFMPEG).
inline constexpr int kAnyApi = 0;
inline constexpr int kFfmpegApi = 1900;

struct EntryPoints {
  int version;
  /// A capture of `path` (a file or an image-sequence pattern); never null,
  /// IsOpened() false when it cannot be opened.
  std::unique_ptr<Capture> (*open_capture)(const std::string& path);
  /// A writer of `path`, opened as cv::VideoWriter::open(path, api, fourcc,
  /// fps, size, colour) opens it (cv::Exception passes through); never null.
  std::unique_ptr<Writer> (*open_writer)(const std::string& path, int api, int fourcc,
                                         double fps, cv::Size size, bool colour);
  /// cv::imwrite and cv::imread.
  bool (*write_image)(const std::string& path, const cv::Mat& image);
  cv::Mat (*read_image)(const std::string& path, int flags);
};

}  // namespace calib::media_module

/// The module's one exported symbol.
extern "C" const calib::media_module::EntryPoints* calib_media_entry_points();
