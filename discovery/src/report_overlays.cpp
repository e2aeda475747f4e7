// Overlay frames for the loop report (report_overlays.h).

#include "calib/discovery/report_overlays.h"

#include "calib/evaluator/overlay.h"
#include "calib/evaluator/recording.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <stdexcept>

namespace calib {

OverlayCapture::OverlayCapture(const PreparedRecording& prepared, std::vector<int> frames,
                               std::filesystem::path report_dir, std::string stage, double scale)
    : prepared_(prepared),
      frames_(std::move(frames)),
      report_dir_(std::move(report_dir)),
      stage_(std::move(stage)),
      scale_(scale) {
  if (!(scale > 0.0 && scale <= 1.0)) {
    throw std::invalid_argument(
        fmt::format("OverlayCapture: scale = {}. Violated: 0 < scale <= 1.", scale));
  }
  std::sort(frames_.begin(), frames_.end());
  recording_ = RecordingDisplayName(prepared.recording.folder);
  if (!frames_.empty() && !video_.Open(prepared.recording.video_path)) {
    throw RecordingError(
        fmt::format("{}: cannot open video", prepared.recording.video_path.string()));
  }
}

void OverlayCapture::operator()(int frame, const Simulator& simulator, const BitMask& mesh_mask,
                                const FrameScore& score) {
  if (frames_.empty() || frame > frames_.back()) return;
  if (frame != next_frame_) {
    throw std::logic_error(fmt::format("OverlayCapture: frame {} after frame {}", frame,
                                       next_frame_ - 1));
  }
  ++next_frame_;
  const bool wanted = std::binary_search(frames_.begin(), frames_.end(), frame);
  if (!wanted) {
    if (!video_.Grab()) {
      throw RecordingError(fmt::format("{}: cannot decode frame {}",
                                       prepared_.recording.video_path.string(), frame));
    }
    return;
  }
  cv::Mat image;
  if (!video_.Read(image)) {
    throw RecordingError(fmt::format("{}: cannot decode frame {}",
                                     prepared_.recording.video_path.string(), frame));
  }
  const Disc* d = prepared_.scene.ObstaclesAt(frame);
  const std::vector<Disc> discs(d, d + prepared_.scene.num_obstacles);
  OverlayOptions options;
  options.frame_index = frame;
  options.xor_px = score.xor_px;
  options.iou = score.iou;
  cv::Mat panel = RenderOverlay(image, prepared_.mesh, simulator.positions(), discs,
                                prepared_.object_masks[frame], mesh_mask, options);
  if (scale_ < 1.0) {
    cv::Mat small;
    cv::resize(panel, small, cv::Size(), scale_, scale_, cv::INTER_AREA);
    panel = small;
  }
  const std::string file = fmt::format("overlays/{}_{}_{:06d}.png", recording_, stage_, frame);
  std::filesystem::create_directories(report_dir_ / "overlays");
  WriteOverlayPng(report_dir_ / file, panel);
  ReportOverlay o;
  o.recording = recording_;
  o.stage = stage_;
  o.frame = frame;
  o.xor_px = score.xor_px;
  o.iou = score.iou;
  o.png_file = file;
  o.caption = "top left: video, mesh and obstacles; top right: object mask; bottom left: mesh "
              "mask; bottom right: missed (red), extra (blue), both (grey)";
  overlays_.push_back(std::move(o));
}

}  // namespace calib
