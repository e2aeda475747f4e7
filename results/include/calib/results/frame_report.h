#pragma once
// The per-frame report of one evaluation as CSV: one row per video frame.
//
// Columns: frame, xor, missed, extra, iou, status, reason; xor, missed and
// extra are pixel areas (px^2, FrameScore), written exactly (the shortest
// text that reads back to the same double). `status` is "ok"
// for a scored frame, "failed" for the frame at which the simulation failed
// (with the reason) and "not_simulated" for the frames after it.
//
// The per-frame difference of two recordings (`calib compare`) likewise:
// frame, xor, only_a, only_b, a, b, iou.

#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/recording_compare.h"

#include <filesystem>

namespace calib {

/// Writes the report of `result` over `num_frames` frames. Throws
/// std::runtime_error naming the path when it cannot be written.
void WriteFrameReportCsv(const std::filesystem::path& path, const EvaluationResult& result,
                         int num_frames);

/// Writes the per-frame difference of two recordings. Throws
/// std::runtime_error naming the path when it cannot be written.
void WriteRecordingDifferenceCsv(const std::filesystem::path& path,
                                 const RecordingDifference& difference);

}  // namespace calib
