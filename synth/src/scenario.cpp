#include "calib/synth/scenario.h"

#include "calib/core/enum_names.h"
#include "calib/core/yaml_map_reader.h"

#include "object_outline.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>

namespace calib::synth {

namespace {

constexpr auto kScenarioKindNames = std::to_array<EnumName<ScenarioKind>>({
    {ScenarioKind::kPush, "push"},
    {ScenarioKind::kHang, "hang"},
});
constexpr auto kObjectShapeNames = std::to_array<EnumName<ObjectShape>>({
    {ObjectShape::kRectangle, "rectangle"},
    {ObjectShape::kWaist, "waist"},
    {ObjectShape::kRounded, "rounded"},
    {ObjectShape::kNotched, "notched"},
    {ObjectShape::kLShape, "l_shape"},
});
constexpr auto kObjectSideNames = std::to_array<EnumName<ObjectSide>>({
    {ObjectSide::kNear, "near"},
    {ObjectSide::kFar, "far"},
    {ObjectSide::kLeft, "left"},
    {ObjectSide::kRight, "right"},
});
constexpr auto kObjectCornerNames = std::to_array<EnumName<ObjectCorner>>({
    {ObjectCorner::kNearLeft, "near_left"},
    {ObjectCorner::kNearRight, "near_right"},
    {ObjectCorner::kFarLeft, "far_left"},
    {ObjectCorner::kFarRight, "far_right"},
});

/// The corner radius a file naming shape rounded without one gets, mm.
constexpr double kDefaultCornerRadiusMm = 8.0;

}  // namespace

std::string ToString(ScenarioKind kind) { return EnumToString(kScenarioKindNames, kind); }

ScenarioKind ScenarioKindFromString(const std::string& text) {
  return EnumFromString(kScenarioKindNames, "scenario kind", text);
}

std::string ToString(ObjectShape shape) { return EnumToString(kObjectShapeNames, shape); }
ObjectShape ObjectShapeFromString(const std::string& text) {
  return EnumFromString(kObjectShapeNames, "object shape", text);
}
std::string ToString(ObjectSide side) { return EnumToString(kObjectSideNames, side); }
ObjectSide ObjectSideFromString(const std::string& text) {
  return EnumFromString(kObjectSideNames, "object side", text);
}
std::string ToString(ObjectCorner corner) { return EnumToString(kObjectCornerNames, corner); }
ObjectCorner ObjectCornerFromString(const std::string& text) {
  return EnumFromString(kObjectCornerNames, "object corner", text);
}

std::vector<std::string> Effects::EnabledNames() const {
  std::vector<std::string> names;
  if (plasticity) names.push_back("plasticity");
  if (uneven_stiffness) names.push_back("uneven_stiffness");
  if (strain_stiffening) names.push_back("strain_stiffening");
  if (viscoelastic) names.push_back("viscoelastic");
  if (strong_friction) names.push_back("strong_friction");
  if (inertia_gravity) names.push_back("inertia_gravity");
  return names;
}

Scenario WithoutEffects(const Scenario& scenario) {
  Scenario twin = scenario;
  twin.effects = Effects{};
  if (twin.kind == ScenarioKind::kHang) twin.effects.inertia_gravity = scenario.effects.inertia_gravity;
  const std::vector<std::string> off = scenario.effects.EnabledNames();
  std::string removed;
  for (const std::string& name : off) {
    if (name == "inertia_gravity" && twin.kind == ScenarioKind::kHang) continue;
    removed += (removed.empty() ? "" : ", ") + name;
  }
  twin.notes = fmt::format("{} [effects switched off: {}]", scenario.notes,
                           removed.empty() ? std::string("none were on") : removed);
  return twin;
}

Scenario DefaultScenario(ScenarioKind kind) {
  Scenario s;
  s.kind = kind;
  if (kind == ScenarioKind::kHang) {
    s.name = "hang";
    s.fps = 240.0;
    s.frames = 180;
    s.object.width_mm = 25.0;
    s.object.height_mm = 100.0;
    s.environment.friction_coefficient = 0.0;
    s.effects.inertia_gravity = InertiaGravityEffect{};
  } else {
    s.name = "push";
    s.simulation.substeps = 2;  // quasi-static: steps only resolve friction and flow
  }
  return s;
}

// ---------------------------------------------------------------- parsing
namespace {

// The project's YAML map reader (calib/core/yaml_map_reader.h) raising
// ScenarioError; a key written without a value is present with nothing in it
// (`plasticity:` turns the effect on with its defaults; `fps:` is an error).
using yaml_reader::MapReader;

[[noreturn]] void RaiseScenarioError(const std::string& message) { throw ScenarioError(message); }

// Reads `key` as a name `from_string` knows (throwing std::invalid_argument
// with the names it knows otherwise) into *value when the map has it.
template <typename E>
void ReadEnum(MapReader& r, const std::string& key, E* value, E (*from_string)(const std::string&)) {
  if (!r.Has(key)) return;
  const YAML::Node n = r.Get(key);
  try {
    if (!n.IsScalar()) throw std::invalid_argument("expected a name");
    *value = from_string(n.Scalar());
  } catch (const std::invalid_argument& e) {
    r.Fail(r.KeyPath(key), n, e.what());
  }
}

void ReadObject(MapReader r, ObjectSpec* o) {
  const bool shape_named = r.Has("shape");
  ReadEnum(r, "shape", &o->shape, &ObjectShapeFromString);
  r.Read("width_mm", &o->width_mm);
  r.Read("height_mm", &o->height_mm);
  r.Read("waist_mm", &o->waist_mm);
  r.Read("corner_radius_mm", &o->corner_radius_mm);
  if (r.Has("notch")) {
    MapReader c = r.OptionalChild("notch");
    NotchSpec notch;
    ReadEnum(c, "side", &notch.side, &ObjectSideFromString);
    c.Read("position_fraction", &notch.position_fraction);
    c.Read("width_mm", &notch.width_mm);
    c.Read("depth_mm", &notch.depth_mm);
    c.Finish();
    o->notch = notch;
  }
  if (r.Has("cutout")) {
    MapReader c = r.OptionalChild("cutout");
    CutoutSpec cutout;
    ReadEnum(c, "corner", &cutout.corner, &ObjectCornerFromString);
    c.Read("width_mm", &cutout.width_mm);
    c.Read("height_mm", &cutout.height_mm);
    c.Finish();
    o->cutout = cutout;
  }
  r.Read("rotation_deg", &o->rotation_deg);
  r.Finish();
  // Files from before shapes had names give only a waist.
  if (!shape_named && o->waist_mm > 0.0) o->shape = ObjectShape::kWaist;
  if (o->shape == ObjectShape::kRounded && !o->corner_radius_mm) o->corner_radius_mm = kDefaultCornerRadiusMm;
  if (o->shape == ObjectShape::kNotched && !o->notch) o->notch = NotchSpec{};
  if (o->shape == ObjectShape::kLShape && !o->cutout) o->cutout = CutoutSpec{};
}

void ReadPush(MapReader r, PushSpec* p) {
  r.Read("finger_radius_mm", &p->finger_radius_mm);
  r.Read("position_fraction", &p->position_fraction);
  r.Read("position_mm", &p->position_mm);
  r.Read("depth_mm", &p->depth_mm);
  r.Read("start_gap_mm", &p->start_gap_mm);
  r.Read("delay_s", &p->delay_s);
  r.Read("approach_s", &p->approach_s);
  r.Read("hold_s", &p->hold_s);
  r.Read("retract_s", &p->retract_s);
  r.Read("pencil_radius_mm", &p->pencil_radius_mm);
  r.Read("pencil_position_fraction", &p->pencil_position_fraction);
  r.Read("pencil_gap_mm", &p->pencil_gap_mm);
  r.Finish();
}

void ReadHang(MapReader r, HangSpec* h) {
  r.Read("top_margin_mm", &h->top_margin_mm);
  r.Read("clamp_depth_mm", &h->clamp_depth_mm);
  r.Read("initial_bend_m_s2", &h->initial_bend_m_s2);
  r.Finish();
}

// Reads effect `name` into *slot when the map has it (`{}` or empty: the
// defaults); `read_keys(reader, effect)` reads the effect's own keys.
template <typename Effect, typename ReadKeys>
void ReadEffect(MapReader& r, const char* name, std::optional<Effect>* slot, ReadKeys read_keys) {
  if (!r.Has(name)) return;
  MapReader c = r.OptionalChild(name);
  Effect effect;
  read_keys(c, effect);
  c.Finish();
  *slot = effect;
}

void ReadEffects(MapReader r, Effects* e) {
  ReadEffect(r, "plasticity", &e->plasticity, [](MapReader& c, PlasticityEffect& p) {
    c.Read("yield_strain", &p.yield_strain);
    c.Read("flow_rate_per_s", &p.flow_rate_per_s);
  });
  ReadEffect(r, "uneven_stiffness", &e->uneven_stiffness, [](MapReader& c, UnevenStiffnessEffect& u) {
    c.Read("gradient", &u.gradient);
    c.Read("direction", &u.direction);
    if (!c.Has("regions")) return;
    const YAML::Node list = c.Get("regions");
    const std::string path = c.KeyPath("regions");
    if (!list.IsSequence()) c.Fail(path, list, "expected a list of regions");
    for (size_t i = 0; i < list.size(); ++i) {
      MapReader rr = c.Nested(list[i], fmt::format("{}[{}]", path, i));
      StiffnessRegionSpec region;
      rr.Read("centre_fraction", &region.centre_fraction);
      rr.Read("radius_mm", &region.radius_mm);
      rr.Read("factor", &region.factor);
      rr.Finish();
      u.regions.push_back(region);
    }
  });
  ReadEffect(r, "strain_stiffening", &e->strain_stiffening,
             [](MapReader& c, StrainStiffeningEffect& s) { c.Read("coefficient", &s.coefficient); });
  ReadEffect(r, "viscoelastic", &e->viscoelastic, [](MapReader& c, ViscoelasticEffect& v) {
    c.Read("fraction", &v.fraction);
    c.Read("relaxation_time_s", &v.relaxation_time_s);
  });
  ReadEffect(r, "strong_friction", &e->strong_friction,
             [](MapReader& c, StrongFrictionEffect& f) { c.Read("coefficient", &f.coefficient); });
  ReadEffect(r, "inertia_gravity", &e->inertia_gravity,
             [](MapReader& c, InertiaGravityEffect& g) { c.Read("gravity_m_s2", &g.gravity_m_s2); });
  r.Finish();
}

void ReadCamera(MapReader r, CameraSpec* c) {
  r.Read("width_px", &c->width_px);
  r.Read("height_px", &c->height_px);
  r.Read("object_rgb", &c->object_rgb);
  r.Read("background_rgb", &c->background_rgb);
  r.Read("finger_rgb", &c->finger_rgb);
  r.Read("pencil_rgb", &c->pencil_rgb);
  r.Read("lighting_gradient", &c->lighting_gradient);
  r.Read("lighting_angle_deg", &c->lighting_angle_deg);
  r.Read("noise_sigma", &c->noise_sigma);
  r.Read("blur_sigma_px", &c->blur_sigma_px);
  r.Read("finger_opacity", &c->finger_opacity);
  r.Read("texture_contrast", &c->texture_contrast);
  r.Read("pore_size_px", &c->pore_size_px);
  r.Read("video_crf", &c->video_crf);
  r.Finish();
}

void ReadTop(MapReader& r, Scenario* s) {
  r.Read("name", &s->name);
  r.Read("mm_per_px", &s->mm_per_px);
  r.Read("fps", &s->fps);
  r.Read("frames", &s->frames);
  r.Read("seed", &s->seed);
  r.Read("notes", &s->notes);
  if (r.Has("object")) ReadObject(r.Child("object"), &s->object);
  if (r.Has("push")) {
    if (s->kind != ScenarioKind::kPush) r.Fail(r.KeyPath("push"), r.Get("push"), "no push section for kind hang");
    ReadPush(r.Child("push"), &s->push);
  }
  if (r.Has("hang")) {
    if (s->kind != ScenarioKind::kHang) r.Fail(r.KeyPath("hang"), r.Get("hang"), "no hang section for kind push");
    ReadHang(r.Child("hang"), &s->hang);
  }
  if (r.Has("material")) {
    MapReader m = r.Child("material");
    ReadEnum(m, "law", &s->material.law, &MaterialLawFromString);
    m.Read("youngs_modulus_pa", &s->material.youngs_modulus_pa);
    m.Read("poisson_ratio", &s->material.poisson_ratio);
    m.Read("thickness_mm", &s->material.thickness_mm);
    m.Read("density_kg_m3", &s->material.density_kg_m3);
    m.Finish();
  }
  if (r.Has("environment")) {
    MapReader m = r.Child("environment");
    m.Read("friction_coefficient", &s->environment.friction_coefficient);
    m.Read("friction_regularisation_mm_s", &s->environment.friction_regularisation_mm_s);
    m.Finish();
  }
  if (r.Has("effects")) ReadEffects(r.OptionalChild("effects"), &s->effects);
  if (r.Has("camera")) ReadCamera(r.Child("camera"), &s->camera);
  if (r.Has("sensor")) {
    MapReader m = r.Child("sensor");
    m.Read("noise_n", &s->sensor.noise_n);
    m.Read("bias_n", &s->sensor.bias_n);
    m.Finish();
  }
  if (r.Has("simulation")) {
    MapReader m = r.Child("simulation");
    m.Read("fine_edge_px", &s->simulation.fine_edge_px);
    m.Read("substeps", &s->simulation.substeps);
    m.Read("max_newton_iterations", &s->simulation.max_newton_iterations);
    m.Finish();
  }
  r.Finish();
}

// ---------------------------------------------------------------- validation

// Collects the first violated rule as "key = value. Violated: rule."
class Checker {
 public:
  template <class T>
  void Require(bool ok, const std::string& key, const T& value, const std::string& rule) {
    if (ok || !message_.empty()) return;
    message_ = fmt::format("{} = {}. Violated: {}.", key, value, rule);
  }
  void RequireFinite(double v, const std::string& key) { Require(std::isfinite(v), key, v, key + " is finite"); }
  void Positive(double v, const std::string& key) {
    Require(std::isfinite(v) && v > 0.0, key, v, key + " > 0");
  }
  void NonNegative(double v, const std::string& key) {
    Require(std::isfinite(v) && v >= 0.0, key, v, key + " >= 0");
  }
  void InRange(double v, double lo, double hi, const std::string& key) {
    Require(std::isfinite(v) && v >= lo && v <= hi, key, v, fmt::format("{} <= {} <= {}", lo, key, hi));
  }
  void Vector(const Vec2& v, const std::string& key) {
    Require(v.allFinite(), key, fmt::format("[{}, {}]", v.x(), v.y()), key + " is finite");
  }
  void Colour(const std::array<int, 3>& c, const std::string& key) {
    Require(std::all_of(c.begin(), c.end(), [](int x) { return x >= 0 && x <= 255; }), key,
            fmt::format("[{}, {}, {}]", c[0], c[1], c[2]), "every channel in 0..255");
  }
  bool ok() const { return message_.empty(); }
  const std::string& message() const { return message_; }

