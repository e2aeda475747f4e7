#include "calib/evaluator/segmentation.h"

#include "calib/evaluator/bit_mask_cv.h"
#include "calib/evaluator/media.h"
#include "calib/evaluator/segmentation_cache.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <cctype>
#include <cstdlib>
#include <optional>
#include <stdexcept>

namespace calib {
namespace {

namespace fs = std::filesystem;

/// Bumped whenever SegmentFrame changes what it returns for the same input.
constexpr int kAlgorithmVersion = 1;

cv::Mat EllipseKernel(int radius_px) {
  return cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                   cv::Size(2 * radius_px + 1, 2 * radius_px + 1));
}

/// Sets to 255 the zero pixels of `mask` (CV_8UC1) that no 4-connected path
/// of zero pixels joins to the image border.
void FillHoles(cv::Mat* mask) {
  cv::Mat padded;
  cv::copyMakeBorder(*mask, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  cv::floodFill(padded, cv::Point(0, 0), cv::Scalar(255), nullptr, cv::Scalar(), cv::Scalar(), 4);
  // padded: 255 = object or outside; 0 = holes.
  const cv::Mat holes = padded(cv::Rect(1, 1, mask->cols, mask->rows)) == 0;
  mask->setTo(255, holes);
}

/// The name an image-sequence pattern ("frames/%06d.png": one %d, %0Nd or
/// %Nd) gives frame `index`; nullopt when `pattern` is not of that form.
std::optional<std::string> ExpandPattern(const std::string& pattern, int index) {
  const auto percent = pattern.find('%');
  if (percent == std::string::npos) return std::nullopt;
  size_t pos = percent + 1;
  const bool zero_pad = pos < pattern.size() && pattern[pos] == '0';
  if (zero_pad) ++pos;
  int width = 0;
  while (pos < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[pos]))) {
    width = 10 * width + (pattern[pos++] - '0');
    if (width > 32) return std::nullopt;
  }
  if (pos >= pattern.size() || pattern[pos] != 'd') return std::nullopt;
  if (pattern.find('%', pos + 1) != std::string::npos) return std::nullopt;
  std::string number = std::to_string(index);
  if (static_cast<int>(number.size()) < width) {
    number.insert(0, width - number.size(), zero_pad ? '0' : ' ');
  }
  return pattern.substr(0, percent) + number + pattern.substr(pos + 1);
}


std::vector<BitMask> SegmentVideo(const Recording& rec, const SegmentationOptions& opt) {
  VideoReader cap(rec.video_path);
  if (!cap.IsOpen()) {
    throw RecordingError(rec.video_path.string() + ": cannot open video (cv::VideoCapture)");
  }
  std::vector<BitMask> masks;
  masks.reserve(rec.num_frames);
  cv::Mat frame;
  for (int f = 0; f < rec.num_frames; ++f) {
    if (!cap.Read(frame) || frame.empty()) {
      throw RecordingError(
          fmt::format("{}: the video yields {} frames but the recording has {} (rows of {})",
                      rec.video_path.string(), f, rec.num_frames, rec.track_path.string()));
    }
    if (frame.cols != rec.frame_width || frame.rows != rec.frame_height) {
      throw RecordingError(fmt::format("{}: frame {} is {} x {}; expected {} x {}",
                                       rec.video_path.string(), f, frame.cols, frame.rows,
                                       rec.frame_width, rec.frame_height));
    }
    if (frame.type() != CV_8UC3) {
      throw RecordingError(fmt::format("{}: frame {} is not 8-bit BGR (OpenCV type {})",
                                       rec.video_path.string(), f, frame.type()));
    }
    masks.push_back(SegmentFrame(frame, rec.object_hsv, rec.roi, opt));
  }
  return masks;
}

}  // namespace

std::vector<fs::path> VideoFiles(const fs::path& video) {
  const std::string name = video.filename().string();
  if (name.find('%') == std::string::npos) return {video};
  const auto expand = [&](int i) {
    const std::optional<std::string> file = ExpandPattern(name, i);
    return file ? video.parent_path() / *file : fs::path();
  };
  if (expand(0).empty()) return {video};  // not a pattern: a file with '%' in its name
  int first = 0;
  while (first <= 1000 && !fs::exists(expand(first))) ++first;
  std::vector<fs::path> files;
  for (int i = first; fs::exists(expand(i)); ++i) files.push_back(expand(i));
  return files;
}

