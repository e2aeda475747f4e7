#include "object_outline.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace calib::synth::outline_detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Longest chord of a rounded corner's arc, px.
constexpr double kArcChordPx = 4.0;

using Polygon = std::vector<Vec2>;

Polygon Rectangle(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

Polygon Waist(double x0, double y0, double x1, double y1, double depth) {
  const double h = y1 - y0;
  const double ya = y0 + 0.35 * h, yb = y0 + 0.45 * h;
  const double yc = y0 + 0.55 * h, yd = y0 + 0.65 * h;
  return {{x0, y0},     {x1, y0},     {x1, ya}, {x1 - depth, yb}, {x1 - depth, yc}, {x1, yd},
          {x1, y1},     {x0, y1},     {x0, yd}, {x0 + depth, yc}, {x0 + depth, yb}, {x0, ya}};
}

Polygon Rounded(double x0, double y0, double x1, double y1, double radius) {
  const int segments =
      std::max(2, static_cast<int>(std::ceil(0.5 * std::numbers::pi * radius / kArcChordPx)));
  // Corner centres clockwise from the near-right corner, each arc starting
  // where the previous side ends (angles in image axes: -90 deg points up).
  const Vec2 centres[4] = {{x1 - radius, y0 + radius}, {x1 - radius, y1 - radius},
                           {x0 + radius, y1 - radius}, {x0 + radius, y0 + radius}};
  Polygon out;
  for (int c = 0; c < 4; ++c) {
    const double start = (-0.5 + 0.5 * c) * std::numbers::pi;
    for (int k = 0; k <= segments; ++k) {
      const double a = start + 0.5 * std::numbers::pi * k / segments;
      out.push_back(centres[c] + radius * Vec2(std::cos(a), std::sin(a)));
    }
  }
  return out;
}

// The notch as the points that replace a side's straight run, in the
// polygon's (clockwise) order along that side.
Polygon Notched(double x0, double y0, double x1, double y1, const NotchSpec& n, double mm_per_px) {
  const double width = std::round(n.width_mm / mm_per_px);
  const double depth = std::round(n.depth_mm / mm_per_px);
  const bool across = n.side == ObjectSide::kNear || n.side == ObjectSide::kFar;
  const double length = across ? x1 - x0 : y1 - y0;
  const double a = std::round(n.position_fraction * length - 0.5 * width);  // from the side's start
  const double b = a + width;
  switch (n.side) {
    case ObjectSide::kNear:
      return {{x0, y0},         {x0 + a, y0}, {x0 + a, y0 + depth}, {x0 + b, y0 + depth},
              {x0 + b, y0},     {x1, y0},     {x1, y1},             {x0, y1}};
    case ObjectSide::kRight:
      return {{x0, y0},         {x1, y0},     {x1, y0 + a},         {x1 - depth, y0 + a},
              {x1 - depth, y0 + b}, {x1, y0 + b}, {x1, y1},         {x0, y1}};
    case ObjectSide::kFar:
      return {{x0, y0},         {x1, y0},     {x1, y1},             {x0 + b, y1},
              {x0 + b, y1 - depth}, {x0 + a, y1 - depth}, {x0 + a, y1}, {x0, y1}};
    case ObjectSide::kLeft:
      return {{x0, y0},         {x1, y0},     {x1, y1},             {x0, y1},
              {x0, y0 + b},     {x0 + depth, y0 + b}, {x0 + depth, y0 + a}, {x0, y0 + a}};
  }
  return Rectangle(x0, y0, x1, y1);
}

Polygon LShape(double x0, double y0, double x1, double y1, const CutoutSpec& c, double mm_per_px) {
  const double w = std::round(c.width_mm / mm_per_px);
  const double h = std::round(c.height_mm / mm_per_px);
  switch (c.corner) {
    case ObjectCorner::kNearLeft:
      return {{x0 + w, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0 + h}, {x0 + w, y0 + h}};
    case ObjectCorner::kNearRight:
      return {{x0, y0}, {x1 - w, y0}, {x1 - w, y0 + h}, {x1, y0 + h}, {x1, y1}, {x0, y1}};
    case ObjectCorner::kFarRight:
      return {{x0, y0}, {x1, y0}, {x1, y1 - h}, {x1 - w, y1 - h}, {x1 - w, y1}, {x0, y1}};
    case ObjectCorner::kFarLeft:
      return {{x0, y0}, {x1, y0}, {x1, y1}, {x0 + w, y1}, {x0 + w, y1 - h}, {x0, y1 - h}};
  }
  return Rectangle(x0, y0, x1, y1);
}

// The first touch of a disc moving along the vertical line x towards the
// polygon: from above (`sign` -1: the smallest centre y at which the disc
// touches) or from below (`sign` +1: the largest). The disc touches an edge
// where its centre lies in the edge's capsule of the disc's radius: the
// capsule's extreme point on the line is on an end cap (a vertex) or on one
// of the two offset edges.
double FirstTouch(const Polygon& polygon, double x, double radius, double sign) {
  double best = -sign * kInf;
  const auto take = [&](double y) { best = sign < 0.0 ? std::min(best, y) : std::max(best, y); };
  const size_t n = polygon.size();
  for (size_t i = 0; i < n; ++i) {
    const Vec2& a = polygon[i];
    const Vec2& b = polygon[(i + 1) % n];
    const double dx = x - a.x();
    if (std::abs(dx) <= radius) take(a.y() + sign * std::sqrt(radius * radius - dx * dx));
    const Vec2 d = b - a;
    const double length = d.norm();
    if (length == 0.0) continue;
    const Vec2 normal(-d.y() / length, d.x() / length);
    for (const double side : {-1.0, 1.0}) {
      const Vec2 p = a + side * radius * normal;
      const Vec2 q = b + side * radius * normal;
      if (p.x() == q.x() || x < std::min(p.x(), q.x()) || x > std::max(p.x(), q.x())) continue;
      const double t = (x - p.x()) / (q.x() - p.x());
      take(p.y() + t * (q.y() - p.y()));
    }
  }
  return best;
}

}  // namespace

