// Video and image files through the media module (media.h).

#include "calib/evaluator/media.h"

#include "media_module.h"

#include <fmt/format.h>

#include <dlfcn.h>

#include <cstdlib>
#include <system_error>
#include <vector>

namespace calib {
namespace {

namespace fs = std::filesystem;
using media_module::EntryPoints;

constexpr const char* kMediaModuleFile = "libcalib_media.so";

std::vector<fs::path> MediaModuleCandidates() {
  if (const char* explicit_path = std::getenv("CALIB_MEDIA_MODULE");
      explicit_path != nullptr && *explicit_path != '\0') {
    return {fs::path(explicit_path)};
  }
  std::vector<fs::path> candidates;
  std::error_code ec;
  const fs::path program = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    candidates.push_back(program.parent_path().parent_path() / "lib" / "calib" / kMediaModuleFile);
  }
  const fs::path built(CALIB_MEDIA_MODULE_BUILD_PATH);
  if (candidates.empty() || candidates.front() != built) candidates.push_back(built);
  return candidates;
}

const EntryPoints* LoadEntryPoints() {
  std::string tried;
  for (const fs::path& path : MediaModuleCandidates()) {
    std::string reason;
    if (!fs::exists(path)) {
      reason = "no such file";
    } else if (void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL); handle == nullptr) {
      const char* error = dlerror();
      reason = error != nullptr ? error : "dlopen failed";
    } else {
      using Entry = const EntryPoints* (*)();
      const auto entry = reinterpret_cast<Entry>(dlsym(handle, "calib_media_entry_points"));
      const EntryPoints* points = entry != nullptr ? entry() : nullptr;
      if (points != nullptr && points->version == media_module::kVersion) return points;
      reason = points == nullptr
                   ? "no calib_media_entry_points in it"
                   : fmt::format("interface version {}, this program's is {} (a module of "
                                 "another build)",
                                 points->version, media_module::kVersion);
      dlclose(handle);
    }
    tried += fmt::format("\n  {}: {}", path.string(), reason);
  }
  throw MediaModuleError(fmt::format(
      "cannot load the video and image module {} (set CALIB_MEDIA_MODULE to its path); "
      "tried:{}",
      kMediaModuleFile, tried));
}

const EntryPoints& MediaEntryPoints() {
  // A throw leaves it uninitialised: the next call tries again.
  static const EntryPoints* const module = LoadEntryPoints();
  return *module;
}

}  // namespace

VideoReader::VideoReader() = default;
VideoReader::VideoReader(const fs::path& path) { Open(path); }
VideoReader::~VideoReader() = default;
VideoReader::VideoReader(VideoReader&&) noexcept = default;
VideoReader& VideoReader::operator=(VideoReader&&) noexcept = default;

bool VideoReader::Open(const fs::path& path) {
  capture_.reset();
  capture_ = MediaEntryPoints().open_capture(path.string());
  return capture_->IsOpened();
}

bool VideoReader::IsOpen() const { return capture_ != nullptr && capture_->IsOpened(); }

bool VideoReader::Read(cv::Mat& frame) { return IsOpen() && capture_->Read(frame); }

bool VideoReader::Grab() { return IsOpen() && capture_->Grab(); }

double VideoReader::StatedWidth() const {
  return IsOpen() ? capture_->Get(media_module::kFrameWidth) : 0.0;
}

double VideoReader::StatedHeight() const {
  return IsOpen() ? capture_->Get(media_module::kFrameHeight) : 0.0;
}

double VideoReader::StatedFrameCount() const {
  return IsOpen() ? capture_->Get(media_module::kFrameCount) : 0.0;
}

VideoWriter::VideoWriter() = default;
VideoWriter::~VideoWriter() { Release(); }
VideoWriter::VideoWriter(VideoWriter&&) noexcept = default;

VideoWriter& VideoWriter::operator=(VideoWriter&& other) noexcept {
  if (this != &other) {
    Release();
    writer_ = std::move(other.writer_);
  }
  return *this;
}

bool VideoWriter::Open(const fs::path& path, int fourcc, double fps, cv::Size frame_size,
                       Backend backend, bool colour) {
  Release();
  const int api = backend == Backend::kFfmpeg ? media_module::kFfmpegApi : media_module::kAnyApi;
  writer_ = MediaEntryPoints().open_writer(path.string(), api, fourcc, fps, frame_size, colour);
  return writer_->IsOpened();
}

bool VideoWriter::IsOpen() const { return writer_ != nullptr && writer_->IsOpened(); }

void VideoWriter::Write(const cv::Mat& frame) {
  if (IsOpen()) writer_->Write(frame);
}

void VideoWriter::Release() {
  if (writer_ != nullptr) writer_->Release();
  writer_.reset();
}

bool WriteImage(const fs::path& path, const cv::Mat& image) {
  return MediaEntryPoints().write_image(path.string(), image);
}

cv::Mat ReadImage(const fs::path& path, ImageMode mode) {
  return MediaEntryPoints().read_image(path.string(), static_cast<int>(mode));
}

}  // namespace calib
