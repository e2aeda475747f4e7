#pragma once
// The per-frame report of one evaluation as CSV: one row per video frame.
//
// Columns: frame, xor, missed, extra, iou, status, reason; xor, missed and
// extra are pixel areas (px^2, FrameScore), written exactly (the shortest
// text that reads back to the same double). `status` is "ok"
// for a scored frame, "failed" for the frame at which the simulation failed
// (with the reason) and "not_simulated" for the frames after it. With
// centroids given, four more columns: mesh_cx, mesh_cy (the simulated mesh's
// area centroid) and object_cx, object_cy (the segmented object's), pixels,
// empty where a frame has none; a swing's phase and period read off them.
//
// The per-frame difference of two recordings (`calib compare`) likewise:
// frame, xor, only_a, only_b, a, b, iou.

#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/recording_compare.h"

#include <filesystem>
#include <vector>

namespace calib {

/// Per frame, where the mesh and the object are (frame pixels).
struct FrameCentroids {
  std::vector<Vec2> mesh_px;    ///< one per scored frame
  std::vector<Vec2> object_px;  ///< one per frame of the recording (NaN: no object)
};

/// Writes the report of `result` over `num_frames` frames, with the
/// centroid columns when `centroids` is not null. Throws std::runtime_error
/// naming the path when it cannot be written.
void WriteFrameReportCsv(const std::filesystem::path& path, const EvaluationResult& result,
                         int num_frames, const FrameCentroids* centroids = nullptr);

/// Writes the per-frame difference of two recordings. Throws
/// std::runtime_error naming the path when it cannot be written.
void WriteRecordingDifferenceCsv(const std::filesystem::path& path,
                                 const RecordingDifference& difference);

}  // namespace calib
