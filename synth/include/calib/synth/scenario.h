#pragma once
// A scenario: everything `calib synth` needs to make one synthetic recording
// (scene geometry, material and effects, camera, force sensor, seed). The YAML
// file format is documented key by key in docs/scenario.md.
//
// Units are in the names: *_mm millimetres on the table, *_px image pixels,
// *_s seconds, *_pa pascals, *_n newtons, *_rgb 8-bit colours (R, G, B).

#include "calib/core/types.h"
#include "calib/synth/material_law.h"
#include "calib/synth/truth_simulator.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib::synth {

/// Thrown for a scenario file that cannot be read or is malformed; what()
/// names the file, the key path (e.g. `push.depth_mm`), the value and the rule.
class ScenarioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// push: a sponge on a table pushed by a finger against a pencil (the paper's
/// setup). hang: an object clamped at its top edge swinging under gravity.
enum class ScenarioKind { kPush, kHang };
std::string ToString(ScenarioKind kind);
/// "push" or "hang"; throws std::invalid_argument naming the text otherwise.
ScenarioKind ScenarioKindFromString(const std::string& text);

/// The object's outline. Every shape is cut from a width_mm x height_mm
/// rectangle; its sides are named as the push sees them before the object is
/// turned: near (top, small y, where the finger comes in), far (bottom, where
/// the pencil stands), left, right.
enum class ObjectShape {
  kRectangle,  ///< the rectangle itself
  kWaist,      ///< both left and right sides cut in by a trapezoid (waist_mm)
  kRounded,    ///< every corner rounded with corner_radius_mm
  kNotched,    ///< a rectangular notch cut into one side (notch)
  kLShape,     ///< a rectangle with one corner block removed (cutout)
};
std::string ToString(ObjectShape shape);
/// "rectangle", "waist", "rounded", "notched" or "l_shape"; throws
/// std::invalid_argument naming the text otherwise.
ObjectShape ObjectShapeFromString(const std::string& text);

enum class ObjectSide { kNear, kFar, kLeft, kRight };
std::string ToString(ObjectSide side);
ObjectSide ObjectSideFromString(const std::string& text);

enum class ObjectCorner { kNearLeft, kNearRight, kFarLeft, kFarRight };
std::string ToString(ObjectCorner corner);
ObjectCorner ObjectCornerFromString(const std::string& text);

/// A rectangular notch cut into one side (shape notched). Its middle lies
/// position_fraction along the side (near and far sides: from the left end;
/// left and right sides: from the near end); width_mm along the side,
/// depth_mm into the object.
struct NotchSpec {
  ObjectSide side = ObjectSide::kFar;
  double position_fraction = 0.5;
  double width_mm = 12.0;
  double depth_mm = 8.0;
};

/// The block removed from one corner (shape l_shape): width_mm along the
/// near/far sides, height_mm along the left/right sides.
struct CutoutSpec {
  ObjectCorner corner = ObjectCorner::kFarRight;
  double width_mm = 30.0;
  double height_mm = 20.0;
};

/// The object's rest outline, cut from a width_mm x height_mm rectangle that
/// is centred horizontally; push: centred in the image, hang: its top edge at
/// hang.top_margin_mm below the image's top. push: the whole outline is then
/// turned by rotation_deg about the rectangle's centre.
struct ObjectSpec {
  /// Read from the file, or waist when the file leaves it out and gives a
  /// waist_mm > 0 (files written before shapes had names), else rectangle.
  ObjectShape shape = ObjectShape::kRectangle;
  double width_mm = 100.0;
  double height_mm = 64.0;
  /// Shape waist: both left and right sides are cut in by a trapezoidal
  /// notch this deep between 35 % and 65 % of the height. 0 otherwise.
  double waist_mm = 0.0;
  /// Shape rounded only (a file that names shape rounded without it gets 8).
  std::optional<double> corner_radius_mm;
  /// Shape notched only (defaults as NotchSpec when the file leaves it out).
  std::optional<NotchSpec> notch;
  /// Shape l_shape only (defaults as CutoutSpec when the file leaves it out).
  std::optional<CutoutSpec> cutout;
  /// Push only: the outline, finger and pencil turn by this angle about the
  /// rectangle's centre, clockwise on screen (image axes, y down), so the
  /// finger comes in along the turned near side's inward normal. [-180, 180].
  double rotation_deg = 0.0;
};

