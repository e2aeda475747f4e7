// Scene families: the bundled specs parse and plan; each kind of bad key or
// value is an error naming the file and the key; sampling is deterministic
// (same seed: same manifest and scenarios; an object depends only on the
// seed, its cell and its index) and each object differs; colours that do
// not separate are drawn again; the held-out push differs from the trained
// one in the push only; --plan writes the manifest and scenario files; and
// one tiny object is synthesised end to end.

#include "calib/synth/family.h"

#include "calib/evaluator/recording.h"
#include "calib/synth/renderer.h"
#include "error_text.h"
#include "support/test_support.h"

#include "support/process_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

namespace calib::synth {
namespace {

namespace fs = std::filesystem;

fs::path Examples() { return fs::path(CALIB_SOURCE_DIR) / "examples" / "families"; }

// A small family: 3 cells (none, plasticity, a confusable friction cell).
const char* kSmall = R"(
name: small
seed: 7
count: 3
base:
  push: {delay_s: 0.2, approach_s: 1, hold_s: 0.5, retract_s: 0.5}
  simulation: {fine_edge_px: 12}
tail_s: {min: 0.5, max: 1}
sample:
  object:
    width_mm: {min: 80, max: 100}
    height_mm: {min: 50, max: 64}
    rotation_deg: {min: -15, max: 15}
    one_of:
      - {shape: rectangle}
      - {shape: rounded, corner_radius_mm: {min: 3, max: 8}}
      - {shape: notched, notch: {side: {choices: [far, left, right]}, width_mm: {min: 8, max: 12}, depth_mm: {min: 4, max: 8}}}
      - {shape: l_shape, cutout: {corner: {choices: [far_left, far_right]}, width_mm: {min: 15, max: 25}, height_mm: {min: 10, max: 15}}}
  push:
    position_fraction: {min: 0.45, max: 0.55}
    depth_mm: {min: 8, max: 10}
  material:
    law: {choices: [neo_hookean, hencky]}
    youngs_modulus_pa: {min: 20000, max: 40000}
    poisson_ratio: {min: 0.2, max: 0.4}
  environment: {friction_coefficient: {min: 0.2, max: 0.4}}
  fps: {choices: [25, 30]}
  camera:
    object_rgb: [{min: 200, max: 240, step: 1}, {min: 170, max: 210, step: 1}, {min: 20, max: 60, step: 1}]
    noise_sigma: {min: 1, max: 3}
    video_crf: {min: 24, max: 30, step: 1}
holdout:
  position_fraction: {choices: [{min: 0.2, max: 0.3}, {min: 0.7, max: 0.8}]}
cells:
  - effect: none
  - effect: plasticity
    magnitude: clear
    parameters: {yield_strain: {min: 0.035, max: 0.045}, flow_rate_per_s: {min: 3, max: 5}}
  - name: friction-holds-dent
    effect: strong_friction
    magnitude: clear
    confusable_with: plasticity
    parameters: {coefficient: {min: 1.3, max: 1.7}}
    sample: {material: {density_kg_m3: {min: 400, max: 600}}}
)";

FamilySpec Small() { return ParseFamilySpec(kSmall, "small.yaml"); }

// ---------------------------------------------------------------- the bundled specs

TEST(Family, BundledSpecsParseAndPlan) {
  for (const char* name : {"ci.yaml", "tune.yaml", "test.yaml"}) {
    const FamilySpec spec = LoadFamilySpec(Examples() / name);
    const FamilyPlan plan = PlanFamily(spec, spec.seed, 2);
    EXPECT_EQ(plan.objects.size(), 2 * spec.cells.size()) << name;
    for (const FamilyObject& o : plan.objects) {
      ASSERT_EQ(o.scenarios.size(), 2u) << o.id;
      for (const Scenario& s : o.scenarios) {
        std::string error;
        EXPECT_TRUE(s.IsValid(&error)) << name << " " << o.id << ": " << error;
        EXPECT_TRUE(ColoursSeparate(s.camera, &error)) << name << " " << o.id << ": " << error;
      }
    }
  }
}

TEST(Family, TuneAndTestHaveEveryEffectAtBothMagnitudesNoneAndThreeConfusableCells) {
  for (const char* name : {"tune.yaml", "test.yaml"}) {
    const FamilySpec spec = LoadFamilySpec(Examples() / name);
    std::set<std::string> labelled;
    int none = 0, confusable = 0;
    for (const FamilyCell& c : spec.cells) {
      if (c.confusable_with) {
        ++confusable;
      } else if (c.effect) {
        labelled.insert(*c.effect + "-" + *c.magnitude);
      } else {
        ++none;
      }
    }
    for (const std::string& effect : FamilyEffectNames()) {
      EXPECT_TRUE(labelled.count(effect + "-clear")) << name << ": " << effect;
      EXPECT_TRUE(labelled.count(effect + "-faint")) << name << ": " << effect;
    }
    EXPECT_EQ(none, 1) << name;
    EXPECT_EQ(confusable, 3) << name;
  }
  // The test family differs from the tuning one: law, seed.
  const FamilySpec tune = LoadFamilySpec(Examples() / "tune.yaml");
  const FamilySpec test = LoadFamilySpec(Examples() / "test.yaml");
  EXPECT_NE(tune.seed, test.seed);
  const FamilyPlan tune_plan = PlanFamily(tune, tune.seed, 1);
  const FamilyPlan test_plan = PlanFamily(test, test.seed, 1);
  for (const FamilyObject& o : tune_plan.objects) EXPECT_EQ(o.scenarios[0].material.law, MaterialLaw::kNeoHookean);
  for (const FamilyObject& o : test_plan.objects) EXPECT_EQ(o.scenarios[0].material.law, MaterialLaw::kHencky);
}

// ---------------------------------------------------------------- bad input

// `text` as a family spec named bad.yaml is refused, naming the file and `parts`.
void ExpectSpecErrorNames(const std::string& text, const std::vector<std::string>& parts) {
  const std::string error = testing::ErrorOf<FamilyError>([&] { ParseFamilySpec(text, "bad.yaml"); });
  testing::ExpectMessageNames(error, text, parts);
  EXPECT_NE(error.find("bad.yaml"), std::string::npos) << error;
}

const std::string kCells = "cells: [{effect: none}]\n";

TEST(FamilySpec, UnknownFamilyKeyIsNamed) {
  ExpectSpecErrorNames("sampel: {}\n" + kCells, {"sampel", "unknown key", "did you mean 'sample'"});
  ExpectSpecErrorNames("cells: [{effect: none, magnitud: clear}]\n", {"cells[0].magnitud", "unknown key"});
}

TEST(FamilySpec, UnknownScenarioKeyInATreeIsNamed) {
  ExpectSpecErrorNames("sample: {push: {depht_mm: {min: 1, max: 2}}}\n" + kCells,
                       {"sample.push.depht_mm", "unknown key", "did you mean 'depth_mm'"});
  ExpectSpecErrorNames("holdout: {depth: 3}\n" + kCells, {"holdout.depth", "unknown key"});
  ExpectSpecErrorNames("sample: {object: {one_of: [{shape: rounded, radius_mm: 3}]}}\n" + kCells,
                       {"sample.object.one_of[0].radius_mm", "unknown key"});
  ExpectSpecErrorNames("cells: [{effect: plasticity, magnitude: clear, parameters: {yield: 0.1}}]\n",
                       {"cells[0].parameters.yield", "unknown key", "yield_strain"});
  ExpectSpecErrorNames("base: {push: {depht_mm: 3}}\n" + kCells, {"base.push.depht_mm", "unknown key"});
}

TEST(FamilySpec, MalformedRangeIsNamed) {
  ExpectSpecErrorNames("sample: {push: {depth_mm: {min: 3}}}\n" + kCells, {"sample.push.depth_mm.max", "missing"});
  ExpectSpecErrorNames("sample: {push: {depth_mm: {min: 5, max: 2}}}\n" + kCells,
                       {"sample.push.depth_mm.max = '2'", "max >= min"});
  ExpectSpecErrorNames("sample: {push: {depth_mm: {min: a, max: 2}}}\n" + kCells,
                       {"sample.push.depth_mm.min = 'a'", "a number"});
  ExpectSpecErrorNames("sample: {push: {depth_mm: {min: 1, max: 2, stp: 1}}}\n" + kCells,
                       {"sample.push.depth_mm.stp", "unknown key in a range"});
  ExpectSpecErrorNames("sample: {camera: {video_crf: {min: 20, max: 30, step: 0}}}\n" + kCells,
                       {"sample.camera.video_crf.step = '0'", "> 0"});
  ExpectSpecErrorNames("sample: {push: {min: 1, max: 2}}\n" + kCells, {"sample.push", "a map of keys here"});
}

TEST(FamilySpec, MalformedChoiceOrOneOfIsNamed) {
  ExpectSpecErrorNames("sample: {material: {law: {choices: []}}}\n" + kCells,
                       {"sample.material.law.choices", "non-empty list"});
  ExpectSpecErrorNames("sample: {material: {law: {choices: hencky}}}\n" + kCells,
                       {"sample.material.law.choices = 'hencky'", "non-empty list"});
  ExpectSpecErrorNames("sample: {object: {one_of: {shape: rounded}}}\n" + kCells,
                       {"sample.object.one_of", "non-empty list of maps"});
  ExpectSpecErrorNames("sample: {object: {width_mm: 90, one_of: [{width_mm: 80}]}}\n" + kCells,
                       {"sample.object.one_of[0].width_mm", "only where both hold a map"});
}

TEST(FamilySpec, KeysTheGeneratorSetsAreRefused) {
  ExpectSpecErrorNames("sample: {frames: {min: 100, max: 200}}\n" + kCells, {"sample.frames", "timeline"});
  ExpectSpecErrorNames("base: {seed: 3}\n" + kCells, {"base.seed", "family seed"});
  ExpectSpecErrorNames("base: {effects: {plasticity: {}}}\n" + kCells, {"base.effects", "cells"});
  ExpectSpecErrorNames("cells: [{effect: none, sample: {name: x}}]\n", {"cells[0].sample.name"});
  ExpectSpecErrorNames("base: {kind: hang}\n" + kCells, {"base.kind = 'hang'", "kind push"});
}

TEST(FamilySpec, BadCellIsNamed) {
  ExpectSpecErrorNames("cells: [{effect: gravity}]\n", {"cells[0].effect = 'gravity'", "plasticity", "or none"});
  ExpectSpecErrorNames("cells: [{effect: plasticity}]\n", {"cells[0].magnitude", "missing"});
  ExpectSpecErrorNames("cells: [{effect: plasticity, magnitude: big}]\n",
                       {"cells[0].magnitude = 'big'", "clear or faint"});
  ExpectSpecErrorNames("cells: [{effect: none, magnitude: clear}]\n", {"cells[0].magnitude", "no magnitude"});
  ExpectSpecErrorNames("cells: [{effect: none, confusable_with: wobble}]\n",
                       {"cells[0].confusable_with = 'wobble'", "table_friction"});
  ExpectSpecErrorNames("cells: [{effect: strong_friction, magnitude: clear, confusable_with: table_friction}]\n",
                       {"cells[0].confusable_with", "itself"});
  ExpectSpecErrorNames("cells: [{effect: none}, {effect: none}]\n", {"cells[1].name", "two cells share"});
  ExpectSpecErrorNames("cells: [{effect: none, parameters: {coefficient: 2}}]\n",
                       {"cells[0].parameters", "without an effect"});
  ExpectSpecErrorNames("cells: [{effect: none, name: 'a b'}]\n", {"cells[0].name = 'a b'", "letters"});
  ExpectSpecErrorNames("cells: []\n", {"cells", "non-empty list"});
  ExpectSpecErrorNames("name: x\n", {"cells", "missing"});
}

TEST(FamilySpec, BadTopLevelValueIsNamed) {
  ExpectSpecErrorNames("count: 0\n" + kCells, {"count = '0'", "1 <= count"});
  ExpectSpecErrorNames("seed: -1\n" + kCells, {"seed = '-1'", "non-negative integer"});
  ExpectSpecErrorNames("name: 'two words'\n" + kCells, {"name = 'two words'", "letters"});
  ExpectSpecErrorNames("tail_s: {min: 1}\n" + kCells, {"tail_s.max", "missing"});
  ExpectSpecErrorNames("base: [1, 2]\n" + kCells, {"base", "a scenario"});
  ExpectSpecErrorNames("cells: [\n", {"not valid YAML"});
}

TEST(FamilySpec, InvalidBaseScenarioIsNamed) {
  ExpectSpecErrorNames("base: {push: {depth_mm: -3}}\n" + kCells, {"base", "push.depth_mm = -3", "Violated"});
  ExpectSpecErrorNames("base: {material: {law: mooney}}\n" + kCells, {"base", "material.law = 'mooney'"});
}

TEST(FamilySpec, SampledScenarioThatIsInvalidIsNamedWithItsCellAndObject) {
  const FamilySpec spec =
      ParseFamilySpec("sample: {push: {depth_mm: {min: 40, max: 50}}}\ncells: [{effect: none}]\n", "bad.yaml");
  const std::string error = testing::ErrorOf<FamilyError>([&] { PlanFamily(spec, 1, 1); });
  testing::ExpectMessageNames(error, "", {"bad.yaml", "cell none", "object none-00", "push-a", "push.depth_mm"});
}

TEST(FamilySpec, LoadNamesAMissingFile) {
  const std::string error =
      testing::ErrorOf<FamilyError>([&] { LoadFamilySpec(testing::ScratchDir("family_load") / "absent.yaml"); });
  testing::ExpectMessageNames(error, "", {"absent.yaml", "cannot open"});
}

// ---------------------------------------------------------------- sampling

TEST(Family, SameSeedGivesTheSameManifestAndScenarios) {
  const FamilySpec spec = Small();
  const FamilyPlan a = PlanFamily(spec, 7, 3);
  const FamilyPlan b = PlanFamily(Small(), 7, 3);
  EXPECT_EQ(FamilyManifestJson(a), FamilyManifestJson(b));
  ASSERT_EQ(a.objects.size(), b.objects.size());
  for (size_t i = 0; i < a.objects.size(); ++i) {
    for (size_t r = 0; r < 2; ++r) {
      EXPECT_EQ(ScenarioToYaml(a.objects[i].scenarios[r]), ScenarioToYaml(b.objects[i].scenarios[r]));
    }
  }
  EXPECT_NE(FamilyManifestJson(a), FamilyManifestJson(PlanFamily(spec, 8, 3)));
}

TEST(Family, ObjectsDifferAndDependOnlyOnSeedCellAndIndex) {
  const FamilySpec spec = Small();
  const FamilyPlan plan = PlanFamily(spec, 7, 3);
  std::set<std::string> yamls;
  std::set<double> widths, moduli;
  std::set<uint64_t> seeds;
  for (const FamilyObject& o : plan.objects) {
    for (const Scenario& s : o.scenarios) {
      yamls.insert(ScenarioToYaml(s));
      seeds.insert(s.seed);
    }
    widths.insert(o.scenarios[0].object.width_mm);
    moduli.insert(o.scenarios[0].material.youngs_modulus_pa);
  }
  EXPECT_EQ(yamls.size(), 2 * plan.objects.size());
  EXPECT_EQ(seeds.size(), 2 * plan.objects.size());
  EXPECT_EQ(widths.size(), plan.objects.size());
  EXPECT_EQ(moduli.size(), plan.objects.size());

  // More objects per cell, or a cell fewer: the objects both plans hold are
  // the same (one object can be made again alone).
  const FamilyPlan more = PlanFamily(spec, 7, 5);
  std::string without_none = kSmall;
  without_none.erase(without_none.find("  - effect: none\n"), std::string("  - effect: none\n").size());
  const FamilySpec fewer = ParseFamilySpec(without_none, "small.yaml");
  ASSERT_EQ(fewer.cells.size(), spec.cells.size() - 1);
  const FamilyPlan less = PlanFamily(fewer, 7, 3);
  const auto find = [](const FamilyPlan& p, const std::string& id) -> const FamilyObject* {
    for (const FamilyObject& o : p.objects) {
      if (o.id == id) return &o;
    }
    return nullptr;
  };
  for (const FamilyObject& o : plan.objects) {
    const FamilyObject* m = find(more, o.id);
    ASSERT_NE(m, nullptr) << o.id;
    EXPECT_EQ(ScenarioToYaml(m->scenarios[1]), ScenarioToYaml(o.scenarios[1])) << o.id;
    const FamilyObject* l = find(less, o.id);
    EXPECT_EQ(l == nullptr, o.cell.name == "none") << o.id;
    if (l != nullptr) {
      EXPECT_EQ(ScenarioToYaml(l->scenarios[0]), ScenarioToYaml(o.scenarios[0])) << o.id;
    }
  }
}

TEST(Family, HeldOutPushDiffersFromTheTrainedOneInThePushOnly) {
  const FamilyPlan plan = PlanFamily(Small(), 7, 3);
  for (const FamilyObject& o : plan.objects) {
    Scenario a = o.scenarios[0], b = o.scenarios[1];
    EXPECT_LT(a.push.position_fraction, 0.6) << o.id;
    EXPECT_GT(std::abs(b.push.position_fraction - 0.5), 0.19) << o.id;
    EXPECT_NE(a.seed, b.seed);
    b.push.position_fraction = a.push.position_fraction;
    b.name = a.name;
    b.seed = a.seed;
    b.notes = a.notes;
    EXPECT_EQ(ScenarioToYaml(a), ScenarioToYaml(b)) << o.id;
  }
}

TEST(Family, FramesLastTheTimelineAndTheTail) {
  const FamilyPlan plan = PlanFamily(Small(), 7, 3);
  for (const FamilyObject& o : plan.objects) {
    const Scenario& s = o.scenarios[0];
    const double timeline = s.push.delay_s + s.push.approach_s + s.push.hold_s + s.push.retract_s;
    EXPECT_GE(s.frames, std::ceil(s.fps * (timeline + 0.5) - 1e-9)) << o.id;
    EXPECT_LE(s.frames, std::ceil(s.fps * (timeline + 1.0) - 1e-9)) << o.id;
  }
}

TEST(Family, CellsGetTheirEffectAndParameters) {
  const FamilyPlan plan = PlanFamily(Small(), 7, 3);
  for (const FamilyObject& o : plan.objects) {
    const Scenario& s = o.scenarios[0];
    if (o.cell.name == "none") {
      EXPECT_TRUE(s.effects.EnabledNames().empty()) << o.id;
    } else if (o.cell.name == "plasticity-clear") {
      ASSERT_TRUE(s.effects.plasticity) << o.id;
      EXPECT_GE(s.effects.plasticity->yield_strain, 0.035);
      EXPECT_LE(s.effects.plasticity->yield_strain, 0.045);
      EXPECT_EQ(s.effects.EnabledNames().size(), 1u);
    } else {
      ASSERT_TRUE(s.effects.strong_friction) << o.id;
      EXPECT_GE(s.material.density_kg_m3, 400.0);  // the cell's own sample
    }
  }
}

TEST(Family, ColoursThatDoNotSeparateAreDrawnAgain) {
  const std::string grey_or_yellow = R"(
sample:
  camera: {object_rgb: {choices: [[128, 128, 128], [225, 200, 40]]}}
cells: [{effect: none}]
)";
  const FamilySpec spec = ParseFamilySpec(grey_or_yellow, "colours.yaml");
  const FamilyPlan plan = PlanFamily(spec, 3, 12);
  for (const FamilyObject& o : plan.objects) {
    EXPECT_EQ(o.scenarios[0].camera.object_rgb, (std::array<int, 3>{225, 200, 40})) << o.id;
  }
  const FamilySpec never = ParseFamilySpec("sample: {camera: {object_rgb: [128, 128, 128]}}\ncells: [{effect: none}]\n",
                                           "grey.yaml");
  const std::string error = testing::ErrorOf<FamilyError>([&] { PlanFamily(never, 3, 1); });
  testing::ExpectMessageNames(error, "", {"grey.yaml", "object none-00", "no colours that separate", "object_rgb"});
}

