// A scenario's scene in pixels (outline, obstacle tracks, clamps) and the
// truth model's material and environment.

#include "calib/synth/scenario.h"

#include "object_outline.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace calib::synth {

RectPx ObjectRectPx(const Scenario& s) {
  const double w = std::round(s.object.width_mm / s.mm_per_px);
  const double h = std::round(s.object.height_mm / s.mm_per_px);
  const double x = std::floor((s.camera.width_px - w) / 2.0);
  const double y = s.kind == ScenarioKind::kPush ? std::floor((s.camera.height_px - h) / 2.0)
                                                 : std::round(s.hang.top_margin_mm / s.mm_per_px);
  return RectPx{x, y, w, h};
}

std::vector<Vec2> RestPolygonPx(const Scenario& s) {
  std::vector<Vec2> polygon = outline_detail::UnturnedOutlinePx(s);
  for (Vec2& p : polygon) p = outline_detail::TurnPx(s, p);
  return polygon;
}

namespace {

// 0 before `start`, a cosine ramp to 1 over `duration`, 1 after.
double Ramp(double t, double start, double duration) {
  const double u = std::clamp((t - start) / duration, 0.0, 1.0);
  return 0.5 - 0.5 * std::cos(std::numbers::pi * u);
}

}  // namespace

std::vector<std::vector<Disc>> ObstacleTracksPx(const Scenario& s) {
  std::vector<std::vector<Disc>> tracks(s.frames);
  if (s.kind != ScenarioKind::kPush) return tracks;
  const PushSpec& p = s.push;
  const RectPx r = ObjectRectPx(s);
  const double finger_r = p.finger_radius_mm / s.mm_per_px;
  const double pencil_r = p.pencil_radius_mm / s.mm_per_px;
  const double finger_x =
      r.x + (p.position_mm ? *p.position_mm / s.mm_per_px : p.position_fraction * r.width);
  // In the object's own frame the finger moves down onto the outline and the
  // pencil stands below it; both then turn with the object.
  const std::vector<Vec2> outline = outline_detail::UnturnedOutlinePx(s);
  const double contact = outline_detail::FirstTouchFromAbove(outline, finger_x, finger_r);
  const double y_start = contact - p.start_gap_mm / s.mm_per_px;
  const double y_deep = contact + p.depth_mm / s.mm_per_px;
  const double retract_start = p.delay_s + p.approach_s + p.hold_s;
  const double pencil_x = r.x + p.pencil_position_fraction * r.width;
  const Disc pencil{outline_detail::TurnPx(
                        s, Vec2(pencil_x, outline_detail::FirstTouchFromBelow(outline, pencil_x, pencil_r) +
                                              p.pencil_gap_mm / s.mm_per_px)),
                    pencil_r};
  for (int f = 0; f < s.frames; ++f) {
    const double t = f / s.fps;
    const double in = Ramp(t, p.delay_s, p.approach_s) - Ramp(t, retract_start, p.retract_s);
    tracks[f] = {
        Disc{outline_detail::TurnPx(s, Vec2(finger_x, y_start + in * (y_deep - y_start))), finger_r},
        pencil};
  }
  return tracks;
}

std::vector<std::string> ObstacleNames(const Scenario& s) {
  if (s.kind == ScenarioKind::kPush) return {"finger", "pencil"};
  return {};
}

std::vector<RectPx> ClampRectsPx(const Scenario& s) {
  if (s.kind != ScenarioKind::kHang) return {};
  const RectPx r = ObjectRectPx(s);
  const double depth = std::round(s.hang.clamp_depth_mm / s.mm_per_px);
  return {RectPx{r.x - 2.0, r.y - 2.0, r.width + 4.0, depth + 2.0}};
}

TruthMaterial ToTruthMaterial(const Scenario& s) {
  TruthMaterial m;
  m.law = s.material.law;
  m.youngs_modulus_pa = s.material.youngs_modulus_pa;
  m.poisson_ratio = s.material.poisson_ratio;
  m.thickness_m = s.material.thickness_mm * 1e-3;
  m.density_kg_m3 = s.material.density_kg_m3;
  const Effects& e = s.effects;
  if (e.uneven_stiffness) {
    m.stiffness_gradient = e.uneven_stiffness->gradient;
    // Both turn with the object: they describe its material.
    m.stiffness_gradient_direction =
        outline_detail::TurnDirection(s, e.uneven_stiffness->direction.normalized());
    const RectPx r = ObjectRectPx(s);
    for (const auto& region : e.uneven_stiffness->regions) {
      m.stiffness_regions.push_back(StiffnessRegion{
          outline_detail::TurnPx(s, Vec2(r.x + region.centre_fraction.x() * r.width,
                                         r.y + region.centre_fraction.y() * r.height)),
          region.radius_mm / s.mm_per_px, region.factor});
    }
  }
  if (e.strain_stiffening) m.stiffening_coefficient = e.strain_stiffening->coefficient;
  if (e.plasticity) {
    m.plastic_yield_strain = e.plasticity->yield_strain;
    m.plastic_flow_rate_per_s = e.plasticity->flow_rate_per_s;
  }
  if (e.viscoelastic) {
    m.viscous_fraction = e.viscoelastic->fraction;
    m.viscous_relaxation_time_s = e.viscoelastic->relaxation_time_s;
  }
  return m;
}

TruthEnvironment ToTruthEnvironment(const Scenario& s) {
  TruthEnvironment env;
  env.friction_coefficient = s.effects.strong_friction ? s.effects.strong_friction->coefficient
                                                       : s.environment.friction_coefficient;
  env.friction_regularisation_m_s = s.environment.friction_regularisation_mm_s * 1e-3;
  if (s.effects.inertia_gravity) {
    env.inertia = true;
    env.gravity_m_s2 = s.effects.inertia_gravity->gravity_m_s2;
  }
  if (s.kind == ScenarioKind::kHang) env.initial_bend_m_s2 = s.hang.initial_bend_m_s2;
  return env;
}

}  // namespace calib::synth