std::vector<Vec2> UnturnedOutlinePx(const Scenario& s) {
  const RectPx r = ObjectRectPx(s);
  const double x0 = r.x, y0 = r.y, x1 = r.x + r.width, y1 = r.y + r.height;
  const ObjectSpec& o = s.object;
  switch (o.shape) {
    case ObjectShape::kRectangle:
      return Rectangle(x0, y0, x1, y1);
    case ObjectShape::kWaist: {
      const double depth = std::round(o.waist_mm / s.mm_per_px);
      return depth > 0.0 ? Waist(x0, y0, x1, y1, depth) : Rectangle(x0, y0, x1, y1);
    }
    case ObjectShape::kRounded:
      return Rounded(x0, y0, x1, y1, o.corner_radius_mm.value_or(0.0) / s.mm_per_px);
    case ObjectShape::kNotched:
      return Notched(x0, y0, x1, y1, o.notch.value_or(NotchSpec{}), s.mm_per_px);
    case ObjectShape::kLShape:
      return LShape(x0, y0, x1, y1, o.cutout.value_or(CutoutSpec{}), s.mm_per_px);
  }
  return Rectangle(x0, y0, x1, y1);
}

Vec2 TurnDirection(const Scenario& s, const Vec2& v) {
  if (s.object.rotation_deg == 0.0) return v;
  const double a = s.object.rotation_deg * std::numbers::pi / 180.0;
  const double c = std::cos(a), sn = std::sin(a);
  return Vec2(c * v.x() - sn * v.y(), sn * v.x() + c * v.y());
}

Vec2 TurnPx(const Scenario& s, const Vec2& p) {
  if (s.object.rotation_deg == 0.0) return p;
  const RectPx r = ObjectRectPx(s);
  const Vec2 centre(r.x + 0.5 * r.width, r.y + 0.5 * r.height);
  return centre + TurnDirection(s, p - centre);
}

double FirstTouchFromAbove(const std::vector<Vec2>& polygon, double x_px, double radius_px) {
  return FirstTouch(polygon, x_px, radius_px, -1.0);
}

double FirstTouchFromBelow(const std::vector<Vec2>& polygon, double x_px, double radius_px) {
  return FirstTouch(polygon, x_px, radius_px, 1.0);
}

}  // namespace calib::synth::outline_detail
