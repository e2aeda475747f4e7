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
                         int num_frames) {
  csv_writer::File out = csv_writer::Open(path);
  if (!out) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  WriteRecord(out.get(), {"frame", "xor", "missed", "extra", "iou", "status", "reason"});
  const int scored = static_cast<int>(result.frames.size());
  for (int frame = 0; frame < num_frames; ++frame) {
    if (frame < scored) {
      const FrameScore& s = result.frames[frame];
      WriteRecord(out.get(), {std::to_string(frame), fmt::format("{}", s.xor_px),
                              fmt::format("{}", s.missed_px), fmt::format("{}", s.extra_px),
                              fmt::format("{:.6f}", s.iou), "ok", ""});
    } else if (frame == result.failure_frame) {
      WriteRecord(out.get(), {std::to_string(frame), "", "", "", "", "failed", result.failure_reason});
    } else {
      WriteRecord(out.get(), {std::to_string(frame), "", "", "", "", "not_simulated", ""});
    }
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