/// The push: a finger disc comes in from the near (top, small y) side along
/// its inward normal, holds, retracts; a pencil disc stands still against the
/// far (bottom) side. Both are placed against the actual outline: the finger
/// starts start_gap_mm from where, moving in, it would first touch the
/// outline, and the pencil stands pencil_gap_mm from where, moving up, it
/// would first touch it (an L-shape's step, a notch's floor). With
/// object.rotation_deg everything turns with the object.
struct PushSpec {
  double finger_radius_mm = 3.5;
  /// Where the finger meets the near side: a fraction of the object's width
  /// from its left end, in [0, 1]; position_mm (from the left end, in
  /// [0, width_mm]) overrides it when set.
  double position_fraction = 0.5;
  std::optional<double> position_mm;
  /// How far the finger's leading point goes past where it first touches the
  /// rest outline, > 0.
  double depth_mm = 10.0;
  /// Gap between the finger and the outline at frame 0, >= 0.
  double start_gap_mm = 4.0;
  /// Timeline: still for delay_s, moving in over approach_s, holding for
  /// hold_s, moving back to the start over retract_s, then still. Moves follow
  /// a smooth (cosine) ramp. Each >= 0; approach_s, retract_s > 0.
  double delay_s = 0.5;
  double approach_s = 4.0;
  double hold_s = 2.0;
  double retract_s = 3.0;
  double pencil_radius_mm = 2.25;
  /// Pencil position along the far side, fraction of the width from its left
  /// end, [0, 1].
  double pencil_position_fraction = 0.5;
  /// Gap between the pencil and the outline at rest, >= 0.
  double pencil_gap_mm = 0.0;
};

/// The hanging object: clamped at its top edge, released at frame 0 from the
/// pose that initial_bend_m_s2 (an extra body acceleration) holds it in.
struct HangSpec {
  double top_margin_mm = 10.0;     ///< object top edge below the image top, > 0
  double clamp_depth_mm = 6.0;     ///< how far down the clamp grips, > 0, < height
  Vec2 initial_bend_m_s2 = Vec2(30.0, 0.0);
};

/// The base (elastic) material of the truth model.
struct MaterialSpec {
  /// neo_hookean (the default) or hencky (logarithmic strain, hencky.h).
  MaterialLaw law = MaterialLaw::kNeoHookean;
  double youngs_modulus_pa = 30e3;
  double poisson_ratio = 0.3;
  double thickness_mm = 20.0;
  double density_kg_m3 = 40.0;
};

/// The table: Coulomb friction, regularised below friction_regularisation_mm_s.
struct EnvironmentSpec {
  double friction_coefficient = 0.3;
  double friction_regularisation_mm_s = 0.01;
};

/// Effects the calibrated model lacks; each is on when present.
struct PlasticityEffect {
  double yield_strain = 0.05;
  double flow_rate_per_s = 5.0;
};
struct StiffnessRegionSpec {
  Vec2 centre_fraction = Vec2(0.5, 0.5);  ///< of the object's width, height; [0, 1]
  double radius_mm = 15.0;
  double factor = 3.0;  ///< Young's modulus multiplier inside
};
struct UnevenStiffnessEffect {
  double gradient = 0.0;                ///< E from (1 - g) to (1 + g); [0, 1)
  Vec2 direction = Vec2(1.0, 0.0);      ///< image axes, non-zero
  std::vector<StiffnessRegionSpec> regions;
};
struct StrainStiffeningEffect {
  double coefficient = 1.0;
};
struct ViscoelasticEffect {
  double fraction = 0.5;           ///< share of stiffness that relaxes, (0, 1)
  double relaxation_time_s = 1.5;
};
struct StrongFrictionEffect {
  double coefficient = 1.5;        ///< replaces environment.friction_coefficient
};
struct InertiaGravityEffect {
  Vec2 gravity_m_s2 = Vec2(0.0, 9.81);
};
struct Effects {
  std::optional<PlasticityEffect> plasticity;
  std::optional<UnevenStiffnessEffect> uneven_stiffness;
  std::optional<StrainStiffeningEffect> strain_stiffening;
  std::optional<ViscoelasticEffect> viscoelastic;
  std::optional<StrongFrictionEffect> strong_friction;
  /// Second-order dynamics with gravity; always on for hang.
  std::optional<InertiaGravityEffect> inertia_gravity;

  /// Names of the effects that are on, in declaration order.
  std::vector<std::string> EnabledNames() const;
};

