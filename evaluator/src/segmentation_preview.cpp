#include "calib/evaluator/segmentation_preview.h"

#include "calib/evaluator/bit_mask_cv.h"
#include "calib/evaluator/media.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <map>
#include <stdexcept>

namespace calib {
namespace {

void CheckBounds(const HsvRange& hsv) {
  const std::array<int, 3> top{179, 255, 255};
  const char* names = "HSV";
  for (int c = 0; c < 3; ++c) {
    if (hsv.lower[c] < 0 || hsv.upper[c] > top[c] || hsv.lower[c] > hsv.upper[c]) {
      throw std::invalid_argument(fmt::format(
          "hsv {} bounds {}..{}: must satisfy 0 <= lower <= upper <= {}", names[c], hsv.lower[c],
          hsv.upper[c], top[c]));
    }
  }
}

cv::Mat Draw(const cv::Mat& frame, const BitMask& mask, const PixelRect& roi, const HsvRange& hsv,
             int index) {
  cv::Mat image = frame.clone();
  const cv::Mat on = ToMat(mask);  // roi-sized, 255 where the object is
  cv::Mat tile = image(cv::Rect(mask.origin_x(), mask.origin_y(), mask.width(), mask.height()));
  cv::Mat green(tile.size(), CV_8UC3, cv::Scalar(0, 255, 0));
  cv::Mat tinted;
  cv::addWeighted(tile, 0.5, green, 0.5, 0.0, tinted);
  tinted.copyTo(tile, on);
  cv::rectangle(image, cv::Rect(roi.x, roi.y, roi.width, roi.height), cv::Scalar(0, 255, 255), 1);
  const std::string label = fmt::format(
      "frame {}: {} px in HSV [{},{},{}]..[{},{},{}]", index, mask.Count(), hsv.lower[0],
      hsv.lower[1], hsv.lower[2], hsv.upper[0], hsv.upper[1], hsv.upper[2]);
  cv::putText(image, label, cv::Point(6, 18), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 3);
  cv::putText(image, label, cv::Point(6, 18), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(255, 255, 255), 1);
  return image;
}

}  // namespace

std::vector<SegmentationPreview> PreviewSegmentation(const Recording& rec,
                                                     const std::vector<int>& frames,
                                                     const HsvRange& hsv,
                                                     const SegmentationOptions& options) {
  CheckBounds(hsv);
  for (const int f : frames) {
    if (f < 0 || f >= rec.num_frames) {
      throw std::invalid_argument(fmt::format("{}: frame {} is out of range: the recording has {} "
                                              "frames (0..{})",
                                              rec.folder.string(), f, rec.num_frames,
                                              rec.num_frames - 1));
    }
  }
  std::map<int, SegmentationPreview> wanted;
  for (const int f : frames) wanted[f].frame = f;
  VideoReader video(rec.video_path);
  if (!video.IsOpen()) {
    throw RecordingError(rec.video_path.string() + ": cannot open video (cv::VideoCapture)");
  }
  const int last = wanted.empty() ? -1 : wanted.rbegin()->first;
  cv::Mat frame;
  for (int f = 0; f <= last; ++f) {
    if (!video.Read(frame) || frame.empty()) {
      throw RecordingError(fmt::format("{}: the video ends at frame {}", rec.video_path.string(), f));
    }
    auto it = wanted.find(f);
    if (it == wanted.end()) continue;
    const BitMask mask = SegmentFrame(frame, hsv, rec.roi, options);
    it->second.object_px = mask.Count();
    it->second.image = Draw(frame, mask, rec.roi, hsv, f);
  }
  std::vector<SegmentationPreview> out;
  for (const int f : frames) out.push_back(wanted.at(f));
  return out;
}

}  // namespace calib
