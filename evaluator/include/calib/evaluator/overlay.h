#pragma once
// Diagnostic images of one frame's comparison, after Fig. 5 of Arriola-Rios
// & Wyatt: a 2 x 2 panel of frame-sized tiles
//
//   +----------------------------+----------------------+
//   | video frame, mesh edges    | object mask          |
//   | and obstacle discs         | (segmentation)       |
//   +----------------------------+----------------------+
//   | mesh mask (rasteriser)     | difference: missed,  |
//   |                            | extra, agreement     |
//   +----------------------------+----------------------+
//
// and writers for PNG stills and an mp4 of such panels.

#include "calib/core/mesh.h"
#include "calib/evaluator/bit_mask.h"
#include "calib/evaluator/media.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace calib {

/// Colours are BGR.
struct OverlayOptions {
  /// Shown in every panel's label when >= 0.
  int frame_index = -1;
  /// The frame's XOR area (FrameScore::xor_px, px^2), shown when >= 0.
  double xor_px = -1.0;
  /// The frame's IoU, shown when >= 0.
  double iou = -1.0;

  cv::Scalar mesh_colour{0, 255, 255};      ///< mesh edges on the video frame
  cv::Scalar obstacle_colour{255, 0, 255};  ///< obstacle disc outlines
  cv::Scalar mask_colour{255, 255, 255};    ///< "on" pixels of the two mask panels
  cv::Scalar missed_colour{0, 0, 255};      ///< object, not mesh (difference panel)
  cv::Scalar extra_colour{255, 160, 0};     ///< mesh, not object (difference panel)
  cv::Scalar agreement_colour{128, 128, 128};  ///< both (difference panel); neither: black
  int line_thickness_px = 1;
  double font_scale = 0.45;

  bool IsValid(std::string* error) const;
};

/// The 2 x 2 panel, CV_8UC3 of size (2 * frame width, 2 * frame height).
/// `frame_bgr`: the video frame, CV_8UC3 (CV_8UC1 is taken as grey).
/// `positions`: the mesh's #N node positions, frame pixels (corner origin,
/// as everywhere in the model; drawn with sub-pixel precision).
/// `object`, `mesh_mask`: same-shaped masks, each drawn at its origin inside
/// its frame-sized tile (clipped); pixels outside the masks stay black.
/// Throws std::invalid_argument for an empty or non-8-bit frame, masks of
/// different shapes, a wrong number of positions or invalid options.
cv::Mat RenderOverlay(const cv::Mat& frame_bgr, const Mesh& mesh,
                      const std::vector<Vec2>& positions, const std::vector<Disc>& obstacles,
                      const BitMask& object, const BitMask& mesh_mask,
                      const OverlayOptions& options);

/// Writes `image` as PNG. Throws std::runtime_error naming `path` when it
/// cannot be written (missing folder, no permission, empty image).
void WriteOverlayPng(const std::filesystem::path& path, const cv::Mat& image);

/// An mp4 of overlay panels. The codec is H.264 ('avc1') where the OpenCV
/// build can encode it, else MPEG-4 part 2 ('mp4v').
class OverlayVideoWriter {
 public:
  /// Opens `path` for frames of `frame_size` at `fps` frames per second.
  /// Returns true (a failure throws std::runtime_error naming the path and
  /// the codecs tried; invalid fps or size throw std::invalid_argument).
  bool Open(const std::filesystem::path& path, double fps, cv::Size frame_size);
  /// Appends one CV_8UC3 frame of the size given to Open. Throws
  /// std::logic_error when not open, std::invalid_argument for a frame of
  /// another size or type (OpenCV would silently drop it).
  void Write(const cv::Mat& image);
  /// Finishes the file; also done by the destructor and by a new Open.
  void Close();

  bool is_open() const { return writer_.IsOpen(); }
  /// The codec in use ("avc1" or "mp4v"); empty when not open.
  const std::string& codec() const { return codec_; }
  int frames_written() const { return frames_written_; }

 private:
  VideoWriter writer_;
  std::filesystem::path path_;
  cv::Size frame_size_;
  std::string codec_;
  int frames_written_ = 0;
};

}  // namespace calib
