#pragma once
// Video and image files: OpenCV's cv::VideoCapture, cv::VideoWriter,
// cv::imwrite and cv::imread, reached through a module loaded on first use.
//
//   VideoReader video(recording.video_path);
//   if (!video.IsOpen()) throw RecordingError(...);
//   cv::Mat frame;
//   while (video.Read(frame)) { ... }
//
// Why a module: Debian's videoio and imgcodecs link some 220 shared
// libraries (FFmpeg, GStreamer, GDAL, GDCM, ...), each bound at load time,
// which made every start of a program that links them cost 0.15-0.2 s of
// CPU, most of it the dynamic loader's symbol lookups, whether or not it
// reads a video: every `calib` command, MPI rank and test process. The
// evaluator links OpenCV's core and imgproc only; libcalib_media.so
// (src/media_module.cpp) links the other two and is opened with dlopen the
// first time one of these classes or functions is used.
//
// Where the module is looked for: $CALIB_MEDIA_MODULE when set (that file
// only); else lib/calib/libcalib_media.so beside the program's folder (the
// build tree's build/lib/calib, an install's <prefix>/lib/calib); else the
// build tree it was built in. A module that cannot be loaded throws
// MediaModuleError naming the paths tried and the loader's reason.

#include <opencv2/core.hpp>

#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>

namespace calib {

namespace media_module {
class Capture;
class Writer;
}  // namespace media_module

class MediaModuleError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The four-character code of a codec, as cv::VideoWriter::fourcc makes it.
constexpr int FourCC(std::string_view code) {
  return (code.size() == 4)
             ? (static_cast<int>(static_cast<unsigned char>(code[0])) |
                (static_cast<int>(static_cast<unsigned char>(code[1])) << 8) |
                (static_cast<int>(static_cast<unsigned char>(code[2])) << 16) |
                (static_cast<int>(static_cast<unsigned char>(code[3])) << 24))
             : 0;
}

/// A video file, or an image-sequence pattern such as frames/%06d.png, read
/// frame by frame (cv::VideoCapture).
class VideoReader {
 public:
  VideoReader();
  /// Open(path).
  explicit VideoReader(const std::filesystem::path& path);
  ~VideoReader();
  VideoReader(VideoReader&&) noexcept;
  VideoReader& operator=(VideoReader&&) noexcept;

  /// Opens `path`, closing what was open; false when OpenCV cannot open it.
  bool Open(const std::filesystem::path& path);
  bool IsOpen() const;
  /// The next frame (BGR as OpenCV decodes it); false at the end or when
  /// nothing is open.
  bool Read(cv::Mat& frame);
  /// Skips a frame; false at the end or when nothing is open.
  bool Grab();
  /// The size and frame count the container states (cv::CAP_PROP_FRAME_*;
  /// 0 or less where it states none or nothing is open).
  double StatedWidth() const;
  double StatedHeight() const;
  double StatedFrameCount() const;

 private:
  std::unique_ptr<media_module::Capture> capture_;
};

/// A video file written frame by frame (cv::VideoWriter).
class VideoWriter {
 public:
  /// Which of OpenCV's back-ends writes: its own choice, or FFmpeg.
  enum class Backend { kAny, kFfmpeg };

  VideoWriter();
  ~VideoWriter();
  VideoWriter(VideoWriter&&) noexcept;
  VideoWriter& operator=(VideoWriter&&) noexcept;

  /// cv::VideoWriter::open: false when the codec (FourCC) or the file cannot
  /// be opened; an encoder missing from the OpenCV build may also throw
  /// cv::Exception, as OpenCV does. Releases what was open first.
  bool Open(const std::filesystem::path& path, int fourcc, double fps, cv::Size frame_size,
            Backend backend = Backend::kAny, bool colour = true);
  bool IsOpen() const;
  /// Appends a frame (OpenCV drops one of another size or type silently).
  void Write(const cv::Mat& frame);
  /// Finishes the file; also done by the destructor.
  void Release();

 private:
  std::unique_ptr<media_module::Writer> writer_;
};

/// How ReadImage decodes (cv::IMREAD_COLOR, _GRAYSCALE, _UNCHANGED).
enum class ImageMode { kColour = 1, kGrey = 0, kUnchanged = -1 };

/// cv::imwrite: false when the file cannot be written; may throw
/// cv::Exception for an image the format cannot hold.
bool WriteImage(const std::filesystem::path& path, const cv::Mat& image);
/// cv::imread: empty when the file cannot be read or decoded.
cv::Mat ReadImage(const std::filesystem::path& path, ImageMode mode = ImageMode::kColour);

}  // namespace calib
