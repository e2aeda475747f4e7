#pragma once
// Segmentation of the object in the video frames: an HSV range test on the
// roi, cleaned by morphology, reduced to the largest connected component.

#include "calib/evaluator/bit_mask.h"
#include "calib/evaluator/recording.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace calib {

struct SegmentationOptions {
  /// Radius of the elliptic kernel of the morphological opening that removes
  /// speckles, pixels (kernel 2r+1 wide); 0: no opening.
  int open_radius_px = 1;
  /// Radius of the elliptic kernel of the closing that bridges small gaps,
  /// pixels; 0: no closing.
  int close_radius_px = 2;
  /// Fill the holes (background regions not connected to the roi border)
  /// inside the kept component.
  bool fill_holes = true;

  /// False, with a message naming the field, its value and the rule, when
  /// an option is out of range.
  bool IsValid(std::string* error) const;

  /// A string that differs whenever the options (or the algorithm version)
  /// would change a mask; part of the segmentation cache key.
  std::string CacheKey() const;
};

/// The object mask of one frame. `bgr` is CV_8UC3 (BGR); `roi` must lie
/// inside it and `opt` must be valid (std::invalid_argument otherwise).
/// Steps: cv::inRange on the HSV roi (inclusive), opening then closing with
/// elliptic kernels, the largest 8-connected component, its holes filled
/// when opt.fill_holes. Returns a roi.width x roi.height mask with origin
/// (roi.x, roi.y); all zero when no pixel is in range.
BitMask SegmentFrame(const cv::Mat& bgr, const HsvRange& hsv, const PixelRect& roi,
                     const SegmentationOptions& opt);

/// The object masks of frames [0, rec.num_frames) of the recording, each as
/// SegmentFrame returns it with rec.object_hsv and rec.roi. Decodes the
/// video once. When `cache_dir` is non-empty, reads the masks from the cache
/// there when an entry for the same video content, hsv range, roi and
/// opt.CacheKey() exists and is intact, and otherwise stores them there
/// (a cache that cannot be written is skipped silently). Throws
/// RecordingError when the video cannot be opened, yields fewer frames than
/// rec.num_frames or frames of another size; std::invalid_argument when
/// `opt` is invalid.
std::vector<BitMask> SegmentRecording(const Recording& rec, const SegmentationOptions& opt,
                                      const std::filesystem::path& cache_dir);

/// The files a video is read from, in order: the file itself, or the files
/// of an image sequence ("frames/%06d.png") from its first index (the first
/// of 0..1000 that exists) to the last before a gap.
std::vector<std::filesystem::path> VideoFiles(const std::filesystem::path& video);

/// The key under which SegmentRecording caches the masks of `rec` with
/// `opt`: FNV-1a 64 of the video's bytes (every file of an image sequence),
/// the hsv range, roi, frame count and opt.CacheKey(). Throws RecordingError
/// when a video file cannot be read.
uint64_t SegmentationCacheKey(const Recording& rec, const SegmentationOptions& opt);

/// $CALIB_CACHE_DIR, else $XDG_CACHE_HOME/calib/segmentation, else
/// $HOME/.cache/calib/segmentation; empty when none of them is set.
std::filesystem::path DefaultSegmentationCacheDir();

}  // namespace calib
