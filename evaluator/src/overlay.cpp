#include "calib/evaluator/overlay.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace calib {
namespace {

// Sub-pixel drawing: OpenCV puts pixel centres at integer coordinates, the
// model at half-integers, and takes fixed-point coordinates with kShift
// fractional bits.
constexpr int kShift = 4;
constexpr double kFixedOne = 1 << kShift;

cv::Point ToFixed(const Vec2& p) {
  // Clamped so that a blown-up state still draws (off-tile) instead of
  // overflowing int.
  const auto fixed = [](double v) {
    return static_cast<int>(std::lround(std::clamp((v - 0.5) * kFixedOne, -1e8, 1e8)));
  };
  return {fixed(p.x()), fixed(p.y())};
}

bool Finite(const Vec2& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

cv::Vec3b ToVec3b(const cv::Scalar& s) {
  return cv::Vec3b(cv::saturate_cast<uint8_t>(s[0]), cv::saturate_cast<uint8_t>(s[1]),
                   cv::saturate_cast<uint8_t>(s[2]));
}

// Paints each tile pixel covered by the masks with colour_of(object_on,
// mesh_on); pixels outside the masks keep their colour.
template <class ColourOf>
void PaintMasks(const BitMask& object, const BitMask& mesh, cv::Mat& tile, ColourOf colour_of) {
  const int x0 = std::max(0, -object.origin_x());
  const int x1 = std::min(object.width(), tile.cols - object.origin_x());
  const int y0 = std::max(0, -object.origin_y());
  const int y1 = std::min(object.height(), tile.rows - object.origin_y());
  for (int y = y0; y < y1; ++y) {
    auto* out = tile.ptr<cv::Vec3b>(object.origin_y() + y);
    for (int x = x0; x < x1; ++x) {
      out[object.origin_x() + x] = colour_of(object.Get(x, y), mesh.Get(x, y));
    }
  }
}

// One line of text: coloured words with a dark outline, legible on any
// background. Returns the x after the text.
struct Word {
  std::string text;
  cv::Scalar colour;
};
int PutWords(cv::Mat& tile, const std::vector<Word>& words, cv::Point at, double font_scale) {
  for (const Word& w : words) {
    cv::putText(tile, w.text, at, cv::FONT_HERSHEY_SIMPLEX, font_scale, cv::Scalar(0, 0, 0), 3,
                cv::LINE_AA);
    cv::putText(tile, w.text, at, cv::FONT_HERSHEY_SIMPLEX, font_scale, w.colour, 1,
                cv::LINE_AA);
    int baseline = 0;
    at.x += cv::getTextSize(w.text + " ", cv::FONT_HERSHEY_SIMPLEX, font_scale, 1, &baseline)
                .width;
  }
  return at.x;
}

// Writes `lines` (empty ones skipped) from the tile's top left.
void PutLabel(cv::Mat& tile, const std::vector<std::vector<Word>>& lines, double font_scale) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize("Xg", cv::FONT_HERSHEY_SIMPLEX, font_scale, 1, &baseline);
  int y = 4;
  for (const std::vector<Word>& line : lines) {
    if (line.empty()) continue;
    y += size.height;
    PutWords(tile, line, cv::Point(4, y), font_scale);
    y += baseline + 2;
  }
}

}  // namespace

bool OverlayOptions::IsValid(std::string* error) const {
  const auto fail = [error](std::string message) {
    if (error != nullptr) *error = std::move(message);
    return false;
  };
  if (line_thickness_px < 1) {
    return fail(fmt::format(
        "OverlayOptions::line_thickness_px = {}. Violated: line_thickness_px >= 1.",
        line_thickness_px));
  }
  if (!(std::isfinite(font_scale) && font_scale > 0.0)) {
    return fail(
        fmt::format("OverlayOptions::font_scale = {}. Violated: finite and > 0.", font_scale));
  }
  return true;
}

