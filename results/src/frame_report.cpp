#include "calib/results/frame_report.h"

#include "calib/results/csv_writer.h"

#include <fmt/format.h>

#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace calib {

using csv_writer::WriteRecord;

void WriteFrameReportCsv(const std::filesystem::path& path, const EvaluationResult& result,
                         int num_frames, const FrameCentroids* centroids) {
  csv_writer::File out = csv_writer::Open(path);
  if (!out) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  std::vector<std::string> header = {"frame", "xor", "missed", "extra", "iou", "status", "reason"};
  if (centroids != nullptr) {
    header.insert(header.end(), {"mesh_cx", "mesh_cy", "object_cx", "object_cy"});
  }
  WriteRecord(out.get(), header);
  // x and y of the frame's entry of `points`, or two empty cells.
  auto add_point = [](std::vector<std::string>& row, const std::vector<Vec2>& points, int frame) {
    const bool have =
        frame >= 0 && frame < static_cast<int>(points.size()) && points[frame].allFinite();
    row.push_back(have ? fmt::format("{}", points[frame].x()) : "");
    row.push_back(have ? fmt::format("{}", points[frame].y()) : "");
  };
  const int scored = static_cast<int>(result.frames.size());
  for (int frame = 0; frame < num_frames; ++frame) {
    std::vector<std::string> row;
    if (frame < scored) {
      const FrameScore& s = result.frames[frame];
      row = {std::to_string(frame), fmt::format("{}", s.xor_px), fmt::format("{}", s.missed_px),
             fmt::format("{}", s.extra_px), fmt::format("{:.6f}", s.iou), "ok", ""};
    } else if (frame == result.failure_frame) {
      row = {std::to_string(frame), "", "", "", "", "failed", result.failure_reason};
    } else {
      row = {std::to_string(frame), "", "", "", "", "not_simulated", ""};
    }
    if (centroids != nullptr) {
      add_point(row, centroids->mesh_px, frame < scored ? frame : -1);
      add_point(row, centroids->object_px, frame);
    }
    WriteRecord(out.get(), row);
  }
  if (!csv_writer::Close(std::move(out))) {
    throw std::runtime_error(fmt::format("{}: write failed", path.string()));
  }
}

void WriteRecordingDifferenceCsv(const std::filesystem::path& path,
                                 const RecordingDifference& difference) {
  csv_writer::File out = csv_writer::Open(path);
  if (!out) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  WriteRecord(out.get(), {"frame", "xor", "only_a", "only_b", "a", "b", "iou"});
  for (size_t frame = 0; frame < difference.frames.size(); ++frame) {
    const FrameDifference& d = difference.frames[frame];
    WriteRecord(out.get(), {std::to_string(frame), std::to_string(d.xor_px),
                            std::to_string(d.only_a_px), std::to_string(d.only_b_px),
                            std::to_string(d.a_px), std::to_string(d.b_px),
                            fmt::format("{:.6f}", d.iou)});
  }
  if (!csv_writer::Close(std::move(out))) {
    throw std::runtime_error(fmt::format("{}: write failed", path.string()));
  }
}

}  // namespace calib
