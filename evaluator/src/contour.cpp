#include "calib/evaluator/contour.h"

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace calib {
namespace {

// 0/255 8-bit image of the mask, mask coordinates. (Local on purpose; see
// bit_mask_cv.h for the shared conversion.)
cv::Mat MaskToMat(const BitMask& mask) {
  cv::Mat image(mask.height(), mask.width(), CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < mask.height(); ++y) {
    auto* row = image.ptr<uint8_t>(y);
    for (int x = 0; x < mask.width(); ++x) row[x] = mask.Get(x, y) ? 255 : 0;
  }
  return image;
}

double TwiceArea(const std::vector<Vec2>& polygon) {
  double twice = 0.0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    twice += Cross(polygon[i], polygon[(i + 1) % polygon.size()]);
  }
  return twice;
}

// Moves every side of `polygon` (positive area, see contour.h) outward by
// half a pixel measured along the axis closest to its normal: by
// 0.5 * max(|n.x|, |n.y|) for the outward unit normal n = (d.y, -d.x) / |d| of
// side d. A chain through the centres of a digital line's border pixels lies,
// on average, that far inside the pixels' squares (0.5 for an axis-aligned
// side, 0.5 / sqrt(2) for a 45-degree staircase), so the moved polygon has the
// pixels' area.
std::vector<Vec2> OffsetToPixelSquares(const std::vector<Vec2>& polygon) {
  const size_t n = polygon.size();
  std::vector<Vec2> normals(n);
  std::vector<double> offsets(n);
  for (size_t i = 0; i < n; ++i) {
    const Vec2 d = polygon[(i + 1) % n] - polygon[i];
    normals[i] = Vec2(d.y(), -d.x()).normalized();
    offsets[i] = 0.5 * normals[i].cwiseAbs().maxCoeff();
  }
  std::vector<Vec2> out;
  out.reserve(n + n / 4);
  for (size_t i = 0; i < n; ++i) {
    const size_t before = (i + n - 1) % n;
    const Vec2& n1 = normals[before];
    const Vec2& n2 = normals[i];
    const double h1 = offsets[before], h2 = offsets[i];
    const double det = Cross(n1, n2);
    if (n1.dot(n2) < 0.0) {
      // Turning by more than 90 degrees: bevel instead of a long mitre.
      out.push_back(polygon[i] + h1 * n1);
      out.push_back(polygon[i] + h2 * n2);
    } else if (std::abs(det) < 1e-12) {
      out.push_back(polygon[i] + 0.5 * (h1 + h2) * n1);
    } else {
      // The intersection of the two moved side lines: m.n1 = h1, m.n2 = h2.
      const Vec2 m((h1 * n2.y() - h2 * n1.y()) / det, (n1.x() * h2 - n2.x() * h1) / det);
      out.push_back(polygon[i] + m);
    }
  }
  return out;
}

}  // namespace

std::vector<Vec2> ObjectOutline(const BitMask& mask, double tolerance_px) {
  if (!std::isfinite(tolerance_px) || tolerance_px < 0.0) {
    throw std::invalid_argument(
        fmt::format("ObjectOutline: tolerance_px = {}. Violated: finite and >= 0.", tolerance_px));
  }
  if (mask.width() <= 0 || mask.height() <= 0 || mask.Count() == 0) {
    throw std::invalid_argument(fmt::format(
        "ObjectOutline: the {}x{} mask has no pixel set; no object to outline", mask.width(),
        mask.height()));
  }

  // Largest region by pixel count (8-connected, as findContours traces).
  const cv::Mat image = MaskToMat(mask);
  cv::Mat labels, stats, centroids;
  const int num_labels = cv::connectedComponentsWithStats(image, labels, stats, centroids, 8,
                                                          CV_32S);
  int largest = 1;
  for (int l = 2; l < num_labels; ++l) {
    if (stats.at<int>(l, cv::CC_STAT_AREA) > stats.at<int>(largest, cv::CC_STAT_AREA)) {
      largest = l;
    }
  }
  const cv::Mat region = labels == largest;

  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(region, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  const auto longest = std::max_element(
      contours.begin(), contours.end(),
      [](const auto& a, const auto& b) { return a.size() < b.size(); });
  std::vector<cv::Point> simplified;
  cv::approxPolyDP(*longest, simplified, tolerance_px, /*closed=*/true);

  const Vec2 centre_offset(mask.origin_x() + 0.5, mask.origin_y() + 0.5);
  std::vector<Vec2> polygon;
  polygon.reserve(simplified.size());
  for (const cv::Point& p : simplified) {
    const Vec2 v = Vec2(p.x, p.y) + centre_offset;
    if (polygon.empty() || v != polygon.back()) polygon.push_back(v);
  }
  while (polygon.size() > 1 && polygon.front() == polygon.back()) polygon.pop_back();

  const double twice_area = TwiceArea(polygon);
  if (polygon.size() < 3 || std::abs(twice_area) < 1.0) {
    const cv::Rect box(stats.at<int>(largest, cv::CC_STAT_LEFT),
                       stats.at<int>(largest, cv::CC_STAT_TOP),
                       stats.at<int>(largest, cv::CC_STAT_WIDTH),
                       stats.at<int>(largest, cv::CC_STAT_HEIGHT));
    const double x0 = mask.origin_x() + box.x, y0 = mask.origin_y() + box.y;
    const double x1 = x0 + box.width, y1 = y0 + box.height;
    return {Vec2(x0, y0), Vec2(x1, y0), Vec2(x1, y1), Vec2(x0, y1)};
  }
  if (twice_area < 0.0) std::reverse(polygon.begin(), polygon.end());
  return OffsetToPixelSquares(polygon);
}

}  // namespace calib
