#include "calib/evaluator/recording_compare.h"

#include "calib/evaluator/scoring.h"

#include <fmt/format.h>

namespace calib {
namespace {

// `mask` placed on a whole frame of width x height (origin 0, 0).
BitMask OnWholeFrame(const BitMask& mask, int width, int height) {
  BitMask out(width, height);
  for (int y = 0; y < mask.height(); ++y) {
    for (int x = 0; x < mask.width(); ++x) {
      if (mask.Get(x, y)) out.Set(x + mask.origin_x(), y + mask.origin_y());
    }
  }
  return out;
}

}  // namespace

int64_t RecordingDifference::XorSum() const {
  int64_t sum = 0;
  for (const FrameDifference& f : frames) sum += f.xor_px;
  return sum;
}

double RecordingDifference::MeanIou() const {
  if (frames.empty()) return 0.0;
  double sum = 0.0;
  for (const FrameDifference& f : frames) sum += f.iou;
  return sum / static_cast<double>(frames.size());
}

RecordingDifference CompareRecordings(const Recording& a, const Recording& b,
                                      const SegmentationOptions& options,
                                      const std::filesystem::path& cache_dir) {
  if (a.num_frames != b.num_frames) {
    throw RecordingError(fmt::format("cannot compare {} ({} frames) with {} ({} frames): the frame "
                                     "counts differ",
                                     a.folder.string(), a.num_frames, b.folder.string(),
                                     b.num_frames));
  }
  if (a.frame_width != b.frame_width || a.frame_height != b.frame_height) {
    throw RecordingError(fmt::format("cannot compare {} ({}x{} px) with {} ({}x{} px): the frame "
                                     "sizes differ",
                                     a.folder.string(), a.frame_width, a.frame_height,
                                     b.folder.string(), b.frame_width, b.frame_height));
  }
  const std::vector<BitMask> masks_a = SegmentRecording(a, options, cache_dir);
  const std::vector<BitMask> masks_b = SegmentRecording(b, options, cache_dir);
  RecordingDifference out;
  out.frames.reserve(masks_a.size());
  const bool same_roi = !masks_a.empty() && masks_a.front().SameShape(masks_b.front());
  for (size_t f = 0; f < masks_a.size(); ++f) {
    const FrameScore s =
        same_roi ? CompareMasks(masks_a[f], masks_b[f])
                 : CompareMasks(OnWholeFrame(masks_a[f], a.frame_width, a.frame_height),
                                OnWholeFrame(masks_b[f], b.frame_width, b.frame_height));
    // Two bit masks: every area is a whole number of pixels.
    const auto px = [](double area) { return static_cast<int64_t>(area); };
    out.frames.push_back(
        {px(s.xor_px), px(s.missed_px), px(s.extra_px), px(s.object_px), px(s.mesh_px), s.iou});
  }
  return out;
}

}  // namespace calib
