// Object shapes and rotation in scenarios: each shape's outline (area,
// orientation, no self-crossing), the finger and the pencil placed against
// the actual outline at every position tried, a turned object's push along
// its near side's inward normal, and each kind of bad shape key named.

#include "calib/synth/scenario.h"

#include "error_text.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace calib::synth {
namespace {

double PolygonArea(const std::vector<Vec2>& p) {  // > 0: clockwise on screen (y down)
  double twice = 0.0;
  for (size_t i = 0; i < p.size(); ++i) {
    const Vec2& a = p[i];
    const Vec2& b = p[(i + 1) % p.size()];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return 0.5 * twice;
}

double SegmentDistance(const Vec2& q, const Vec2& a, const Vec2& b) {
  const Vec2 d = b - a;
  const double t = std::clamp((q - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (q - (a + t * d)).norm();
}

double DistanceToOutline(const Vec2& q, const std::vector<Vec2>& p) {
  double best = 1e300;
  for (size_t i = 0; i < p.size(); ++i) best = std::min(best, SegmentDistance(q, p[i], p[(i + 1) % p.size()]));
  return best;
}

bool Inside(const Vec2& q, const std::vector<Vec2>& p) {  // even-odd rule
  bool in = false;
  for (size_t i = 0, j = p.size() - 1; i < p.size(); j = i++) {
    if ((p[i].y() > q.y()) != (p[j].y() > q.y()) &&
        q.x() < (p[j].x() - p[i].x()) * (q.y() - p[i].y()) / (p[j].y() - p[i].y()) + p[i].x()) {
      in = !in;
    }
  }
  return in;
}

bool SegmentsCross(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const auto cross = [](const Vec2& u, const Vec2& v) { return u.x() * v.y() - u.y() * v.x(); };
  const double d1 = cross(b - a, c - a), d2 = cross(b - a, d - a);
  const double d3 = cross(d - c, a - c), d4 = cross(d - c, b - c);
  return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0)) && d1 != 0 && d2 != 0 && d3 != 0 && d4 != 0;
}

bool Simple(const std::vector<Vec2>& p) {
  const size_t n = p.size();
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i + 2; j < n; ++j) {
      if (i == 0 && j == n - 1) continue;  // neighbours through the closing edge
      if (SegmentsCross(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n])) return false;
    }
  }
  return true;
}

struct ShapeCase {
  std::string name;
  std::string object;   // the object section, YAML flow map
  double expected_area_px2;
  double area_tolerance_px2;
};

// 100 x 64 mm at 0.25 mm/px: a 400 x 256 px rectangle.
std::vector<ShapeCase> Shapes() {
  const double rect = 400.0 * 256.0;
  const double r = 32.0;  // 8 mm corner radius in px
  return {
      {"rectangle", "{shape: rectangle}", rect, 1e-9},
      // Two trapezoids 12 px deep, 0.3 h long at the mouth and 0.1 h at the floor.
      {"waist", "{shape: waist, waist_mm: 3}", rect - 2.0 * 12.0 * 0.2 * 256.0, 1e-6},
      // Inscribed arcs: a little less than the exact (4 - pi) r^2 cut.
      {"rounded", "{shape: rounded, corner_radius_mm: 8}", rect - (4.0 - std::numbers::pi) * r * r, 40.0},
      {"notched", "{shape: notched, notch: {side: far, position_fraction: 0.3, width_mm: 12, depth_mm: 8}}",
       rect - 48.0 * 32.0, 1e-9},
      {"notched_near", "{shape: notched, notch: {side: near, position_fraction: 0.5, width_mm: 20, depth_mm: 6}}",
       rect - 80.0 * 24.0, 1e-9},
      {"notched_left", "{shape: notched, notch: {side: left, position_fraction: 0.5, width_mm: 10, depth_mm: 10}}",
       rect - 40.0 * 40.0, 1e-9},
      {"l_shape", "{shape: l_shape, cutout: {corner: near_right, width_mm: 40, height_mm: 20}}",
       rect - 160.0 * 80.0, 1e-9},
      {"l_shape_far_left", "{shape: l_shape, cutout: {corner: far_left, width_mm: 30, height_mm: 25}}",
       rect - 120.0 * 100.0, 1e-9},
  };
}

