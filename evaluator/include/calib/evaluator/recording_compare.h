#pragma once
// The difference between two recordings of one scene: per frame, the pixels
// where their segmented objects disagree, counted like the score. Two takes
// of the same push give the score's floor (what no model can explain); a
// synthetic recording against its twin with the effects switched off
// (`calib synth --without-effects`) gives an effect's footprint in pixels,
// to set beside a calibrated model's residual.

#include "calib/evaluator/recording.h"
#include "calib/evaluator/segmentation.h"

#include <cstdint>
#include <filesystem>
#include <vector>

namespace calib {

/// One frame: pixels of the object in exactly one of the recordings.
struct FrameDifference {
  int64_t xor_px = 0;     ///< only_a_px + only_b_px
  int64_t only_a_px = 0;  ///< object in a, not in b
  int64_t only_b_px = 0;  ///< object in b, not in a
  int64_t a_px = 0;
  int64_t b_px = 0;
  double iou = 0.0;       ///< 1 when both are empty
};

struct RecordingDifference {
  std::vector<FrameDifference> frames;
  int64_t XorSum() const;
  double MeanIou() const;
};

/// Segments both recordings (each with its own colour range and roi; the
/// segmentation cache in `cache_dir` when non-empty) and compares their
/// masks frame by frame over the whole frame. Throws RecordingError naming
/// both folders when the frame counts or frame sizes differ.
RecordingDifference CompareRecordings(const Recording& a, const Recording& b,
                                      const SegmentationOptions& options,
                                      const std::filesystem::path& cache_dir);

}  // namespace calib