TEST(Family, ManifestHasTheAgreedShape) {
  const FamilyPlan plan = PlanFamily(Small(), 7, 2);
  const auto doc = nlohmann::json::parse(FamilyManifestJson(plan));
  EXPECT_EQ(doc["format"], "calib-family/1");
  EXPECT_EQ(doc["name"], "small");
  EXPECT_EQ(doc["spec"], "small.yaml");
  EXPECT_EQ(doc["seed"], 7);
  EXPECT_EQ(doc["count"], 2);
  ASSERT_EQ(doc["objects"].size(), 6u);
  const std::set<std::string> keys{"id",        "cell",        "effect",     "loop_effect",
                                   "magnitude", "confusable_with", "recordings", "scenario"};
  for (const auto& o : doc["objects"]) {
    std::set<std::string> found;
    for (const auto& [k, v] : o.items()) found.insert(k);
    EXPECT_EQ(found, keys);
    ASSERT_EQ(o["recordings"].size(), 2u);
    EXPECT_EQ(o["recordings"][0], o["id"].get<std::string>() + "/push-a");
    EXPECT_EQ(o["recordings"][1], o["id"].get<std::string>() + "/push-b");
    EXPECT_TRUE(o["scenario"].contains("shape"));
    EXPECT_TRUE(o["scenario"].contains("law"));
    EXPECT_TRUE(o["scenario"].contains("camera"));
  }
  const auto& none = doc["objects"][0];
  EXPECT_EQ(none["id"], "none-00");
  EXPECT_TRUE(none["effect"].is_null());
  EXPECT_TRUE(none["loop_effect"].is_null());
  EXPECT_TRUE(none["magnitude"].is_null());
  const auto& friction = doc["objects"][4];
  EXPECT_EQ(friction["cell"], "friction-holds-dent");
  EXPECT_EQ(friction["effect"], "strong_friction");
  EXPECT_EQ(friction["loop_effect"], "table_friction");
  EXPECT_EQ(friction["magnitude"], "clear");
  EXPECT_EQ(friction["confusable_with"], "plasticity");
  EXPECT_EQ(friction["scenario"]["effects"]["strong_friction"]["coefficient"],
            friction["scenario"]["friction_coefficient"]);
}