Scenario Parse(const std::string& object, const std::string& push = "{}") {
  return ParseScenario("kind: push\nobject: " + object + "\npush: " + push + "\n", "shape.yaml");
}

TEST(ObjectShape, OutlinesHaveTheirAreaAndAreSimpleAndClockwise) {
  for (const ShapeCase& c : Shapes()) {
    const Scenario s = Parse(c.object);
    std::string error;
    ASSERT_TRUE(s.IsValid(&error)) << c.name << ": " << error;
    const std::vector<Vec2> outline = RestPolygonPx(s);
    EXPECT_NEAR(PolygonArea(outline), c.expected_area_px2, c.area_tolerance_px2) << c.name;
    EXPECT_TRUE(Simple(outline)) << c.name;
    // Inside the rectangle it is cut from.
    const RectPx r = ObjectRectPx(s);
    for (const Vec2& p : outline) {
      EXPECT_TRUE(p.x() >= r.x && p.x() <= r.x + r.width && p.y() >= r.y && p.y() <= r.y + r.height)
          << c.name << ": (" << p.x() << ", " << p.y() << ")";
    }
  }
}

TEST(ObjectShape, ShapeRoundTripsThroughYaml) {
  for (const ShapeCase& c : Shapes()) {
    const Scenario s = Parse(c.object, "{}");
    const std::string yaml = ScenarioToYaml(s);
    const Scenario back = ParseScenario(yaml, "back.yaml");
    EXPECT_EQ(ScenarioToYaml(back), yaml) << c.name;
    EXPECT_EQ(RestPolygonPx(back), RestPolygonPx(s)) << c.name;
  }
}

// The finger starts start_gap_mm (along its way in) from where it first
// touches the outline and reaches depth_mm past there; the pencil stands
// pencil_gap_mm (along the same line) from where it would touch the outline.
void ExpectPlacedAgainstOutline(const Scenario& s, const std::string& label) {
  const std::vector<Vec2> outline = RestPolygonPx(s);
  const auto tracks = ObstacleTracksPx(s);
  const Disc& start = tracks.front()[0];
  const double px = 1.0 / s.mm_per_px;
  const double a = s.object.rotation_deg * std::numbers::pi / 180.0;
  const Vec2 inward(-std::sin(a), std::cos(a));  // (0, 1) turned with the object
  const Vec2 touch = start.centre + s.push.start_gap_mm * px * inward;
  EXPECT_NEAR(DistanceToOutline(touch, outline), start.radius_px, 1e-6) << label;
  EXPECT_FALSE(Inside(touch, outline)) << label;
  EXPECT_GE(DistanceToOutline(start.centre, outline), start.radius_px - 1e-9) << label;
  const Disc& pencil = tracks.front()[1];
  const Vec2 pencil_touch = pencil.centre - s.push.pencil_gap_mm * px * inward;
  EXPECT_NEAR(DistanceToOutline(pencil_touch, outline), pencil.radius_px, 1e-6) << label;
  EXPECT_FALSE(Inside(pencil_touch, outline)) << label;
  // The deepest frame: the disc has travelled gap + depth along the inward
  // normal of the near side.
  double deepest = 0.0;
  Vec2 deep_centre = start.centre;
  for (const auto& frame : tracks) {
    const double travel = (frame[0].centre - start.centre).dot(inward);
    if (travel > deepest) {
      deepest = travel;
      deep_centre = frame[0].centre;
    }
  }
  EXPECT_NEAR(deepest, (s.push.start_gap_mm + s.push.depth_mm) * px, 1e-6) << label;
  const Vec2 sideways = deep_centre - start.centre - deepest * inward;
  EXPECT_LT(sideways.norm(), 1e-6) << label;
  // The pencil is on the far side: beyond the object's centre along the
  // finger's way in.
  const RectPx r = ObjectRectPx(s);
  const Vec2 centre(r.x + 0.5 * r.width, r.y + 0.5 * r.height);
  EXPECT_GT((pencil.centre - centre).dot(inward), 0.0) << label;
  EXPECT_LT((start.centre - centre).dot(inward), 0.0) << label;
}