cv::Mat RenderOverlay(const cv::Mat& frame_bgr, const Mesh& mesh,
                      const std::vector<Vec2>& positions, const std::vector<Disc>& obstacles,
                      const BitMask& object, const BitMask& mesh_mask,
                      const OverlayOptions& options) {
  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  if (frame_bgr.empty() || frame_bgr.depth() != CV_8U ||
      (frame_bgr.channels() != 3 && frame_bgr.channels() != 1)) {
    throw std::invalid_argument(fmt::format(
        "RenderOverlay: expected a non-empty 8-bit BGR or grey frame, got {}x{} type {}",
        frame_bgr.cols, frame_bgr.rows, frame_bgr.type()));
  }
  if (!object.SameShape(mesh_mask)) {
    throw std::invalid_argument(fmt::format(
        "RenderOverlay: object mask {}x{} at ({}, {}) and mesh mask {}x{} at ({}, {}) differ",
        object.width(), object.height(), object.origin_x(), object.origin_y(), mesh_mask.width(),
        mesh_mask.height(), mesh_mask.origin_x(), mesh_mask.origin_y()));
  }
  if (static_cast<int>(positions.size()) != mesh.NumNodes()) {
    throw std::invalid_argument(fmt::format(
        "RenderOverlay: {} positions for a mesh of {} nodes", positions.size(), mesh.NumNodes()));
  }

  const int w = frame_bgr.cols;
  const int h = frame_bgr.rows;
  cv::Mat panel(2 * h, 2 * w, CV_8UC3, cv::Scalar(0, 0, 0));
  cv::Mat video = panel(cv::Rect(0, 0, w, h));
  cv::Mat object_tile = panel(cv::Rect(w, 0, w, h));
  cv::Mat mesh_tile = panel(cv::Rect(0, h, w, h));
  cv::Mat diff_tile = panel(cv::Rect(w, h, w, h));

  if (frame_bgr.channels() == 3) {
    frame_bgr.copyTo(video);
  } else {
    cv::cvtColor(frame_bgr, video, cv::COLOR_GRAY2BGR);
  }
  for (const auto& [i, j] : mesh.edges) {
    if (!Finite(positions[i]) || !Finite(positions[j])) continue;
    cv::line(video, ToFixed(positions[i]), ToFixed(positions[j]), options.mesh_colour,
             options.line_thickness_px, cv::LINE_AA, kShift);
  }
  for (const Disc& d : obstacles) {
    if (!Finite(d.centre) || !std::isfinite(d.radius_px) || d.radius_px <= 0.0) continue;
    const int radius = static_cast<int>(std::lround(std::min(d.radius_px * kFixedOne, 1e8)));
    cv::circle(video, ToFixed(d.centre), radius, options.obstacle_colour,
               options.line_thickness_px, cv::LINE_AA, kShift);
  }

  const cv::Vec3b black(0, 0, 0);
  const cv::Vec3b on = ToVec3b(options.mask_colour);
  const cv::Vec3b missed = ToVec3b(options.missed_colour);
  const cv::Vec3b extra = ToVec3b(options.extra_colour);
  const cv::Vec3b agreement = ToVec3b(options.agreement_colour);
  PaintMasks(object, mesh_mask, object_tile, [&](bool o, bool) { return o ? on : black; });
  PaintMasks(object, mesh_mask, mesh_tile, [&](bool, bool m) { return m ? on : black; });
  PaintMasks(object, mesh_mask, diff_tile, [&](bool o, bool m) {
    return o ? (m ? agreement : missed) : (m ? extra : black);
  });

  std::string stats;
  const auto append = [&stats](const std::string& item) {
    stats += stats.empty() ? item : "  " + item;
  };
  if (options.frame_index >= 0) append(fmt::format("frame {}", options.frame_index));
  if (options.xor_px >= 0) append(fmt::format("XOR {:.1f} px", options.xor_px));
  if (options.iou >= 0.0) append(fmt::format("IoU {:.4f}", options.iou));
  const cv::Scalar white(255, 255, 255);
  std::vector<Word> stats_line;
  if (!stats.empty()) stats_line.push_back({stats, white});
  PutLabel(video, {{{"video + mesh", white}}, stats_line}, options.font_scale);
  PutLabel(object_tile, {{{"object", white}}, stats_line}, options.font_scale);
  PutLabel(mesh_tile, {{{"mesh", white}}, stats_line}, options.font_scale);
  PutLabel(diff_tile,
           {{{"difference:", white},
             {"missed", options.missed_colour},
             {"extra", options.extra_colour},
             {"both", options.agreement_colour}},
            stats_line},
           options.font_scale);
  return panel;
}

void WriteOverlayPng(const std::filesystem::path& path, const cv::Mat& image) {
  if (image.empty()) {
    throw std::runtime_error(fmt::format("cannot write '{}': the image is empty", path.string()));
  }
  bool written = false;
  std::string reason = "cv::imwrite failed (missing folder or no permission?)";
  try {
    written = WriteImage(path, image);
  } catch (const cv::Exception& e) {
    reason = e.what();
  }
  if (!written) throw std::runtime_error(fmt::format("cannot write '{}': {}", path.string(), reason));
}

bool OverlayVideoWriter::Open(const std::filesystem::path& path, double fps, cv::Size frame_size) {
  Close();
  if (!(std::isfinite(fps) && fps > 0.0)) {
    throw std::invalid_argument(
        fmt::format("OverlayVideoWriter: fps = {} for '{}'. Violated: fps > 0.", fps, path.string()));
  }
  if (frame_size.width <= 0 || frame_size.height <= 0) {
    throw std::invalid_argument(fmt::format("OverlayVideoWriter: frame size {}x{} for '{}'",
                                            frame_size.width, frame_size.height, path.string()));
  }
  for (const char* codec : {"avc1", "mp4v"}) {
    try {
      if (writer_.Open(path, FourCC(codec), fps, frame_size)) {
        path_ = path;
        frame_size_ = frame_size;
        codec_ = codec;
        frames_written_ = 0;
        return true;
      }
    } catch (const cv::Exception&) {
      // An encoder missing from this OpenCV build: try the next codec.
    }
    writer_.Release();
  }
  throw std::runtime_error(
      fmt::format("cannot open video '{}' for writing (tried codecs avc1 and mp4v)", path.string()));
}

void OverlayVideoWriter::Write(const cv::Mat& image) {
  if (!writer_.IsOpen()) throw std::logic_error("OverlayVideoWriter::Write: no video is open");
  if (image.size() != frame_size_ || image.type() != CV_8UC3) {
    throw std::invalid_argument(fmt::format(
        "OverlayVideoWriter: frame {} for '{}' is {}x{} type {}, expected {}x{} CV_8UC3",
        frames_written_, path_.string(), image.cols, image.rows, image.type(), frame_size_.width,
        frame_size_.height));
  }
  writer_.Write(image);
  ++frames_written_;
}

void OverlayVideoWriter::Close() {
  writer_.Release();
  codec_.clear();
}

}  // namespace calib
