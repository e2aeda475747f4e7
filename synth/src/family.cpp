// Drawing a family's scenarios, its manifest, and making its recordings.

#include "calib/synth/family.h"

#include "calib/synth/renderer.h"
#include "calib/synth/synthesize.h"
#include "family_trees.h"
#include "random.h"
#include "sample_tree.h"
#include "text_file.h"
#include "yaml_json.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <fstream>

namespace calib::synth {
namespace {

namespace fs = std::filesystem;

/// Draws of the camera section before a family gives up on separable colours.
constexpr int kColourAttempts = 100;
/// The recordings of each object: trained on, held out.
constexpr const char* kRecordings[] = {"push-a", "push-b"};

// The seed of the stream of `section` (a top-level scenario key, or
// "effects", "holdout", "tail_s", "seed-<recording>") of an object, for
// draw `attempt`.
uint64_t StreamSeed(uint64_t object_seed, const std::string& section, uint64_t attempt = 0) {
  return DeriveSeed(DeriveSeed(object_seed, NameStream(section)), attempt);
}

YAML::Node Draw(const YAML::Node& tree, uint64_t object_seed, const std::string& section,
                uint64_t attempt = 0) {
  SplitMix64 rng(StreamSeed(object_seed, section, attempt));
  return family_detail::Sample(tree, rng);
}

// The scenario values of one object: each top-level section of the sample
// tree from its own stream (the camera's from draw `camera_attempt`, a
// top-level one_of from its own), so that a section's draws do not move
// when another section changes.
YAML::Node DrawValues(const YAML::Node& sample, uint64_t object_seed, uint64_t camera_attempt) {
  YAML::Node values(YAML::NodeType::Map);
  if (!sample.IsMap()) return values;
  for (const auto& kv : sample) {
    const std::string key = kv.first.Scalar();
    if (key != "one_of") values[key] = Draw(kv.second, object_seed, key, key == "camera" ? camera_attempt : 0);
  }
  if (!sample["one_of"]) return values;
  YAML::Node alone(YAML::NodeType::Map);  // drawn last, laid over the rest (sample_tree.h)
  alone["one_of"] = YAML::Clone(sample["one_of"]);
  return family_detail::Merge(values, Draw(alone, object_seed, "one_of"));
}

// Parses a drawn scenario map; an invalid one is the spec's fault.
Scenario ParseDrawn(const YAML::Node& map, const std::string& where) {
  try {
    return ParseScenario(YAML::Dump(map), where + ": sampled scenario");
  } catch (const ScenarioError& e) {
    throw FamilyError(e.what());
  }
}

double DrawTail(const YAML::Node& tree, uint64_t object_seed, const std::string& where) {
  const YAML::Node tail = Draw(tree, object_seed, "tail_s");
  double value = -1.0;
  try {
    value = tail.as<double>();
  } catch (const YAML::Exception&) {
  }
  if (!(std::isfinite(value) && value >= 0.0)) {
    throw FamilyError(fmt::format("{}: tail_s = {}: expected a number >= 0 (seconds)", where, YAML::Dump(tail)));
  }
  return value;
}

// Frames that last the push's timeline and `tail_s` after it (at least 2).
int TimelineFrames(const Scenario& s, double tail_s) {
  const PushSpec& p = s.push;
  const double seconds = p.delay_s + p.approach_s + p.hold_s + p.retract_s + tail_s;
  return std::max(2, static_cast<int>(std::ceil(s.fps * seconds - 1e-9)));
}

std::string ObjectId(const std::string& cell, int index, int count) {
  int digits = 2;
  for (int n = count - 1; n >= 100; n /= 10) ++digits;
  return fmt::format("{}-{:0{}}", cell, index, digits);
}

// One object's scenarios: push-a from the drawn values, push-b with the
// held-out push laid over push-a's; colours drawn again until they separate.
FamilyObject PlanObject(const FamilySpec& spec, size_t cell_index, int index, uint64_t family_seed,
                        int count) {
  const FamilyCell& cell = spec.cells[cell_index];
  const FamilySpec::Trees::Cell& trees = spec.trees->cells[cell_index];
  FamilyObject object;
  object.id = ObjectId(cell.name, index, count);
  object.index = index;
  object.cell = cell;
  const uint64_t object_seed =
      DeriveSeed(DeriveSeed(family_seed, NameStream(cell.name)), static_cast<uint64_t>(index));
  const std::string where = fmt::format("{}: cell {}, object {}", spec.source, cell.name, object.id);
  const double tail_s = DrawTail(trees.tail_s, object_seed, where);
  std::string colour_error;
  for (int attempt = 0; attempt < kColourAttempts; ++attempt) {
    YAML::Node map = family_detail::Merge(spec.trees->base, DrawValues(trees.sample, object_seed, attempt));
    map["kind"] = "push";
    if (cell.effect) map["effects"][*cell.effect] = Draw(trees.parameters, object_seed, "effects");
    YAML::Node held_out = YAML::Clone(map);
    const YAML::Node& const_map = map;
    held_out["push"] = family_detail::Merge(const_map["push"] ? const_map["push"] : YAML::Node(YAML::NodeType::Map),
                                            Draw(trees.holdout, object_seed, "holdout"));
    std::vector<Scenario> scenarios;
    for (const YAML::Node& m : {map, held_out}) {
      const std::string recording = kRecordings[scenarios.size()];
      Scenario s = ParseDrawn(m, where + ", " + recording);
      s.name = object.id + "-" + recording;
      s.seed = StreamSeed(object_seed, "seed-" + recording) >> 33;
      s.frames = TimelineFrames(s, tail_s);
      const std::string given_notes = s.notes;
      s.notes = fmt::format("family {} ({}), seed {}, cell {}, object {}, {} ({}){}{}", spec.name,
                            spec.source, family_seed, cell.name, object.id, recording,
                            scenarios.empty() ? "trained on" : "held out",
                            given_notes.empty() ? "" : "; ", given_notes);
      std::string error;
      if (!s.IsValid(&error)) throw FamilyError(fmt::format("{}, {}: sampled scenario: {}", where, recording, error));
      scenarios.push_back(std::move(s));
    }
    if (!ColoursSeparate(scenarios.front().camera, &colour_error)) continue;
    object.scenarios = std::move(scenarios);
    object.recordings.assign(std::begin(kRecordings), std::end(kRecordings));
    return object;
  }
  throw FamilyError(fmt::format("{}: no colours that separate in {} draws of the camera; the last: {}",
                                where, kColourAttempts, colour_error));
}

nlohmann::ordered_json Summary(const FamilyObject& object) {
  const Scenario& a = object.scenarios.front();
  const nlohmann::json yaml = YamlToJson(YAML::Load(ScenarioToYaml(a)));
  nlohmann::ordered_json s;
  s["shape"] = ToString(a.object.shape);
  s["object"] = yaml["object"];
  s["law"] = ToString(a.material.law);
  s["youngs_modulus_pa"] = a.material.youngs_modulus_pa;
  s["poisson_ratio"] = a.material.poisson_ratio;
  s["density_kg_m3"] = a.material.density_kg_m3;
  s["friction_coefficient"] = a.effects.strong_friction ? a.effects.strong_friction->coefficient
                                                        : a.environment.friction_coefficient;
  s["effects"] = yaml["effects"];
  s["mm_per_px"] = a.mm_per_px;
  s["fps"] = a.fps;
  s["fine_edge_px"] = a.simulation.fine_edge_px;
  s["substeps"] = a.simulation.substeps;
  s["camera"] = yaml["camera"];
  nlohmann::ordered_json pushes = nlohmann::ordered_json::array();
  for (size_t r = 0; r < object.scenarios.size(); ++r) {
    const Scenario& sr = object.scenarios[r];
    pushes.push_back({{"recording", object.id + "/" + object.recordings[r]},
                      {"scenario_file", object.id + "/" + object.recordings[r] + ".yaml"},
                      {"seed", sr.seed},
                      {"frames", sr.frames},
                      {"push", YamlToJson(YAML::Load(ScenarioToYaml(sr)))["push"]}});
  }
  s["pushes"] = pushes;
  return s;
}

}  // namespace

FamilyPlan PlanFamily(const FamilySpec& spec, uint64_t seed, int count) {
  FamilyPlan plan;
  plan.name = spec.name;
  plan.spec_path = spec.source;
  plan.seed = seed;
  plan.count = count;
  for (size_t c = 0; c < spec.cells.size(); ++c) {
    for (int i = 0; i < count; ++i) plan.objects.push_back(PlanObject(spec, c, i, seed, count));
  }
  return plan;
}

std::string FamilyManifestJson(const FamilyPlan& plan, const std::map<std::string, std::string>& not_made) {
  nlohmann::ordered_json objects = nlohmann::ordered_json::array();
  const auto or_null = [](const std::optional<std::string>& v) {
    return v ? nlohmann::ordered_json(*v) : nlohmann::ordered_json(nullptr);
  };
  for (const FamilyObject& o : plan.objects) {
    nlohmann::ordered_json recordings = nlohmann::ordered_json::array();
    for (const std::string& r : o.recordings) recordings.push_back(o.id + "/" + r);
    objects.push_back({{"id", o.id},
                       {"cell", o.cell.name},
                       {"effect", or_null(o.cell.effect)},
                       {"loop_effect", o.cell.effect ? nlohmann::ordered_json(LoopEffectName(*o.cell.effect))
                                                      : nlohmann::ordered_json(nullptr)},
                       {"magnitude", or_null(o.cell.magnitude)},
                       {"confusable_with", or_null(o.cell.confusable_with)},
                       {"recordings", recordings},
                       {"scenario", Summary(o)}});
    if (const auto it = not_made.find(o.id); it != not_made.end()) objects.back()["not_made"] = it->second;
  }
  const nlohmann::ordered_json manifest = {{"format", "calib-family/1"},
                                           {"name", plan.name},
                                           {"spec", plan.spec_path},
                                           {"seed", plan.seed},
                                           {"count", plan.count},
                                           {"objects", objects}};
  return manifest.dump(1) + "\n";
}

namespace {

// The not_made marks of an earlier family.json in `out_dir` made from the
// same plan (name, seed, count); none when there is none or it does not
// read (it is about to be rewritten).
std::map<std::string, std::string> EarlierNotMade(const fs::path& out_dir, const FamilyPlan& plan) {
  std::map<std::string, std::string> marks;
  std::error_code ec;
  if (!fs::is_regular_file(out_dir / "family.json", ec)) return marks;
  try {
    std::ifstream in(out_dir / "family.json", std::ios::binary);
    const nlohmann::json doc = nlohmann::json::parse(in);
    if (doc.value("name", "") != plan.name || doc.value("seed", uint64_t{0}) != plan.seed ||
        doc.value("count", int64_t{-1}) != plan.count) {
      return marks;
    }
    for (const nlohmann::json& o : doc.at("objects")) {
      if (o.contains("not_made") && o["not_made"].is_string()) {
        marks[o.at("id").get<std::string>()] = o["not_made"].get<std::string>();
      }
    }
  } catch (const std::exception&) {
    marks.clear();
  }
  return marks;
}

}  // namespace

FamilySummary MakeFamily(const FamilyPlan& plan, const fs::path& out_dir, const FamilyOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  std::vector<const FamilyObject*> chosen;
  for (const FamilyObject& o : plan.objects) {
    if (!options.only || o.id == *options.only) chosen.push_back(&o);
  }
  if (options.only && chosen.empty()) {
    std::string ids;
    for (const FamilyObject& o : plan.objects) ids += (ids.empty() ? "" : ", ") + o.id;
    throw FamilyError(fmt::format("--only {}: no such object in family {} (objects: {})", *options.only,
                                  plan.name, ids));
  }
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir)) {
    throw std::runtime_error(fmt::format("{}: cannot create the output folder", out_dir.string()));
  }
  // The objects made now lose their marks; the others keep them (--only).
  std::map<std::string, std::string> not_made;
  if (options.only) {
    not_made = EarlierNotMade(out_dir, plan);
    not_made.erase(*options.only);
  }
  WriteText(out_dir / "family.json", FamilyManifestJson(plan, not_made));
  std::function<SynthesisSummary(const Scenario&, const fs::path&)> synthesize = options.synthesize;
  if (!synthesize) synthesize = [](const Scenario& s, const fs::path& dir) { return Synthesize(s, dir); };
  FamilySummary summary;
  for (const FamilyObject* o : chosen) {
    const fs::path dir = out_dir / o->id;
    fs::create_directories(dir, ec);
    ++summary.objects;
    for (size_t r = 0; r < o->recordings.size(); ++r) {
      const std::string& recording = o->recordings[r];
      WriteText(dir / (recording + ".yaml"),
                fmt::format("# Family {} ({}), seed {}: object {}, {}. `calib synth THIS_FILE --out DIR`\n"
                            "# makes the recording {}/{} of the family again.\n",
                            plan.name, plan.spec_path, plan.seed, o->id, recording, o->id, recording) +
                    ScenarioToYaml(o->scenarios[r]));
      if (options.plan_only) {
        if (options.progress) options.progress(fmt::format("{}/{}.yaml", o->id, recording));
        continue;
      }
      SynthesisSummary s;
      try {
        s = synthesize(o->scenarios[r], dir / recording);
      } catch (const std::exception& e) {
        // One sampled scene the truth model cannot simulate must not cost
        // the family: the object is left out, with its reason.
        const std::string reason = fmt::format("{}: {}", recording, e.what());
        summary.not_made[o->id] = reason;
        not_made[o->id] = reason;
        if (options.progress) options.progress(fmt::format("{}/{}: not made: {}", o->id, recording, e.what()));
        break;
      }
      ++summary.recordings;
      summary.simulation_s += s.simulation_s;
      summary.rendering_s += s.rendering_s;
      summary.bytes += s.bytes;
      if (options.progress) options.progress(fmt::format("{}/{}: {}", o->id, recording, s.BriefReport()));
    }
  }
  if (!summary.not_made.empty()) WriteText(out_dir / "family.json", FamilyManifestJson(plan, not_made));
  summary.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace calib::synth