TEST(ObjectShape, FingerAndPencilArePlacedAgainstTheActualOutline) {
  for (const ShapeCase& c : Shapes()) {
    for (const double position : {0.05, 0.3, 0.5, 0.85}) {
      for (const double pencil : {0.1, 0.5, 0.7}) {
        const std::string push = "{position_fraction: " + std::to_string(position) +
                                 ", pencil_position_fraction: " + std::to_string(pencil) +
                                 ", start_gap_mm: 3, pencil_gap_mm: 0.5, depth_mm: 6}";
        const Scenario s = Parse(c.object, push);
        ExpectPlacedAgainstOutline(s, c.name + " at " + std::to_string(position) + ", pencil at " +
                                          std::to_string(pencil));
      }
    }
  }
}

TEST(ObjectShape, FingerOverACutoutMeetsTheStepBelowIt) {
  // Near-right block 40 x 20 mm removed: a finger at 90 % of the width comes
  // down onto the step 80 px below the near side.
  const Scenario s =
      Parse("{shape: l_shape, cutout: {corner: near_right, width_mm: 40, height_mm: 20}}",
            "{position_fraction: 0.9, start_gap_mm: 0}");
  const RectPx r = ObjectRectPx(s);
  const auto tracks = ObstacleTracksPx(s);
  const Disc& finger = tracks.front()[0];
  EXPECT_NEAR(finger.centre.y() + finger.radius_px, r.y + 80.0, 1e-9);
}

TEST(ObjectShape, TurnedObjectTurnsItsOutlineAndPush) {
  for (const ShapeCase& c : Shapes()) {
    const Scenario flat = Parse(c.object, "{position_fraction: 0.4}");
    for (const double angle : {-35.0, 20.0, 90.0}) {
      std::string object = c.object;
      object.insert(object.size() - 1, ", rotation_deg: " + std::to_string(angle));
      const Scenario s = Parse(object, "{position_fraction: 0.4}");
      std::string error;
      ASSERT_TRUE(s.IsValid(&error)) << c.name << " " << angle << ": " << error;
      const std::vector<Vec2> outline = RestPolygonPx(s);
      const std::vector<Vec2> unturned = RestPolygonPx(flat);
      ASSERT_EQ(outline.size(), unturned.size());
      EXPECT_NEAR(PolygonArea(outline), PolygonArea(unturned), 1e-6 * PolygonArea(unturned)) << c.name;
      // Turned about the rectangle's centre: distances to it are kept.
      const RectPx r = ObjectRectPx(s);
      const Vec2 centre(r.x + 0.5 * r.width, r.y + 0.5 * r.height);
      for (size_t i = 0; i < outline.size(); ++i) {
        EXPECT_NEAR((outline[i] - centre).norm(), (unturned[i] - centre).norm(), 1e-9);
      }
      ExpectPlacedAgainstOutline(s, c.name + " turned " + std::to_string(angle));
    }
  }
}

TEST(ObjectShape, UnevenStiffnessTurnsWithTheObject) {
  const std::string effects =
      "\neffects: {uneven_stiffness: {gradient: 0.5, direction: [1, 0], "
      "regions: [{centre_fraction: [0.25, 0.5], radius_mm: 10, factor: 2}]}}\n";
  const Scenario s = ParseScenario("kind: push\nobject: {width_mm: 80, rotation_deg: 90}" + effects, "u.yaml");
  const TruthMaterial m = ToTruthMaterial(s);
  EXPECT_NEAR(m.stiffness_gradient_direction.x(), 0.0, 1e-12);
  EXPECT_NEAR(m.stiffness_gradient_direction.y(), 1.0, 1e-12);  // x turned clockwise on screen: down
  const RectPx r = ObjectRectPx(s);
  ASSERT_EQ(m.stiffness_regions.size(), 1u);
  // A quarter of the width left of the centre, turned 90 degrees: above it.
  EXPECT_NEAR(m.stiffness_regions[0].centre_px.x(), r.x + 0.5 * r.width, 1e-9);
  EXPECT_NEAR(m.stiffness_regions[0].centre_px.y(), r.y + 0.5 * r.height - 0.25 * r.width, 1e-9);
}

