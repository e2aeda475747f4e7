#include "segment_cli.h"

#include "calib/evaluator/overlay.h"
#include "calib/evaluator/segmentation_preview.h"

#include <fmt/format.h>

#include <filesystem>

namespace calib::cli {

struct SegmentCli {
  CLI::App* segment = nullptr;
  std::filesystem::path recording;
  std::vector<int> frames;
  std::vector<int> hsv;
  std::filesystem::path out = "out/segment";
  bool preview = false;
  SegmentationOptions options;
};

std::shared_ptr<SegmentCli> AddSegmentSubcommand(CLI::App& app) {
  auto cli = std::make_shared<SegmentCli>();
  cli->segment = app.add_subcommand(
      "segment", "the colour segmentation of chosen frames: the object's pixels per frame, and "
                 "with --preview the mask over the video (to set a camera's colour bounds)");
  auto* cmd = cli->segment;
  cmd->add_option("recording", cli->recording, "recording folder")->required();
  cmd->add_option("--frames", cli->frames, "frames to segment (default: the first, middle and last)")
      ->delimiter(',');
  cmd->add_option("--hsv", cli->hsv,
                  "bounds to try instead of recording.json's object_hsv: H0,S0,V0,H1,S1,V1")
      ->delimiter(',')
      ->expected(6);
  cmd->add_flag("--preview", cli->preview, "write each frame with its mask as a PNG into --out");
  cmd->add_option("--out", cli->out, "folder of the previews")->capture_default_str();
  return cli;
}

std::optional<int> RunChosenSegmentSubcommand(SegmentCli& cli) {
  if (!*cli.segment) return std::nullopt;
  const Recording rec = LoadRecording(cli.recording);
  HsvRange hsv = rec.object_hsv;
  if (!cli.hsv.empty()) {
    hsv.lower = {cli.hsv[0], cli.hsv[1], cli.hsv[2]};
    hsv.upper = {cli.hsv[3], cli.hsv[4], cli.hsv[5]};
  }
  std::vector<int> frames = cli.frames;
  if (frames.empty()) frames = {0, rec.num_frames / 2, rec.num_frames - 1};
  const std::vector<SegmentationPreview> previews =
      PreviewSegmentation(rec, frames, hsv, cli.options);
  if (cli.preview) std::filesystem::create_directories(cli.out);
  for (const SegmentationPreview& p : previews) {
    fmt::print("frame {}: {} object pixels\n", p.frame, p.object_px);
    if (cli.preview) {
      const std::filesystem::path png = cli.out / fmt::format("segment_{:06d}.png", p.frame);
      WriteOverlayPng(png, p.image);
      fmt::print("  preview: {}\n", png.string());
    }
  }
  return 0;
}

}  // namespace calib::cli
