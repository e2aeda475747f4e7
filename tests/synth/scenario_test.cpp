// Scenario files: a full file round-trips through ScenarioToYaml; defaults
// fill what a file leaves out; every kind of bad input is an error naming the
// file, the key path and the value.

#include "calib/synth/scenario.h"

#include "error_text.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

namespace calib::synth {
namespace {

// Parses `text` as a scenario named bad.yaml: refused, naming the file and `parts`.
void ExpectErrorNames(const std::string& text, const std::vector<std::string>& parts) {
  const std::string error =
      testing::ErrorOf<ScenarioError>([&] { ParseScenario(text, "bad.yaml"); });
  testing::ExpectMessageNames(error, text, parts);
  EXPECT_NE(error.find("bad.yaml"), std::string::npos) << error;
}

const char* kFullPush = R"(
name: full_push
kind: push
mm_per_px: 0.25
fps: 30
frames: 120
seed: 42
notes: "every key"
object: {width_mm: 90, height_mm: 60, waist_mm: 0}
push:
  finger_radius_mm: 4
  position_mm: 30
  depth_mm: 8
  start_gap_mm: 2
  delay_s: 0.2
  approach_s: 1.5
  hold_s: 0.5
  retract_s: 1
  pencil_radius_mm: 2
  pencil_position_fraction: 0.4
  pencil_gap_mm: 0.5
material: {youngs_modulus_pa: 25000, poisson_ratio: 0.25, thickness_mm: 18, density_kg_m3: 35}
environment: {friction_coefficient: 0.4, friction_regularisation_mm_s: 2}
effects:
  plasticity: {yield_strain: 0.04, flow_rate_per_s: 3}
  uneven_stiffness:
    gradient: 0.3
    direction: [0, 1]
    regions:
      - {centre_fraction: [0.25, 0.5], radius_mm: 10, factor: 2.5}
  strain_stiffening: {coefficient: 0.8}
  viscoelastic: {fraction: 0.4, relaxation_time_s: 2}
  strong_friction: {coefficient: 2}
camera:
  width_px: 640
  height_px: 480
  object_rgb: [230, 190, 30]
  noise_sigma: 1.5
  blur_sigma_px: 0.5
  finger_opacity: 0.5
  video_crf: 30
sensor: {noise_n: 0.01, bias_n: [0.001, 0.002]}
simulation: {fine_edge_px: 5, substeps: 8, max_newton_iterations: 30}
)";

TEST(Scenario, FullFileRoundTrips) {
  const Scenario s = ParseScenario(kFullPush, "full.yaml");
  EXPECT_EQ(s.name, "full_push");
  EXPECT_EQ(s.frames, 120);
  EXPECT_EQ(s.seed, 42u);
  ASSERT_TRUE(s.push.position_mm.has_value());
  EXPECT_EQ(*s.push.position_mm, 30.0);
  ASSERT_TRUE(s.effects.uneven_stiffness.has_value());
  ASSERT_EQ(s.effects.uneven_stiffness->regions.size(), 1u);
  EXPECT_EQ(s.effects.uneven_stiffness->regions[0].factor, 2.5);
  EXPECT_FALSE(s.effects.inertia_gravity.has_value());
  EXPECT_EQ(s.effects.EnabledNames().size(), 5u);
  EXPECT_EQ(s.camera.object_rgb[2], 30);
  EXPECT_EQ(s.camera.video_crf, 30);
  EXPECT_EQ(s.sensor.bias_n.y(), 0.002);

  const std::string yaml = ScenarioToYaml(s);
  const Scenario back = ParseScenario(yaml, "roundtrip.yaml");
  EXPECT_EQ(ScenarioToYaml(back), yaml);
  EXPECT_EQ(back.material.youngs_modulus_pa, s.material.youngs_modulus_pa);
  EXPECT_EQ(back.effects.viscoelastic->relaxation_time_s, 2.0);
}

TEST(Scenario, WithoutEffectsSwitchesEveryEffectOffAndKeepsTheRest) {
  const Scenario s = ParseScenario(kFullPush, "full.yaml");
  const Scenario twin = WithoutEffects(s);
  EXPECT_TRUE(twin.effects.EnabledNames().empty());
  // Everything else, noise seed included, is the scenario's: only the
  // effects differ between the two recordings.
  Scenario expected = s;
  expected.effects = Effects{};
  expected.notes = twin.notes;
  EXPECT_EQ(ScenarioToYaml(twin), ScenarioToYaml(expected));
  EXPECT_NE(twin.notes.find("plasticity"), std::string::npos) << twin.notes;
  EXPECT_NE(twin.notes.find("strong_friction"), std::string::npos) << twin.notes;
  std::string error;
  EXPECT_TRUE(twin.IsValid(&error)) << error;
}

TEST(Scenario, WithoutEffectsKeepsTheGravityAHangNeeds) {
  Scenario hang = DefaultScenario(ScenarioKind::kHang);
  hang.effects.viscoelastic = ViscoelasticEffect{};
  const Scenario twin = WithoutEffects(hang);
  EXPECT_EQ(twin.effects.EnabledNames(), std::vector<std::string>{"inertia_gravity"});
  std::string error;
  EXPECT_TRUE(twin.IsValid(&error)) << error;
  EXPECT_NE(twin.notes.find("viscoelastic"), std::string::npos) << twin.notes;
}

TEST(Scenario, LoadScenarioReadsAFileAndNamesAMissingOne) {
  const auto dir = testing::ScratchDir("scenario_load");
  std::ofstream(dir / "s.yaml") << kFullPush;
  EXPECT_EQ(LoadScenario(dir / "s.yaml").name, "full_push");
  try {
    LoadScenario(dir / "absent.yaml");
    FAIL() << "read a missing file";
  } catch (const ScenarioError& e) {
    EXPECT_NE(std::string(e.what()).find("absent.yaml: cannot open"), std::string::npos) << e.what();
  }
}

TEST(Scenario, DefaultsFillAMinimalFile) {
  const Scenario push = ParseScenario("kind: push\n", "min.yaml");
  EXPECT_EQ(push.frames, 330);
  EXPECT_EQ(push.fps, 30.0);
  EXPECT_EQ(push.object.width_mm, 100.0);
  EXPECT_LE(push.simulation.fine_edge_px, 20.0 / 3.0);
  EXPECT_TRUE(push.effects.EnabledNames().empty());
  const RectPx r = ObjectRectPx(push);
  EXPECT_EQ(r.width, 400.0);
  EXPECT_EQ(r.height, 256.0);

  const Scenario hang = ParseScenario("kind: hang\nobject: {waist_mm: 4}\n", "min.yaml");
  EXPECT_GE(hang.fps, 200.0);
  EXPECT_TRUE(hang.effects.inertia_gravity.has_value());
  EXPECT_EQ(ObstacleTracksPx(hang)[0].size(), 0u);
  EXPECT_EQ(ClampRectsPx(hang).size(), 1u);
  EXPECT_EQ(RestPolygonPx(hang).size(), 12u);  // notched: concave
  EXPECT_TRUE(ToTruthEnvironment(hang).inertia);
}

TEST(Scenario, PushTrackMovesInHoldsAndRetracts) {
  Scenario s = ParseScenario("kind: push\npush: {position_fraction: 0.25}\n", "p.yaml");
  const auto tracks = ObstacleTracksPx(s);
  ASSERT_EQ(tracks.size(), 330u);
  const RectPx r = ObjectRectPx(s);
  const Disc& first = tracks.front()[0];
  EXPECT_DOUBLE_EQ(first.centre.x(), r.x + 0.25 * r.width);
  EXPECT_LT(first.centre.y() + first.radius_px, r.y);  // clear of the object
  double deepest = 0.0;
  for (const auto& frame : tracks) deepest = std::max(deepest, frame[0].centre.y() + frame[0].radius_px);
  EXPECT_NEAR(deepest, r.y + s.push.depth_mm / s.mm_per_px, 1e-9);
  EXPECT_DOUBLE_EQ(tracks.back()[0].centre.y(), first.centre.y());  // back at the start
  const Disc& pencil = tracks.front()[1];
  EXPECT_DOUBLE_EQ(pencil.centre.y() - pencil.radius_px, r.y + r.height);
}

TEST(Scenario, UnknownKeyIsNamed) {
  ExpectErrorNames("kind: push\npush: {depht_mm: 3}\n", {"push.depht_mm", "unknown key", "'3'"});
  ExpectErrorNames("kind: push\ncolour: red\n", {"colour", "unknown key"});
  ExpectErrorNames("kind: push\neffects: {plasticity: {yield: 0.1}}\n", {"effects.plasticity.yield"});
}

TEST(Scenario, WrongTypeIsNamed) {
  ExpectErrorNames("kind: push\npush: {depth_mm: deep}\n", {"push.depth_mm", "a number", "'deep'"});
  ExpectErrorNames("kind: push\nframes: 12.5\n", {"frames", "an integer", "'12.5'"});
  ExpectErrorNames("kind: push\ncamera: {object_rgb: [1, 2]}\n", {"camera.object_rgb", "3 integers"});
  ExpectErrorNames("kind: push\nobject: 5\n", {"object", "a map"});
  ExpectErrorNames("kind: push\nseed: -3\n", {"seed", "non-negative integer", "'-3'"});
  ExpectErrorNames(
      "kind: push\neffects: {uneven_stiffness: {regions: [{centre_fraction: [0.5, x]}]}}\n",
      {"effects.uneven_stiffness.regions[0].centre_fraction[1]", "'x'"});
}

TEST(Scenario, OutOfRangeValueIsNamed) {
  ExpectErrorNames("kind: push\npush: {depth_mm: -3}\n", {"push.depth_mm = -3", "Violated"});
  ExpectErrorNames("kind: push\nmaterial: {poisson_ratio: 0.5}\n", {"material.poisson_ratio = 0.5"});
  ExpectErrorNames("kind: push\nsimulation: {fine_edge_px: 0}\n", {"simulation.fine_edge_px = 0"});
  ExpectErrorNames("kind: push\ncamera: {width_px: 641}\n", {"camera.width_px = 641"});
  ExpectErrorNames("kind: push\neffects: {viscoelastic: {fraction: 1.5}}\n",
                   {"effects.viscoelastic.fraction = 1.5"});
  ExpectErrorNames("kind: push\ncamera: {object_rgb: [300, 0, 0]}\n", {"camera.object_rgb", "0..255"});
  ExpectErrorNames("kind: push\nobject: {width_mm: 200}\n", {"object.width_mm = 200", "fits"});
}

TEST(Scenario, BadKindAndMisplacedSectionAreNamed) {
  ExpectErrorNames("kind: roll\n", {"kind", "push or hang", "'roll'"});
  ExpectErrorNames("kind: hang\npush: {depth_mm: 3}\n", {"push", "kind hang"});
  ExpectErrorNames("name: [a]\n", {"name", "a string"});
  ExpectErrorNames("kind: push\n  bad indent: [\n", {"not valid YAML"});
}

}  // namespace
}  // namespace calib::synth
