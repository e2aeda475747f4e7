#pragma once
// Rendering synthetic camera frames of the deformed object, as a camera above
// the table would see them: a pore-textured object whose texture moves with
// the material, a lighting gradient, an opaque pencil, a semi-transparent
// finger over everything, gaussian pixel noise and a slight blur.
//
// Coordinates are image pixels (x right, y down, origin at the top-left
// pixel's corner); pixel (x, y) shows the scene at its centre (x + .5, y + .5),
// the convention of calib::BitMask and calib::Rasterizer.

#include "calib/core/mesh.h"
#include "calib/evaluator/bit_mask.h"
#include "calib/evaluator/rasterizer.h"
#include "calib/evaluator/recording.h"
#include "calib/synth/scenario.h"

#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace calib::synth {

/// One obstacle disc as drawn: opacity 1 hides what lies below; less blends.
struct DrawnDisc {
  Disc disc;
  std::array<int, 3> rgb{0, 0, 0};
  double opacity = 1.0;  ///< (0, 1]
};

/// The inclusive HSV range (OpenCV convention) that segments the object of
/// `camera`: hue within 8 of the object colour's, saturation at least 60 % of
/// it, value at least 75 % of the darkest the texture and lighting make it.
/// Written into recording.json.
HsvRange ObjectHsvRange(const CameraSpec& camera);

/// False, with a message naming the colour key, when the background, finger
/// (blended over the background at finger_opacity) or pencil colour falls
/// inside ObjectHsvRange, or the object colour itself falls outside it (for
/// example a grey object, whose hue is undefined); `error` may be null.
bool ColoursSeparate(const CameraSpec& camera, std::string* error);

class FrameRenderer {
 public:
  /// `rest_mesh` is the fine mesh in its rest shape (px; copied); the texture
  /// is laid on it once, from `seed`. `camera` must be valid
  /// (Scenario::IsValid).
  FrameRenderer(const CameraSpec& camera, const Mesh& rest_mesh, uint64_t seed);

  /// Frame `frame` (CV_8UC3, BGR, camera.width_px x camera.height_px) with the
  /// mesh nodes at `positions` (#N, px). `discs` are drawn in order after the
  /// object. Noise is drawn from (seed, frame): the same arguments give the
  /// same bits.
  cv::Mat Render(int frame, const std::vector<Vec2>& positions,
                 const std::vector<DrawnDisc>& discs) const;

  /// The object's true mask with nodes at `positions`: over the whole frame,
  /// pixels whose centre lies in a triangle (Rasterizer::RasterizeTriangles).
  BitMask TruthMask(const std::vector<Vec2>& positions) const;

  int width() const { return camera_.width_px; }
  int height() const { return camera_.height_px; }

 private:
  CameraSpec camera_;
  Mesh mesh_;
  uint64_t seed_;
  cv::Mat albedo_;      // CV_32F texture over the rest shape's bounding box
  Vec2 albedo_origin_;  // rest-space px of albedo_ pixel (0, 0)'s corner
  cv::Mat lighting_;    // CV_32F brightness factor per pixel
};

}  // namespace calib::synth