 private:
  std::string message_;
};

// The shape's own keys: the ones of object.shape only, each in range.
void CheckShape(const Scenario& s, Checker& c) {
  const ObjectSpec& o = s.object;
  const double smaller = std::min(o.width_mm, o.height_mm);
  const std::string shape = ToString(o.shape);
  if (o.shape == ObjectShape::kWaist) {
    c.Require(std::isfinite(o.waist_mm) && o.waist_mm > 0.0 && o.waist_mm < 0.35 * smaller,
              "object.waist_mm", o.waist_mm,
              "0 < object.waist_mm < 0.35 * min(object.width_mm, object.height_mm) for shape waist");
  } else {
    c.Require(o.waist_mm == 0.0, "object.waist_mm", o.waist_mm,
              "object.waist_mm is 0 unless object.shape is waist (object.shape is " + shape + ")");
  }
  if (o.corner_radius_mm) {
    c.Require(o.shape == ObjectShape::kRounded, "object.corner_radius_mm", *o.corner_radius_mm,
              "only shape rounded has a corner radius (object.shape is " + shape + ")");
    c.Require(std::isfinite(*o.corner_radius_mm) && *o.corner_radius_mm > 0.0 &&
                  *o.corner_radius_mm <= 0.45 * smaller,
              "object.corner_radius_mm", *o.corner_radius_mm,
              "0 < object.corner_radius_mm <= 0.45 * min(object.width_mm, object.height_mm)");
  }
  // At least 2 px: a notch or cutout the fine mesh can resolve.
  const auto at_least_2px = [&](double mm, const std::string& key) {
    c.Require(std::isfinite(mm) && mm / s.mm_per_px >= 2.0, key, mm, key + " / mm_per_px >= 2 (2 px)");
  };
  if (o.notch) {
    const NotchSpec& n = *o.notch;
    c.Require(o.shape == ObjectShape::kNotched, "object.notch", ToString(n.side),
              "only shape notched has a notch (object.shape is " + shape + ")");
    const bool across = n.side == ObjectSide::kNear || n.side == ObjectSide::kFar;
    const double length = across ? o.width_mm : o.height_mm;
    const double thickness = across ? o.height_mm : o.width_mm;
    c.InRange(n.position_fraction, 0.0, 1.0, "object.notch.position_fraction");
    c.Positive(n.width_mm, "object.notch.width_mm");
    c.Positive(n.depth_mm, "object.notch.depth_mm");
    at_least_2px(n.width_mm, "object.notch.width_mm");
    at_least_2px(n.depth_mm, "object.notch.depth_mm");
    c.Require(n.position_fraction * length > 0.5 * n.width_mm &&
                  n.position_fraction * length < length - 0.5 * n.width_mm,
              "object.notch.position_fraction", n.position_fraction,
              "the notch lies inside its side: object.notch.width_mm / 2 < position_fraction * "
              "side length < side length - width_mm / 2");
    c.Require(n.depth_mm < 0.5 * thickness, "object.notch.depth_mm", n.depth_mm,
              "object.notch.depth_mm < half the object's size across the notched side");
  }
  if (o.cutout) {
    const CutoutSpec& k = *o.cutout;
    c.Require(o.shape == ObjectShape::kLShape, "object.cutout", ToString(k.corner),
              "only shape l_shape has a cutout (object.shape is " + shape + ")");
    c.Require(std::isfinite(k.width_mm) && k.width_mm > 0.0 && k.width_mm <= 0.8 * o.width_mm,
              "object.cutout.width_mm", k.width_mm, "0 < object.cutout.width_mm <= 0.8 * object.width_mm");
    c.Require(std::isfinite(k.height_mm) && k.height_mm > 0.0 && k.height_mm <= 0.8 * o.height_mm,
              "object.cutout.height_mm", k.height_mm,
              "0 < object.cutout.height_mm <= 0.8 * object.height_mm");
    at_least_2px(k.width_mm, "object.cutout.width_mm");
    at_least_2px(k.height_mm, "object.cutout.height_mm");
  }
  c.InRange(o.rotation_deg, -180.0, 180.0, "object.rotation_deg");
  if (s.kind == ScenarioKind::kHang) {
    c.Require(o.rotation_deg == 0.0, "object.rotation_deg", o.rotation_deg,
              "object.rotation_deg is 0 for kind hang (the clamp holds the top edge)");
  }
}

// The scene in the image: the (turned) object with 2 px to spare, the finger
// and pencil discs inside the image and touching the outline, the push no
// deeper than half the object under the finger.
void CheckFit(const Scenario& s, Checker& c) {
  const RectPx r = ObjectRectPx(s);
  c.Require(r.width >= 12.0 && r.height >= 12.0, "object.width_mm", s.object.width_mm,
            "the object spans at least 12 px each way (width_mm, height_mm / mm_per_px)");
  c.Require(r.x >= 2.0 && r.x + r.width <= s.camera.width_px - 2.0, "object.width_mm",
            s.object.width_mm, "the object fits in camera.width_px with 2 px to spare");
  c.Require(r.y >= 2.0 && r.y + r.height <= s.camera.height_px - 2.0, "object.height_mm",
            s.object.height_mm, "the object fits in camera.height_px with 2 px to spare");
  if (!c.ok()) return;
  if (s.object.rotation_deg != 0.0) {
    bool inside = true;
    for (const Vec2& p : RestPolygonPx(s)) {
      inside = inside && p.x() >= 2.0 && p.x() <= s.camera.width_px - 2.0 && p.y() >= 2.0 &&
               p.y() <= s.camera.height_px - 2.0;
    }
    c.Require(inside, "object.rotation_deg", s.object.rotation_deg,
              "the turned object fits in the image with 2 px to spare");
  }
  if (s.kind != ScenarioKind::kPush || !c.ok()) return;
  const PushSpec& p = s.push;
  const std::vector<Vec2> outline = outline_detail::UnturnedOutlinePx(s);
  const double finger_x =
      r.x + (p.position_mm ? *p.position_mm / s.mm_per_px : p.position_fraction * r.width);
  const double finger_r = p.finger_radius_mm / s.mm_per_px;
  const double contact = outline_detail::FirstTouchFromAbove(outline, finger_x, finger_r);
  c.Require(std::isfinite(contact), "push.position_fraction", p.position_fraction,
            "the finger meets the object");
  if (s.object.shape != ObjectShape::kRectangle && s.object.shape != ObjectShape::kWaist) {
    const double far = outline_detail::FirstTouchFromBelow(outline, finger_x, 0.0);
    c.Require(p.depth_mm / s.mm_per_px < 0.5 * (far - (contact + finger_r)), "push.depth_mm", p.depth_mm,
              "push.depth_mm < half the object's thickness under the finger");
  }
  const double pencil_x = r.x + p.pencil_position_fraction * r.width;
  c.Require(std::isfinite(outline_detail::FirstTouchFromBelow(outline, pencil_x,
                                                              p.pencil_radius_mm / s.mm_per_px)),
            "push.pencil_position_fraction", p.pencil_position_fraction, "the pencil meets the object");
  if (!c.ok()) return;
  const auto tracks = ObstacleTracksPx(s);
  const auto inside_image = [&](const Disc& d) {
    return d.centre.x() - d.radius_px >= 0.0 && d.centre.x() + d.radius_px <= s.camera.width_px &&
           d.centre.y() - d.radius_px >= 0.0 && d.centre.y() + d.radius_px <= s.camera.height_px;
  };
  c.Require(inside_image(tracks.front()[0]), "push.start_gap_mm", p.start_gap_mm,
            "the finger starts inside the image (its disc, gap + 2 radius beyond the near side)");
  c.Require(inside_image(tracks.front()[1]), "push.pencil_gap_mm", p.pencil_gap_mm,
            "the pencil lies inside the image");
}

}  // namespace

bool Scenario::IsValid(std::string* error) const {
  Checker c;
  c.Require(!name.empty() && std::all_of(name.begin(), name.end(),
                                         [](char ch) {
                                           return std::isalnum(static_cast<unsigned char>(ch)) ||
                                                  ch == '_' || ch == '-' || ch == '.';
                                         }),
            "name", "'" + name + "'", "name is non-empty and uses only letters, digits, _ - .");
  c.Positive(mm_per_px, "mm_per_px");
  c.InRange(fps, 1.0, 10000.0, "fps");
  c.Require(frames >= 2 && frames <= 100000, "frames", frames, "2 <= frames <= 100000");
  c.Positive(object.width_mm, "object.width_mm");
  c.Positive(object.height_mm, "object.height_mm");
  CheckShape(*this, c);
  if (kind == ScenarioKind::kPush) {
    c.Positive(push.finger_radius_mm, "push.finger_radius_mm");
    c.InRange(push.position_fraction, 0.0, 1.0, "push.position_fraction");
    if (push.position_mm) c.InRange(*push.position_mm, 0.0, object.width_mm, "push.position_mm");
    c.Require(std::isfinite(push.depth_mm) && push.depth_mm > 0.0 &&
                  push.depth_mm < 0.5 * object.height_mm,
              "push.depth_mm", push.depth_mm, "0 < push.depth_mm < object.height_mm / 2");
    c.NonNegative(push.start_gap_mm, "push.start_gap_mm");
    c.NonNegative(push.delay_s, "push.delay_s");
    c.Positive(push.approach_s, "push.approach_s");
    c.NonNegative(push.hold_s, "push.hold_s");
    c.Positive(push.retract_s, "push.retract_s");
    c.Positive(push.pencil_radius_mm, "push.pencil_radius_mm");
    c.InRange(push.pencil_position_fraction, 0.0, 1.0, "push.pencil_position_fraction");
    c.NonNegative(push.pencil_gap_mm, "push.pencil_gap_mm");
  } else {
    c.Positive(hang.top_margin_mm, "hang.top_margin_mm");
    c.Require(std::isfinite(hang.clamp_depth_mm) && hang.clamp_depth_mm > 0.0 &&
                  hang.clamp_depth_mm < 0.5 * object.height_mm,
              "hang.clamp_depth_mm", hang.clamp_depth_mm,
              "0 < hang.clamp_depth_mm < object.height_mm / 2");
    c.Vector(hang.initial_bend_m_s2, "hang.initial_bend_m_s2");
    c.Require(effects.inertia_gravity.has_value(), "effects.inertia_gravity", "absent",
              "effects.inertia_gravity is on for kind hang");
  }
  c.Positive(material.youngs_modulus_pa, "material.youngs_modulus_pa");
  c.Require(std::isfinite(material.poisson_ratio) && material.poisson_ratio >= 0.0 &&
                material.poisson_ratio < 0.5,
            "material.poisson_ratio", material.poisson_ratio, "0 <= material.poisson_ratio < 0.5");
  c.Positive(material.thickness_mm, "material.thickness_mm");
  c.Positive(material.density_kg_m3, "material.density_kg_m3");
  c.NonNegative(environment.friction_coefficient, "environment.friction_coefficient");
  c.Positive(environment.friction_regularisation_mm_s, "environment.friction_regularisation_mm_s");
  if (effects.plasticity) {
    c.Positive(effects.plasticity->yield_strain, "effects.plasticity.yield_strain");
    c.Positive(effects.plasticity->flow_rate_per_s, "effects.plasticity.flow_rate_per_s");
  }
  if (const auto& u = effects.uneven_stiffness) {
    c.Require(std::isfinite(u->gradient) && u->gradient >= 0.0 && u->gradient < 1.0,
              "effects.uneven_stiffness.gradient", u->gradient,
              "0 <= effects.uneven_stiffness.gradient < 1");
    c.Require(u->direction.allFinite() && u->direction.norm() > 1e-9,
              "effects.uneven_stiffness.direction",
              fmt::format("[{}, {}]", u->direction.x(), u->direction.y()),
              "effects.uneven_stiffness.direction is finite and non-zero");
    c.Require(u->gradient > 0.0 || !u->regions.empty(), "effects.uneven_stiffness.gradient",
              u->gradient, "a gradient > 0 or at least one region");
    for (size_t i = 0; i < u->regions.size(); ++i) {
      const std::string key = fmt::format("effects.uneven_stiffness.regions[{}]", i);
      const auto& region = u->regions[i];
      c.InRange(region.centre_fraction.x(), 0.0, 1.0, key + ".centre_fraction[0]");
      c.InRange(region.centre_fraction.y(), 0.0, 1.0, key + ".centre_fraction[1]");
      c.Positive(region.radius_mm, key + ".radius_mm");
      c.Positive(region.factor, key + ".factor");
    }
  }
  if (effects.strain_stiffening) {
    c.Positive(effects.strain_stiffening->coefficient, "effects.strain_stiffening.coefficient");
  }
  if (effects.viscoelastic) {
    c.Require(std::isfinite(effects.viscoelastic->fraction) && effects.viscoelastic->fraction > 0.0 &&
                  effects.viscoelastic->fraction < 1.0,
              "effects.viscoelastic.fraction", effects.viscoelastic->fraction,
              "0 < effects.viscoelastic.fraction < 1");
    c.Positive(effects.viscoelastic->relaxation_time_s, "effects.viscoelastic.relaxation_time_s");
  }
  if (effects.strong_friction) {
    c.Positive(effects.strong_friction->coefficient, "effects.strong_friction.coefficient");
  }
  if (effects.inertia_gravity) c.Vector(effects.inertia_gravity->gravity_m_s2, "effects.inertia_gravity.gravity_m_s2");
  c.Require(camera.width_px >= 64 && camera.width_px <= 4096 && camera.width_px % 2 == 0,
            "camera.width_px", camera.width_px, "camera.width_px even, in 64..4096");
  c.Require(camera.height_px >= 64 && camera.height_px <= 4096 && camera.height_px % 2 == 0,
            "camera.height_px", camera.height_px, "camera.height_px even, in 64..4096");
  c.Colour(camera.object_rgb, "camera.object_rgb");
  c.Colour(camera.background_rgb, "camera.background_rgb");
  c.Colour(camera.finger_rgb, "camera.finger_rgb");
  c.Colour(camera.pencil_rgb, "camera.pencil_rgb");
  c.InRange(camera.lighting_gradient, 0.0, 0.5, "camera.lighting_gradient");
  c.RequireFinite(camera.lighting_angle_deg, "camera.lighting_angle_deg");
  c.InRange(camera.noise_sigma, 0.0, 30.0, "camera.noise_sigma");
  c.InRange(camera.blur_sigma_px, 0.0, 5.0, "camera.blur_sigma_px");
  c.Require(std::isfinite(camera.finger_opacity) && camera.finger_opacity > 0.0 &&
                camera.finger_opacity <= 1.0,
            "camera.finger_opacity", camera.finger_opacity, "0 < camera.finger_opacity <= 1");
  c.InRange(camera.texture_contrast, 0.0, 0.6, "camera.texture_contrast");
  c.InRange(camera.pore_size_px, 0.5, 20.0, "camera.pore_size_px");
  c.Require(camera.video_crf >= 0 && camera.video_crf <= 51, "camera.video_crf", camera.video_crf,
            "0 <= camera.video_crf <= 51");
  c.NonNegative(sensor.noise_n, "sensor.noise_n");
  c.Vector(sensor.bias_n, "sensor.bias_n");
  c.Require(std::isfinite(simulation.fine_edge_px) && simulation.fine_edge_px >= 1.0 &&
                simulation.fine_edge_px <= 20.0,
            "simulation.fine_edge_px", simulation.fine_edge_px, "1 <= simulation.fine_edge_px <= 20");
  c.Require(simulation.substeps >= 1 && simulation.substeps <= 1000, "simulation.substeps",
            simulation.substeps, "1 <= simulation.substeps <= 1000");
  c.Require(simulation.max_newton_iterations >= 1, "simulation.max_newton_iterations",
            simulation.max_newton_iterations, "simulation.max_newton_iterations >= 1");

  if (c.ok()) CheckFit(*this, c);  // does the scene fit in the image?
  if (!c.ok() && error) *error = c.message();
  return c.ok();
}

Scenario ParseScenario(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw ScenarioError(fmt::format("{}: not valid YAML: {}", source, e.what()));
  }
  if (root.IsNull()) throw ScenarioError(fmt::format("{}: empty scenario file", source));
  MapReader top(root, "", &source, &RaiseScenarioError, yaml_reader::EmptyValue::kPresent);
  ScenarioKind kind = ScenarioKind::kPush;
  if (top.Has("kind")) {
    const YAML::Node n = top.Get("kind");
    try {
      if (!n.IsScalar()) throw std::invalid_argument("");
      kind = ScenarioKindFromString(n.Scalar());
    } catch (const std::invalid_argument&) {
      top.Fail("kind", n, "must be push or hang");
    }
  }
  Scenario s = DefaultScenario(kind);
  ReadTop(top, &s);
  std::string error;
  if (!s.IsValid(&error)) throw ScenarioError(fmt::format("{}: {}", source, error));
  return s;
}

Scenario LoadScenario(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw ScenarioError(fmt::format("{}: cannot open scenario file", path.string()));
  std::stringstream text;
  text << in.rdbuf();
  return ParseScenario(text.str(), path.string());
}

}  // namespace calib::synth