// Parses `text` as a scenario named bad.yaml: refused, naming the file and `parts`.
void ExpectShapeErrorNames(const std::string& text, const std::vector<std::string>& parts) {
  const std::string error =
      testing::ErrorOf<ScenarioError>([&] { ParseScenario(text, "bad.yaml"); });
  testing::ExpectMessageNames(error, text, parts);
  EXPECT_NE(error.find("bad.yaml"), std::string::npos) << error;
}

TEST(ObjectShape, UnknownShapeSideOrCornerIsNamed) {
  ExpectShapeErrorNames("object: {shape: star}\n", {"object.shape", "'star'", "rectangle, waist, rounded"});
  ExpectShapeErrorNames("object: {shape: notched, notch: {side: top}}\n", {"object.notch.side", "'top'", "near"});
  ExpectShapeErrorNames("object: {shape: l_shape, cutout: {corner: top_left}}\n",
                   {"object.cutout.corner", "'top_left'", "near_left"});
  ExpectShapeErrorNames("object: {shape: notched, notch: {sid: far}}\n", {"object.notch.sid", "unknown key"});
}

TEST(ObjectShape, ShapeKeysOfAnotherShapeAreNamed) {
  ExpectShapeErrorNames("object: {corner_radius_mm: 5}\n", {"object.corner_radius_mm = 5", "only shape rounded"});
  ExpectShapeErrorNames("object: {shape: rounded, notch: {}}\n", {"object.notch", "only shape notched"});
  ExpectShapeErrorNames("object: {cutout: {}}\n", {"object.cutout", "only shape l_shape"});
  ExpectShapeErrorNames("object: {shape: rounded, waist_mm: 3}\n", {"object.waist_mm = 3", "shape is rounded"});
  ExpectShapeErrorNames("object: {shape: waist}\n", {"object.waist_mm = 0", "shape waist"});
}

TEST(ObjectShape, OutOfRangeShapeValuesAreNamed) {
  ExpectShapeErrorNames("object: {shape: rounded, corner_radius_mm: 40}\n", {"object.corner_radius_mm = 40"});
  ExpectShapeErrorNames("object: {shape: notched, notch: {position_fraction: 0.02}}\n",
                   {"object.notch.position_fraction = 0.02", "inside its side"});
  ExpectShapeErrorNames("object: {shape: notched, notch: {depth_mm: 40}}\n", {"object.notch.depth_mm = 40"});
  ExpectShapeErrorNames("object: {shape: notched, notch: {width_mm: 0.2}}\n", {"object.notch.width_mm = 0.2", "2 px"});
  ExpectShapeErrorNames("object: {shape: l_shape, cutout: {width_mm: 90}}\n", {"object.cutout.width_mm = 90"});
  ExpectShapeErrorNames("object: {shape: l_shape, cutout: {height_mm: -2}}\n", {"object.cutout.height_mm = -2"});
  ExpectShapeErrorNames("object: {rotation_deg: 200}\n", {"object.rotation_deg = 200"});
  ExpectShapeErrorNames("object: {width_mm: 110, rotation_deg: 45}\n",
                   {"object.rotation_deg = 45", "turned object fits"});
  ExpectShapeErrorNames("kind: hang\nobject: {rotation_deg: 10}\n", {"object.rotation_deg = 10", "kind hang"});
  // Pushing 12 mm into the 44 mm left under a 20 mm cutout: past half of it.
  ExpectShapeErrorNames(
      "object: {shape: l_shape, cutout: {corner: near_left, width_mm: 40, height_mm: 20}}\n"
      "push: {position_fraction: 0.2, depth_mm: 24}\n",
      {"push.depth_mm = 24", "thickness under the finger"});
  ExpectShapeErrorNames("object: {rotation_deg: 30, width_mm: 60, height_mm: 40}\npush: {start_gap_mm: 60}\n",
                   {"push.start_gap_mm = 60", "finger starts inside the image"});
}

}  // namespace
}  // namespace calib::synth
