#include "calib/synth/renderer.h"

#include "random.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace calib::synth {
namespace {

// HSV (OpenCV convention) of an RGB colour.
cv::Vec3b RgbToHsv(double r, double g, double b) {
  cv::Mat bgr(1, 1, CV_8UC3,
              cv::Scalar(std::clamp(b, 0.0, 255.0), std::clamp(g, 0.0, 255.0), std::clamp(r, 0.0, 255.0)));
  cv::Mat hsv;
  cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV);
  return hsv.at<cv::Vec3b>(0, 0);
}

bool InRange(const cv::Vec3b& hsv, const HsvRange& range) {
  for (int c = 0; c < 3; ++c) {
    if (hsv[c] < range.lower[c] || hsv[c] > range.upper[c]) return false;
  }
  return true;
}

// The darkest albedo the pore texture gives (base shading included).
double DarkestAlbedo(const CameraSpec& camera) { return 1.0 - camera.texture_contrast; }

// Bilinear sample of a CV_32F image at continuous pixel coordinates (x, y)
// (pixel centres at +0.5), clamped at the border.
float Sample(const cv::Mat& image, double x, double y) {
  const double fx = std::clamp(x - 0.5, 0.0, image.cols - 1.001);
  const double fy = std::clamp(y - 0.5, 0.0, image.rows - 1.001);
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  const float ax = static_cast<float>(fx - x0), ay = static_cast<float>(fy - y0);
  const float* r0 = image.ptr<float>(y0);
  const float* r1 = image.ptr<float>(y0 + 1);
  return (1 - ay) * ((1 - ax) * r0[x0] + ax * r0[x0 + 1]) + ay * ((1 - ax) * r1[x0] + ax * r1[x0 + 1]);
}

}  // namespace

HsvRange ObjectHsvRange(const CameraSpec& camera) {
  const auto& c = camera.object_rgb;
  const cv::Vec3b hsv = RgbToHsv(c[0], c[1], c[2]);
  const double darkest = DarkestAlbedo(camera) * (1.0 - camera.lighting_gradient);
  HsvRange range;
  range.lower = {std::max(0, hsv[0] - 8), static_cast<int>(std::lround(0.75 * hsv[1])),
                 static_cast<int>(std::lround(0.75 * darkest * hsv[2]))};
  range.upper = {std::min(179, hsv[0] + 8), 255, 255};
  return range;
}

bool ColoursSeparate(const CameraSpec& camera, std::string* error) {
  const HsvRange range = ObjectHsvRange(camera);
  auto fail = [&](const std::string& message) {
    if (error) *error = message;
    return false;
  };
  const auto& o = camera.object_rgb;
  const double darkest = DarkestAlbedo(camera) * (1.0 - camera.lighting_gradient);
  if (RgbToHsv(o[0], o[1], o[2])[1] < 40 || !InRange(RgbToHsv(o[0], o[1], o[2]), range) ||
      !InRange(RgbToHsv(darkest * o[0], darkest * o[1], darkest * o[2]), range)) {
    return fail(fmt::format(
        "camera.object_rgb = [{}, {}, {}]. Violated: the object colour is saturated enough to "
        "segment (saturation >= 40 of 255) in its darkest shade too",
        o[0], o[1], o[2]));
  }
  // True when no lighting of `rgb` falls in the object's range.
  const auto check = [&](const std::array<int, 3>& rgb) {
    for (double light : {1.0 - camera.lighting_gradient, 1.0, 1.0 + camera.lighting_gradient}) {
      if (InRange(RgbToHsv(light * rgb[0], light * rgb[1], light * rgb[2]), range)) return false;
    }
    return true;
  };
  const auto show = [](const std::array<int, 3>& c) { return fmt::format("[{}, {}, {}]", c[0], c[1], c[2]); };
  const std::string rule = fmt::format(
      "outside the object's HSV range [{}, {}, {}]..[{}, {}, {}]", range.lower[0], range.lower[1],
      range.lower[2], range.upper[0], range.upper[1], range.upper[2]);
  if (!check(camera.background_rgb)) {
    return fail(fmt::format("camera.background_rgb = {}. Violated: {}", show(camera.background_rgb), rule));
  }
  if (!check(camera.pencil_rgb)) {
    return fail(fmt::format("camera.pencil_rgb = {}. Violated: {}", show(camera.pencil_rgb), rule));
  }
  std::array<int, 3> blended;
  for (int i = 0; i < 3; ++i) {
    blended[i] = static_cast<int>(std::lround(camera.finger_opacity * camera.finger_rgb[i] +
                                              (1.0 - camera.finger_opacity) * camera.background_rgb[i]));
  }
  if (!check(camera.finger_rgb) || !check(blended)) {
    return fail(fmt::format("camera.finger_rgb = {}. Violated: {} (alone and over the background)",
                            show(camera.finger_rgb), rule));
  }
  return true;
}