bool SegmentationOptions::IsValid(std::string* error) const {
  auto fail = [error](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (open_radius_px < 0) {
    return fail(
        fmt::format("SegmentationOptions::open_radius_px = {}. Violated: open_radius_px >= 0.",
                    open_radius_px));
  }
  if (close_radius_px < 0) {
    return fail(
        fmt::format("SegmentationOptions::close_radius_px = {}. Violated: close_radius_px >= 0.",
                    close_radius_px));
  }
  return true;
}

std::string SegmentationOptions::CacheKey() const {
  return fmt::format("seg-v{}:open={}:close={}:fill={}", kAlgorithmVersion, open_radius_px,
                     close_radius_px, fill_holes ? 1 : 0);
}

BitMask SegmentFrame(const cv::Mat& bgr, const HsvRange& hsv, const PixelRect& roi,
                     const SegmentationOptions& opt) {
  std::string error;
  if (!opt.IsValid(&error)) throw std::invalid_argument(error);
  if (bgr.type() != CV_8UC3) {
    throw std::invalid_argument(
        fmt::format("SegmentFrame: expected a CV_8UC3 image, found type {}", bgr.type()));
  }
  if (roi.x < 0 || roi.y < 0 || roi.width <= 0 || roi.height <= 0 || roi.x + roi.width > bgr.cols ||
      roi.y + roi.height > bgr.rows) {
    throw std::invalid_argument(
        fmt::format("SegmentFrame: roi [{}, {}, {}, {}] is not inside the {} x {} image",
                    roi.x, roi.y, roi.width, roi.height, bgr.cols, bgr.rows));
  }

  cv::Mat hsv_image, mask;
  cv::cvtColor(bgr(cv::Rect(roi.x, roi.y, roi.width, roi.height)), hsv_image, cv::COLOR_BGR2HSV);
  cv::inRange(hsv_image, cv::Scalar(hsv.lower[0], hsv.lower[1], hsv.lower[2]),
              cv::Scalar(hsv.upper[0], hsv.upper[1], hsv.upper[2]), mask);
  if (opt.open_radius_px > 0) {
    cv::morphologyEx(mask, mask, cv::MORPH_OPEN, EllipseKernel(opt.open_radius_px));
  }
  if (opt.close_radius_px > 0) {
    cv::morphologyEx(mask, mask, cv::MORPH_CLOSE, EllipseKernel(opt.close_radius_px));
  }

  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  int best = 0;
  int best_area = 0;
  for (int label = 1; label < n; ++label) {
    const int area = stats.at<int>(label, cv::CC_STAT_AREA);
    if (area > best_area) {
      best = label;
      best_area = area;
    }
  }
  if (best == 0) return BitMask(roi.width, roi.height, roi.x, roi.y);
  mask = labels == best;
  if (opt.fill_holes) FillHoles(&mask);
  return FromMat(mask, roi.x, roi.y);
}

uint64_t SegmentationCacheKey(const Recording& rec, const SegmentationOptions& opt) {
  uint64_t hash = Fnv1a64("calib-segmentation");
  for (const fs::path& file : VideoFiles(rec.video_path)) {
    try {
      hash = HashFileContent(file, hash);
    } catch (const std::runtime_error& e) {
      throw RecordingError(e.what());
    }
  }
  const HsvRange& h = rec.object_hsv;
  const PixelRect& r = rec.roi;
  return Fnv1a64(fmt::format("|hsv {} {} {} {} {} {}|roi {} {} {} {}|frames {}|{}", h.lower[0],
                             h.lower[1], h.lower[2], h.upper[0], h.upper[1], h.upper[2], r.x, r.y,
                             r.width, r.height, rec.num_frames, opt.CacheKey()),
                 hash);
}

std::vector<BitMask> SegmentRecording(const Recording& rec, const SegmentationOptions& opt,
                                      const fs::path& cache_dir) {
  std::string error;
  if (!opt.IsValid(&error)) throw std::invalid_argument(error);
  if (cache_dir.empty()) return SegmentVideo(rec, opt);

  const uint64_t key = SegmentationCacheKey(rec, opt);
  const fs::path file = SegmentationCachePath(cache_dir, key);
  std::vector<BitMask> masks;
  if (ReadSegmentationCache(file, key, rec.num_frames, rec.roi.width, rec.roi.height, rec.roi.x,
                            rec.roi.y, &masks)) {
    return masks;
  }
  masks = SegmentVideo(rec, opt);
  WriteSegmentationCache(file, key, masks);  // best effort: a failed write only costs time
  return masks;
}

fs::path DefaultSegmentationCacheDir() {
  auto env = [](const char* name) -> const char* {
    const char* v = std::getenv(name);
    return (v != nullptr && *v != '\0') ? v : nullptr;
  };
  if (const char* dir = env("CALIB_CACHE_DIR")) return dir;
  if (const char* dir = env("XDG_CACHE_HOME")) return fs::path(dir) / "calib" / "segmentation";
  if (const char* dir = env("HOME")) return fs::path(dir) / ".cache" / "calib" / "segmentation";
  return {};
}

}  // namespace calib