TEST(Family, LoopNamesOfEffects) {
  EXPECT_EQ(LoopEffectName("strong_friction"), "table_friction");
  EXPECT_EQ(LoopEffectName("table_friction"), "table_friction");
  EXPECT_EQ(LoopEffectName("viscoelastic"), "viscoelastic");
  EXPECT_THROW(LoopEffectName("inertia_gravity"), std::invalid_argument);
}

// ---------------------------------------------------------------- writing

TEST(Family, PlanWritesTheManifestAndScenarioFilesOnly) {
  const auto dir = testing::ScratchDir("family_plan");
  const FamilySpec spec = Small();
  const FamilyPlan plan = PlanFamily(spec, 7, 2);
  FamilyOptions options;
  options.plan_only = true;
  const FamilySummary summary = MakeFamily(plan, dir, options);
  EXPECT_EQ(summary.objects, 6);
  EXPECT_EQ(summary.recordings, 0);
  EXPECT_EQ(testing::ReadText(dir / "family.json"), FamilyManifestJson(plan));
  for (const FamilyObject& o : plan.objects) {
    for (size_t r = 0; r < 2; ++r) {
      const fs::path file = dir / o.id / (o.recordings[r] + ".yaml");
      ASSERT_TRUE(fs::exists(file)) << file;
      EXPECT_FALSE(fs::exists(dir / o.id / o.recordings[r])) << "a plan renders nothing";
      EXPECT_EQ(ScenarioToYaml(LoadScenario(file)), ScenarioToYaml(o.scenarios[r])) << file;
    }
  }
  // --only: that object's files, the whole manifest; an unknown id is named.
  const auto one = testing::ScratchDir("family_plan_one");
  options.only = "plasticity-clear-01";
  EXPECT_EQ(MakeFamily(plan, one, options).objects, 1);
  EXPECT_TRUE(fs::exists(one / "plasticity-clear-01" / "push-b.yaml"));
  EXPECT_FALSE(fs::exists(one / "none-00"));
  EXPECT_EQ(testing::ReadText(one / "family.json"), FamilyManifestJson(plan));
  options.only = "plasticity-clear-07";
  const std::string error = testing::ErrorOf<FamilyError>([&] { MakeFamily(plan, one, options); });
  testing::ExpectMessageNames(error, "", {"plasticity-clear-07", "no such object", "plasticity-clear-01"});
}