FrameRenderer::FrameRenderer(const CameraSpec& camera, const Mesh& rest_mesh, uint64_t seed)
    : camera_(camera), mesh_(rest_mesh), seed_(seed) {
  // The pore texture over the rest shape's bounding box (+ a margin).
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const Vec2& p : mesh_.rest_positions) {
    x0 = std::min(x0, p.x());
    y0 = std::min(y0, p.y());
    x1 = std::max(x1, p.x());
    y1 = std::max(y1, p.y());
  }
  if (mesh_.rest_positions.empty()) x0 = y0 = x1 = y1 = 0.0;
  albedo_origin_ = Vec2(std::floor(x0) - 4.0, std::floor(y0) - 4.0);
  const int w = static_cast<int>(std::ceil(x1) - albedo_origin_.x()) + 5;
  const int h = static_cast<int>(std::ceil(y1) - albedo_origin_.y()) + 5;
  SplitMix64 rng(DeriveSeed(seed, 0x7e47u));

  // Slow shading variation: a coarse random grid, smoothly upsampled.
  const int cell = 24;
  cv::Mat coarse(h / cell + 3, w / cell + 3, CV_32F);
  for (int y = 0; y < coarse.rows; ++y) {
    for (int x = 0; x < coarse.cols; ++x) coarse.at<float>(y, x) = static_cast<float>(rng.Uniform());
  }
  cv::Mat slow;
  cv::resize(coarse, slow, cv::Size(coarse.cols * cell, coarse.rows * cell), 0, 0, cv::INTER_CUBIC);
  albedo_ = cv::Mat(h, w, CV_32F);
  const double contrast = camera_.texture_contrast;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      albedo_.at<float>(y, x) =
          static_cast<float>(1.0 - 0.15 * contrast * std::clamp(slow.at<float>(y, x), 0.0f, 1.0f));
    }
  }
  // Pores: dark soft discs, overlapping, over about a third of the surface.
  const double r_mean = camera_.pore_size_px;
  const int count = static_cast<int>(0.45 * w * h / (std::numbers::pi * r_mean * r_mean * 1.2));
  for (int i = 0; i < count; ++i) {
    const double cx = rng.Uniform() * w, cy = rng.Uniform() * h;
    const double r = r_mean * (0.5 + rng.Uniform());
    const double depth = contrast * (0.5 + 0.5 * rng.Uniform());
    const int bx0 = std::max(0, static_cast<int>(cx - r - 1)), bx1 = std::min(w - 1, static_cast<int>(cx + r + 1));
    const int by0 = std::max(0, static_cast<int>(cy - r - 1)), by1 = std::min(h - 1, static_cast<int>(cy + r + 1));
    for (int y = by0; y <= by1; ++y) {
      for (int x = bx0; x <= bx1; ++x) {
        const double d = std::hypot(x + 0.5 - cx, y + 0.5 - cy) / r;
        if (d >= 1.0) continue;
        const float v = static_cast<float>(1.0 - depth * std::sqrt(1.0 - d * d));
        float& a = albedo_.at<float>(y, x);
        a = std::min(a, v);
      }
    }
  }
  cv::max(albedo_, static_cast<float>(DarkestAlbedo(camera_)), albedo_);

  // Lighting: linear in the projection on the light direction, 1 +- gradient.
  lighting_ = cv::Mat(camera_.height_px, camera_.width_px, CV_32F);
  const double a = camera_.lighting_angle_deg * std::numbers::pi / 180.0;
  const double ux = std::cos(a), uy = std::sin(a);
  const double cx = 0.5 * camera_.width_px, cy = 0.5 * camera_.height_px;
  const double half = std::abs(ux) * cx + std::abs(uy) * cy;
  for (int y = 0; y < camera_.height_px; ++y) {
    float* row = lighting_.ptr<float>(y);
    for (int x = 0; x < camera_.width_px; ++x) {
      const double proj = ((x + 0.5 - cx) * ux + (y + 0.5 - cy) * uy) / half;
      row[x] = static_cast<float>(1.0 + camera_.lighting_gradient * proj);
    }
  }
}

