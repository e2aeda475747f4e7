// ScenarioToYaml: a scenario as a YAML file that ParseScenario reads back.

#include "calib/synth/scenario.h"

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

namespace calib::synth {

namespace {

std::string Num(double v) { return fmt::format("{}", v); }

void EmitVec(YAML::Emitter& out, const char* key, const Vec2& v) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq << Num(v.x()) << Num(v.y())
      << YAML::EndSeq;
}
void EmitRgb(YAML::Emitter& out, const char* key, const std::array<int, 3>& c) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq << c[0] << c[1] << c[2]
      << YAML::EndSeq;
}
void EmitNum(YAML::Emitter& out, const char* key, double v) {
  out << YAML::Key << key << YAML::Value << Num(v);
}

}  // namespace

std::string ScenarioToYaml(const Scenario& s) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << s.name;
  out << YAML::Key << "kind" << YAML::Value << ToString(s.kind);
  EmitNum(out, "mm_per_px", s.mm_per_px);
  EmitNum(out, "fps", s.fps);
  out << YAML::Key << "frames" << YAML::Value << s.frames;
  out << YAML::Key << "seed" << YAML::Value << s.seed;
  out << YAML::Key << "notes" << YAML::Value << YAML::DoubleQuoted << s.notes;
  out << YAML::Key << "object" << YAML::Value << YAML::BeginMap;
  const ObjectSpec& o = s.object;
  out << YAML::Key << "shape" << YAML::Value << ToString(o.shape);
  EmitNum(out, "width_mm", o.width_mm);
  EmitNum(out, "height_mm", o.height_mm);
  EmitNum(out, "waist_mm", o.waist_mm);
  if (o.corner_radius_mm) EmitNum(out, "corner_radius_mm", *o.corner_radius_mm);
  if (o.notch) {
    out << YAML::Key << "notch" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "side" << YAML::Value << ToString(o.notch->side);
    EmitNum(out, "position_fraction", o.notch->position_fraction);
    EmitNum(out, "width_mm", o.notch->width_mm);
    EmitNum(out, "depth_mm", o.notch->depth_mm);
    out << YAML::EndMap;
  }
  if (o.cutout) {
    out << YAML::Key << "cutout" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "corner" << YAML::Value << ToString(o.cutout->corner);
    EmitNum(out, "width_mm", o.cutout->width_mm);
    EmitNum(out, "height_mm", o.cutout->height_mm);
    out << YAML::EndMap;
  }
  EmitNum(out, "rotation_deg", o.rotation_deg);
  out << YAML::EndMap;
  if (s.kind == ScenarioKind::kPush) {
    const PushSpec& p = s.push;
    out << YAML::Key << "push" << YAML::Value << YAML::BeginMap;
    EmitNum(out, "finger_radius_mm", p.finger_radius_mm);
    EmitNum(out, "position_fraction", p.position_fraction);
    if (p.position_mm) EmitNum(out, "position_mm", *p.position_mm);
    EmitNum(out, "depth_mm", p.depth_mm);
    EmitNum(out, "start_gap_mm", p.start_gap_mm);
    EmitNum(out, "delay_s", p.delay_s);
    EmitNum(out, "approach_s", p.approach_s);
    EmitNum(out, "hold_s", p.hold_s);
    EmitNum(out, "retract_s", p.retract_s);
    EmitNum(out, "pencil_radius_mm", p.pencil_radius_mm);
    EmitNum(out, "pencil_position_fraction", p.pencil_position_fraction);
    EmitNum(out, "pencil_gap_mm", p.pencil_gap_mm);
    out << YAML::EndMap;
  } else {
    out << YAML::Key << "hang" << YAML::Value << YAML::BeginMap;
    EmitNum(out, "top_margin_mm", s.hang.top_margin_mm);
    EmitNum(out, "clamp_depth_mm", s.hang.clamp_depth_mm);
    EmitVec(out, "initial_bend_m_s2", s.hang.initial_bend_m_s2);
    out << YAML::EndMap;
  }
  out << YAML::Key << "material" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "law" << YAML::Value << ToString(s.material.law);
  EmitNum(out, "youngs_modulus_pa", s.material.youngs_modulus_pa);
  EmitNum(out, "poisson_ratio", s.material.poisson_ratio);
  EmitNum(out, "thickness_mm", s.material.thickness_mm);
  EmitNum(out, "density_kg_m3", s.material.density_kg_m3);
  out << YAML::EndMap;
  out << YAML::Key << "environment" << YAML::Value << YAML::BeginMap;
  EmitNum(out, "friction_coefficient", s.environment.friction_coefficient);
  EmitNum(out, "friction_regularisation_mm_s", s.environment.friction_regularisation_mm_s);
  out << YAML::EndMap;
  const Effects& e = s.effects;
  out << YAML::Key << "effects" << YAML::Value << YAML::BeginMap;
  if (e.plasticity) {
    out << YAML::Key << "plasticity" << YAML::Value << YAML::BeginMap;
    EmitNum(out, "yield_strain", e.plasticity->yield_strain);
    EmitNum(out, "flow_rate_per_s", e.plasticity->flow_rate_per_s);
    out << YAML::EndMap;
  }
  if (e.uneven_stiffness) {
    out << YAML::Key << "uneven_stiffness" << YAML::Value << YAML::BeginMap;
    EmitNum(out, "gradient", e.uneven_stiffness->gradient);
    EmitVec(out, "direction", e.uneven_stiffness->direction);
    out << YAML::Key << "regions" << YAML::Value << YAML::BeginSeq;
    for (const auto& region : e.uneven_stiffness->regions) {
      out << YAML::BeginMap;
      EmitVec(out, "centre_fraction", region.centre_fraction);
      EmitNum(out, "radius_mm", region.radius_mm);
      EmitNum(out, "factor", region.factor);
      out << YAML::EndMap;
    }
    out << YAML::EndSeq << YAML::EndMap;
  }
  if (e.strain_stiffening) {
    out << YAML::Key << "strain_stiffening" << YAML::Value << YAML::BeginMap;
    EmitNum(out, "coefficient", e.strain_stiffening->coefficient);
    out << YAML::EndMap;
  }
  if (e.viscoelastic) {
    out << YAML::Key << "viscoelastic" << YAML::Value << YAML::BeginMap;
    EmitNum(out, "fraction", e.viscoelastic->fraction);
    EmitNum(out, "relaxation_time_s", e.viscoelastic->relaxation_time_s);
    out << YAML::EndMap;
  }
  if (e.strong_friction) {
    out << YAML::Key << "strong_friction" << YAML::Value << YAML::BeginMap;
    EmitNum(out, "coefficient", e.strong_friction->coefficient);
    out << YAML::EndMap;
  }
  if (e.inertia_gravity) {
    out << YAML::Key << "inertia_gravity" << YAML::Value << YAML::BeginMap;
    EmitVec(out, "gravity_m_s2", e.inertia_gravity->gravity_m_s2);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  const CameraSpec& c = s.camera;
  out << YAML::Key << "camera" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "width_px" << YAML::Value << c.width_px;
  out << YAML::Key << "height_px" << YAML::Value << c.height_px;
  EmitRgb(out, "object_rgb", c.object_rgb);
  EmitRgb(out, "background_rgb", c.background_rgb);
  EmitRgb(out, "finger_rgb", c.finger_rgb);
  EmitRgb(out, "pencil_rgb", c.pencil_rgb);
  EmitNum(out, "lighting_gradient", c.lighting_gradient);
  EmitNum(out, "lighting_angle_deg", c.lighting_angle_deg);
  EmitNum(out, "noise_sigma", c.noise_sigma);
  EmitNum(out, "blur_sigma_px", c.blur_sigma_px);
  EmitNum(out, "finger_opacity", c.finger_opacity);
  EmitNum(out, "texture_contrast", c.texture_contrast);
  EmitNum(out, "pore_size_px", c.pore_size_px);
  out << YAML::Key << "video_crf" << YAML::Value << c.video_crf;
  out << YAML::EndMap;
  out << YAML::Key << "sensor" << YAML::Value << YAML::BeginMap;
  EmitNum(out, "noise_n", s.sensor.noise_n);
  EmitVec(out, "bias_n", s.sensor.bias_n);
  out << YAML::EndMap;
  out << YAML::Key << "simulation" << YAML::Value << YAML::BeginMap;
  EmitNum(out, "fine_edge_px", s.simulation.fine_edge_px);
  out << YAML::Key << "substeps" << YAML::Value << s.simulation.substeps;
  out << YAML::Key << "max_newton_iterations" << YAML::Value << s.simulation.max_newton_iterations;
  out << YAML::EndMap;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

}  // namespace calib::synth
