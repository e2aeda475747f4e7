// A scenario's scene in pixels (outline, obstacle tracks, clamps) and the
// truth model's material and environment.

#include "calib/synth/scenario.h"

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
  const RectPx r = ObjectRectPx(s);
  const double x0 = r.x, y0 = r.y, x1 = r.x + r.width, y1 = r.y + r.height;
  const double d = std::round(s.object.waist_mm / s.mm_per_px);
  if (d <= 0.0) return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  const double ya = y0 + 0.35 * r.height, yb = y0 + 0.45 * r.height;
  const double yc = y0 + 0.55 * r.height, yd = y0 + 0.65 * r.height;
  return {{x0, y0},     {x1, y0}, {x1, ya}, {x1 - d, yb}, {x1 - d, yc}, {x1, yd},
          {x1, y1},     {x0, y1}, {x0, yd}, {x0 + d, yc}, {x0 + d, yb}, {x0, ya}};
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
  const double y_start = r.y - finger_r - p.start_gap_mm / s.mm_per_px;
  const double y_deep = r.y - finger_r + p.depth_mm / s.mm_per_px;
  const double retract_start = p.delay_s + p.approach_s + p.hold_s;
  const Disc pencil{Vec2(r.x + p.pencil_position_fraction * r.width,
                         r.y + r.height + pencil_r + p.pencil_gap_mm / s.mm_per_px),
                    pencil_r};
  for (int f = 0; f < s.frames; ++f) {
    const double t = f / s.fps;
    const double in = Ramp(t, p.delay_s, p.approach_s) - Ramp(t, retract_start, p.retract_s);
    tracks[f] = {Disc{Vec2(finger_x, y_start + in * (y_deep - y_start)), finger_r}, pencil};
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
  m.youngs_modulus_pa = s.material.youngs_modulus_pa;
  m.poisson_ratio = s.material.poisson_ratio;
  m.thickness_m = s.material.thickness_mm * 1e-3;
  m.density_kg_m3 = s.material.density_kg_m3;
  const Effects& e = s.effects;
  if (e.uneven_stiffness) {
    m.stiffness_gradient = e.uneven_stiffness->gradient;
    m.stiffness_gradient_direction = e.uneven_stiffness->direction.normalized();
    const RectPx r = ObjectRectPx(s);
    for (const auto& region : e.uneven_stiffness->regions) {
      m.stiffness_regions.push_back(StiffnessRegion{
          Vec2(r.x + region.centre_fraction.x() * r.width, r.y + region.centre_fraction.y() * r.height),
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
