#include "calib/results/frame_report.h"

#include <csv.h>
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {
namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

// Writes one CSV record. Fields that hold a separator, quote or line break
// are quoted (and their quotes doubled) by libcsv; the rest go out as they are.
void WriteRecord(std::FILE* out, const std::vector<std::string>& fields) {
  for (size_t i = 0; i < fields.size(); ++i) {
    if (i > 0) std::fputc(',', out);
    if (fields[i].find_first_of(",\"\r\n") != std::string::npos) {
      csv_fwrite(out, fields[i].data(), fields[i].size());
    } else {
      std::fputs(fields[i].c_str(), out);
    }
  }
  std::fputc('\n', out);
}

}  // namespace

void WriteFrameReportCsv(const std::filesystem::path& path, const EvaluationResult& result,
                         int num_frames) {
  std::unique_ptr<std::FILE, FileCloser> out(std::fopen(path.c_str(), "w"));
  if (!out) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  WriteRecord(out.get(), {"frame", "xor", "missed", "extra", "iou", "status", "reason"});
  const int scored = static_cast<int>(result.frames.size());
  for (int frame = 0; frame < num_frames; ++frame) {
    if (frame < scored) {
      const FrameScore& s = result.frames[frame];
      WriteRecord(out.get(), {std::to_string(frame), std::to_string(s.xor_px),
                              std::to_string(s.missed_px), std::to_string(s.extra_px),
                              fmt::format("{:.6f}", s.iou), "ok", ""});
    } else if (frame == result.failure_frame) {
      WriteRecord(out.get(), {std::to_string(frame), "", "", "", "", "failed", result.failure_reason});
    } else {
      WriteRecord(out.get(), {std::to_string(frame), "", "", "", "", "not_simulated", ""});
    }
  }
  if (std::ferror(out.get()) != 0) {
    throw std::runtime_error(fmt::format("{}: write failed", path.string()));
  }
}

}  // namespace calib