/// How the frames look.
struct CameraSpec {
  int width_px = 640;
  int height_px = 480;
  std::array<int, 3> object_rgb{225, 200, 40};
  std::array<int, 3> background_rgb{62, 60, 58};
  std::array<int, 3> finger_rgb{215, 170, 150};
  std::array<int, 3> pencil_rgb{40, 90, 150};
  /// Brightness varies linearly by +-lighting_gradient across the image along
  /// lighting_angle_deg (0: brighter to the right, 90: brighter downwards).
  double lighting_gradient = 0.15;
  double lighting_angle_deg = 30.0;
  double noise_sigma = 2.0;        ///< gaussian pixel noise, grey levels
  double blur_sigma_px = 0.7;      ///< gaussian blur; 0: none
  double finger_opacity = 0.6;     ///< (0, 1]
  double texture_contrast = 0.3;   ///< pores darken the object by up to this share, [0, 0.6]
  double pore_size_px = 2.5;       ///< mean pore radius, > 0
  int video_crf = 28;              ///< H.264 constant rate factor, [0, 51]; lower: larger, sharper
};

/// The force sensor on the finger: reading = true force + noise + bias.
struct SensorSpec {
  double noise_n = 0.005;          ///< gaussian noise per component, N, >= 0
  Vec2 bias_n = Vec2(0.004, -0.006);
};

/// The truth model's discretisation.
struct SimulationSpec {
  /// Fine-mesh edge length, px; at most 1/3 of the calibrated model's 20 px.
  double fine_edge_px = 6.0;
  /// Truth-model steps per frame: push 2 (quasi-static: 2 and 10 steps
  /// differ by < 0.1 px), hang 10 (dynamics at the frame rate).
  int substeps = 10;
  int max_newton_iterations = 50;
};

struct Scenario {
  std::string name = "scenario";
  ScenarioKind kind = ScenarioKind::kPush;
  double mm_per_px = 0.25;
  double fps = 30.0;
  int frames = 330;
  uint64_t seed = 1;
  std::string notes;
  ObjectSpec object;
  PushSpec push;     ///< used when kind == kPush
  HangSpec hang;     ///< used when kind == kHang
  MaterialSpec material;
  EnvironmentSpec environment;
  Effects effects;
  CameraSpec camera;
  SensorSpec sensor;
  SimulationSpec simulation;

  /// False, with a message naming the key path (as in the file), its value
  /// and the rule, when a value is out of range or the object, finger or
  /// pencil does not fit in the image; `error` may be null.
  bool IsValid(std::string* error) const;
};

/// The defaults of a kind: push as in the paper (100 x 64 mm, 330 frames at
/// 30 fps); hang a 25 x 100 mm strip at 240 fps for 180 frames, no table
/// friction, inertia and gravity on.
Scenario DefaultScenario(ScenarioKind kind);

/// Parses and validates a scenario from YAML text; `source` names it in
/// messages (usually the file path). Unknown keys, wrong types and
/// out-of-range values throw ScenarioError naming source, key path and value.
Scenario ParseScenario(const std::string& yaml_text, const std::string& source);

/// Reads `path` and parses it as ParseScenario does. Throws ScenarioError
/// naming the file when it cannot be read.
Scenario LoadScenario(const std::filesystem::path& path);

/// The same scenario (scene, material, camera, noise, seed) with every
/// effect switched off, except the inertia and gravity a hang needs: the
/// twin whose recording, compared with the scenario's (`calib compare`),
/// gives the effects' footprint in pixels. The notes say so.
Scenario WithoutEffects(const Scenario& scenario);

/// The scenario as YAML that ParseScenario reads back to an equal scenario
/// (every key written, numbers with full precision).
std::string ScenarioToYaml(const Scenario& scenario);

// ---- Geometry in pixels and the truth model's inputs -------------------

/// The rectangle the object's shape is cut from, px (integer-aligned), before
/// object.rotation_deg turns it about its centre.
RectPx ObjectRectPx(const Scenario& scenario);

/// The rest outline, px, clockwise on screen: the object's shape cut from
/// ObjectRectPx, turned by object.rotation_deg about the rectangle's centre.
std::vector<Vec2> RestPolygonPx(const Scenario& scenario);

/// Obstacle discs per frame, px: push: {finger, pencil}; hang: none.
std::vector<std::vector<Disc>> ObstacleTracksPx(const Scenario& scenario);

/// Obstacle names in ObstacleTracksPx order ({"finger", "pencil"} or {}).
std::vector<std::string> ObstacleNames(const Scenario& scenario);

/// Clamp rectangles, px (integer-aligned): hang: one over the top edge,
/// reaching 2 px beyond the object on three sides; push: none.
std::vector<RectPx> ClampRectsPx(const Scenario& scenario);

/// The truth model's material and environment for the scenario's effects.
TruthMaterial ToTruthMaterial(const Scenario& scenario);
TruthEnvironment ToTruthEnvironment(const Scenario& scenario);

}  // namespace calib::synth