cv::Mat FrameRenderer::Render(int frame, const std::vector<Vec2>& positions,
                              const std::vector<DrawnDisc>& discs) const {
  const int W = camera_.width_px, H = camera_.height_px;
  const auto bgr = [](const std::array<int, 3>& rgb) {
    return cv::Vec3f(static_cast<float>(rgb[2]), static_cast<float>(rgb[1]), static_cast<float>(rgb[0]));
  };
  cv::Mat image(H, W, CV_32FC3, cv::Scalar(bgr(camera_.background_rgb)));

  // The object: every pixel whose centre lies in a deformed triangle takes the
  // texture at the corresponding rest point (barycentric coordinates).
  const cv::Vec3f object = bgr(camera_.object_rgb);
  for (const auto& tri : mesh_.triangles) {
    const Vec2& p0 = positions[tri[0]];
    const Vec2& p1 = positions[tri[1]];
    const Vec2& p2 = positions[tri[2]];
    const Vec2 e1 = p1 - p0, e2 = p2 - p0;
    const double det = Cross(e1, e2);
    if (!(std::abs(det) > 1e-12)) continue;
    const Vec2& r0 = mesh_.rest_positions[tri[0]];
    const Vec2 f1 = mesh_.rest_positions[tri[1]] - r0, f2 = mesh_.rest_positions[tri[2]] - r0;
    const int xa = std::max(0, static_cast<int>(std::floor(std::min({p0.x(), p1.x(), p2.x()}) - 0.5)));
    const int xb = std::min(W - 1, static_cast<int>(std::ceil(std::max({p0.x(), p1.x(), p2.x()}))));
    const int ya = std::max(0, static_cast<int>(std::floor(std::min({p0.y(), p1.y(), p2.y()}) - 0.5)));
    const int yb = std::min(H - 1, static_cast<int>(std::ceil(std::max({p0.y(), p1.y(), p2.y()}))));
    for (int y = ya; y <= yb; ++y) {
      cv::Vec3f* row = image.ptr<cv::Vec3f>(y);
      for (int x = xa; x <= xb; ++x) {
        const Vec2 d(x + 0.5 - p0.x(), y + 0.5 - p0.y());
        const double l1 = Cross(d, e2) / det, l2 = Cross(e1, d) / det;
        if (l1 < -1e-9 || l2 < -1e-9 || l1 + l2 > 1.0 + 1e-9) continue;
        const Vec2 rest = r0 + l1 * f1 + l2 * f2 - albedo_origin_;
        row[x] = object * Sample(albedo_, rest.x(), rest.y());
      }
    }
  }

  // Obstacles in order, anti-aliased by the distance to the rim; lit a little
  // less towards their rim (round bodies).
  for (const DrawnDisc& drawn : discs) {
    const Disc& disc = drawn.disc;
    const cv::Vec3f colour = bgr(drawn.rgb);
    const double r = disc.radius_px;
    const int xa = std::max(0, static_cast<int>(disc.centre.x() - r - 2));
    const int xb = std::min(W - 1, static_cast<int>(disc.centre.x() + r + 2));
    const int ya = std::max(0, static_cast<int>(disc.centre.y() - r - 2));
    const int yb = std::min(H - 1, static_cast<int>(disc.centre.y() + r + 2));
    for (int y = ya; y <= yb; ++y) {
      cv::Vec3f* row = image.ptr<cv::Vec3f>(y);
      for (int x = xa; x <= xb; ++x) {
        const double dist = std::hypot(x + 0.5 - disc.centre.x(), y + 0.5 - disc.centre.y());
        const double coverage = std::clamp(r - dist + 0.5, 0.0, 1.0);
        if (coverage <= 0.0) continue;
        const double rho = std::min(dist / r, 1.0);
        const float alpha = static_cast<float>(drawn.opacity * coverage);
        const cv::Vec3f shaded = colour * static_cast<float>(1.0 - 0.15 * rho * rho);
        row[x] = (1.0f - alpha) * row[x] + alpha * shaded;
      }
    }
  }

  // Lighting, then sensor noise (from the seed and the frame), then blur.
  SplitMix64 rng(DeriveSeed(seed_, 0x6e01u + static_cast<uint64_t>(frame)));
  const float sigma = static_cast<float>(camera_.noise_sigma);
  for (int y = 0; y < H; ++y) {
    cv::Vec3f* row = image.ptr<cv::Vec3f>(y);
    const float* light = lighting_.ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      row[x] *= light[x];
      if (sigma > 0.0f) {
        for (int c = 0; c < 3; ++c) row[x][c] += sigma * static_cast<float>(rng.Normal());
      }
    }
  }
  if (camera_.blur_sigma_px > 0.0) {
    cv::GaussianBlur(image, image, cv::Size(0, 0), camera_.blur_sigma_px, camera_.blur_sigma_px,
                     cv::BORDER_REFLECT);
  }
  cv::Mat out;
  image.convertTo(out, CV_8UC3);  // rounds and saturates
  return out;
}

BitMask FrameRenderer::TruthMask(const std::vector<Vec2>& positions) const {
  BitMask mask(camera_.width_px, camera_.height_px);
  Rasterizer rasterizer;
  rasterizer.RasterizeTriangles(mesh_, positions, mask);
  return mask;
}

}  // namespace calib::synth