// A recording the truth model cannot make leaves its object out (its other
// recordings are not attempted), with the reason in the summary and in
// family.json; every other object is made. Re-making one object keeps the
// other objects' marks; re-making the object left out clears its own.
TEST(Family, ARecordingThatCannotBeMadeLeavesItsObjectOutAndTheOthersAreMade) {
  const auto dir = testing::ScratchDir("family_not_made");
  const FamilyPlan plan = PlanFamily(Small(), 7, 2);
  std::vector<std::string> attempted;
  FamilyOptions options;
  options.synthesize = [&](const Scenario&, const fs::path& out) {
    const std::string id = out.parent_path().filename().string(), recording = out.filename().string();
    attempted.push_back(id + "/" + recording);
    if (id + "/" + recording == "plasticity-clear-01/push-b" || id + "/" + recording == "none-00/push-a") {
      throw std::runtime_error("SimulateTruth: frame 113: a quasi-static step did not converge");
    }
    fs::create_directories(out);
    return SynthesisSummary{};
  };
  const FamilySummary summary = MakeFamily(plan, dir, options);
  EXPECT_EQ(summary.objects, 6);
  EXPECT_EQ(summary.recordings, 6 * 2 - 3) << "push-a of plasticity-clear-01 made, none-00 neither";
  EXPECT_EQ(std::count(attempted.begin(), attempted.end(), "none-00/push-b"), 0)
      << "the object is out once a recording fails";
  EXPECT_EQ(attempted.size(), 6u * 2 - 1);
  const std::map<std::string, std::string> expected = {
      {"none-00", "push-a: SimulateTruth: frame 113: a quasi-static step did not converge"},
      {"plasticity-clear-01", "push-b: SimulateTruth: frame 113: a quasi-static step did not converge"}};
  EXPECT_EQ(summary.not_made, expected);
  EXPECT_EQ(testing::ReadText(dir / "family.json"), FamilyManifestJson(plan, expected));
  const auto manifest = nlohmann::json::parse(testing::ReadText(dir / "family.json"));
  int marked = 0;
  for (const auto& o : manifest["objects"]) marked += o.contains("not_made") ? 1 : 0;
  EXPECT_EQ(marked, 2);

  // --only another object: the marks stay.
  options.only = "plasticity-clear-00";
  EXPECT_TRUE(MakeFamily(plan, dir, options).not_made.empty());
  EXPECT_EQ(testing::ReadText(dir / "family.json"), FamilyManifestJson(plan, expected));
  // --only the object left out, made this time: its mark goes.
  options.only = "none-00";
  options.synthesize = [](const Scenario&, const fs::path& out) {
    fs::create_directories(out);
    return SynthesisSummary{};
  };
  EXPECT_TRUE(MakeFamily(plan, dir, options).not_made.empty());
  EXPECT_EQ(testing::ReadText(dir / "family.json"),
            FamilyManifestJson(plan, {{"plasticity-clear-01", expected.at("plasticity-clear-01")}}));
  // Another plan (seed) in the folder: its marks are not this plan's.
  const FamilyPlan other = PlanFamily(Small(), 8, 2);
  EXPECT_TRUE(MakeFamily(other, dir, options).not_made.empty());
  EXPECT_EQ(testing::ReadText(dir / "family.json"), FamilyManifestJson(other));
}

