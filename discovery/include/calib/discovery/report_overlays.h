#pragma once
// Overlay frames for the loop report: an Evaluator on_frame callback that
// reads the recording's video alongside the simulation and writes the
// overlay panel (evaluator/overlay.h) of chosen frames as PNG files.
//
//   OverlayCapture capture(prepared, analysis.worst_frames, out_dir, "base");
//   evaluator.Evaluate(values, [&](int f, const Simulator& s, const BitMask& m,
//                                  const FrameScore& sc) {
//     analyser(f, s, m, sc);  // the residual analysis in the same pass
//     capture(f, s, m, sc);
//   });
//   report.overlays += capture.overlays();

#include "calib/core/simulator.h"
#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/media.h"
#include "calib/discovery/loop_report.h"

#include <filesystem>
#include <string>
#include <vector>

namespace calib {

class OverlayCapture {
 public:
  /// Frames `frames` of `prepared` (which must outlive the capture) are
  /// written to report_dir / "overlays" / "<recording>_<stage>_<frame>.png",
  /// scaled by `scale` (0 < scale <= 1). Throws RecordingError when the
  /// video does not open, std::invalid_argument for a bad scale.
  OverlayCapture(const PreparedRecording& prepared, std::vector<int> frames,
                 std::filesystem::path report_dir, std::string stage, double scale = 0.5);

  /// The on_frame callback: frames must come in order from 0.
  void operator()(int frame, const Simulator& simulator, const BitMask& mesh_mask,
                  const FrameScore& score);

  /// One per captured frame, png_file relative to report_dir.
  const std::vector<ReportOverlay>& overlays() const { return overlays_; }

 private:
  const PreparedRecording& prepared_;
  std::vector<int> frames_;
  std::filesystem::path report_dir_;
  std::string stage_;
  std::string recording_;
  double scale_;
  VideoReader video_;
  int next_frame_ = 0;
  std::vector<ReportOverlay> overlays_;
};

}  // namespace calib
