#pragma once
// `calib segment REC --preview`: the colour segmentation of chosen frames
// drawn over the video, to set a new camera's colour bounds
// (recording.json object_hsv): the frame, the object mask that
// SegmentFrame finds tinted over it, the roi and the bounds used.

#include "calib/evaluator/recording.h"
#include "calib/evaluator/segmentation.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace calib {

struct SegmentationPreview {
  int frame = 0;
  /// Pixels of the object mask (SegmentFrame's, as the score uses).
  int64_t object_px = 0;
  /// The frame (CV_8UC3, the video's size) with the mask tinted green, the
  /// roi in yellow and a label: frame, pixels, the HSV bounds.
  cv::Mat image;
};

/// Segments frames `frames` of `rec` with the bounds `hsv` (to try bounds
/// other than the recording's object_hsv) and draws each. Throws
/// std::invalid_argument naming a frame outside [0, num_frames) or bounds
/// outside H 0..179, S and V 0..255 (or lower > upper); RecordingError when
/// the video cannot be read.
std::vector<SegmentationPreview> PreviewSegmentation(const Recording& rec,
                                                     const std::vector<int>& frames,
                                                     const HsvRange& hsv,
                                                     const SegmentationOptions& options);

}  // namespace calib