// One object of a tiny family, synthesised: 10 frames on a coarse mesh in a
// small image (a few seconds).
TEST(Family, TinyObjectIsSynthesisedEndToEnd) {
  const FamilySpec spec = ParseFamilySpec(R"(
name: tiny
base:
  mm_per_px: 0.5
  push: {delay_s: 0, approach_s: 0.2, hold_s: 0.05, retract_s: 0.05, depth_mm: 6, start_gap_mm: 1}
  simulation: {fine_edge_px: 14}
  camera: {width_px: 320, height_px: 240}
tail_s: 0
sample:
  object: {one_of: [{shape: l_shape, cutout: {corner: far_right}}], rotation_deg: {min: -10, max: 10}}
  material: {law: hencky}
cells:
  - effect: plasticity
    magnitude: clear
    parameters: {yield_strain: 0.04}
)",
                                          "tiny.yaml");
  const FamilyPlan plan = PlanFamily(spec, 1, 1);
  const auto dir = testing::ScratchDir("family_tiny");
  FamilyOptions options;
  std::vector<std::string> lines;
  options.progress = [&](const std::string& line) { lines.push_back(line); };
  const FamilySummary summary = MakeFamily(plan, dir, options);
  EXPECT_EQ(summary.recordings, 2);
  EXPECT_EQ(lines.size(), 2u);
  for (const char* recording : {"push-a", "push-b"}) {
    const Recording rec = LoadRecording(dir / "plasticity-clear-00" / recording);
    EXPECT_EQ(rec.num_frames, 9);  // 0.3 s at 30 fps
    EXPECT_EQ(rec.frame_width, 320);
    ASSERT_EQ(rec.obstacles.size(), 2u);
    const auto truth = nlohmann::json::parse(testing::ReadText(dir / "plasticity-clear-00" / recording / "truth.json"));
    EXPECT_EQ(truth["effects"], nlohmann::json::array({"plasticity"}));
    EXPECT_EQ(truth["material"]["law"], "hencky");
    EXPECT_EQ(truth["scenario"]["object"]["shape"], "l_shape");
  }
}

}  // namespace
}  // namespace calib::synth
