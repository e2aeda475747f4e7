// Reading and checking family specs (docs/scenario.md, "Scene families").

#include "calib/core/yaml_map_reader.h"
#include "calib/synth/family.h"
#include "family_trees.h"
#include "sample_tree.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <sstream>
#include <utility>

namespace calib::synth {
namespace {

using yaml_reader::MapReader;

[[noreturn]] void RaiseFamilyError(const std::string& message) { throw FamilyError(message); }

/// Scenario keys the generator sets itself, and why.
constexpr std::array<std::pair<const char*, const char*>, 5> kGeneratorKeys{{
    {"name", "the generator names each recording <object id>-<recording>"},
    {"seed", "each recording's seed derives from the family seed, cell and object"},
    {"frames", "frames follow the timeline: delay, approach, hold, retract and tail_s"},
    {"effects", "effects come from the cells (cells[i].effect and cells[i].parameters)"},
    {"hang", "families are of pushes (kind push)"},
}};

bool NameIsValid(const std::string& name) {
  return !name.empty() && std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
  });
}

// Refuses the keys the generator sets in a scenario tree at `path`.
void RefuseGeneratorKeys(const YAML::Node& tree, const std::string& path, const MapReader& r) {
  if (!tree.IsMap()) return;
  for (const auto& [key, why] : kGeneratorKeys) {
    const YAML::Node n = tree[key];
    if (n) r.Fail(path + "." + key, n, std::string("not allowed here: ") + why);
  }
}

// Reads an optional sample tree `key` of `r`, checked against `schema`;
// a tree of scenario keys first refuses the keys the generator sets.
YAML::Node ReadTree(MapReader& r, const std::string& key, const YAML::Node& schema,
                    bool scenario_keys = false) {
  if (!r.Has(key)) return YAML::Node();
  const YAML::Node tree = r.Get(key);
  if (scenario_keys) RefuseGeneratorKeys(tree, r.KeyPath(key), r);
  family_detail::CheckTree(tree, schema, r.KeyPath(key), r.source());
  return tree;
}

// The base scenario: scenario keys only (notes too), kind push, valid as a
// scenario.
YAML::Node ReadBase(MapReader& top, const YAML::Node& schema) {
  YAML::Node base(YAML::NodeType::Map);
  if (!top.Has("base")) return base;
  const YAML::Node given = top.Get("base");
  if (!given.IsMap()) top.Fail("base", given, "expected a scenario (a map of keys, docs/scenario.md)");
  RefuseGeneratorKeys(given, "base", top);
  base = YAML::Clone(given);
  if (base["kind"]) {
    if (!base["kind"].IsScalar() || base["kind"].Scalar() != "push") {
      top.Fail("base.kind", base["kind"], "families are of pushes: kind push");
    }
    base.remove("kind");
  }
  family_detail::CheckTree(base, schema, "base", top.source());
  for (const auto& kv : base) {
    if (family_detail::IsRange(kv.second) || family_detail::IsChoice(kv.second)) {
      top.Fail("base." + kv.first.Scalar(), kv.second, "the base holds fixed values; ranges go in sample");
    }
  }
  YAML::Node scenario = YAML::Clone(base);
  scenario["kind"] = "push";
  try {
    ParseScenario(YAML::Dump(scenario), top.source() + ": base");
  } catch (const ScenarioError& e) {
    throw FamilyError(e.what());
  }
  return base;
}

FamilyCell ReadCellLabels(MapReader& c) {
  FamilyCell cell;
  const YAML::Node effect = c.Require("effect", "the cell's effect, or none");
  const std::string effect_name = c.String("effect", effect);
  const auto& names = FamilyEffectNames();
  if (effect_name != "none") {
    if (std::find(names.begin(), names.end(), effect_name) == names.end()) {
      std::string list;
      for (const auto& n : names) list += n + ", ";
      c.Fail(c.KeyPath("effect"), effect, "expected " + list + "or none");
    }
    cell.effect = effect_name;
  }
  if (cell.effect) {
    const YAML::Node magnitude = c.Require("magnitude", "clear or faint, for a cell with an effect");
    const std::string m = c.String("magnitude", magnitude);
    if (m != "clear" && m != "faint") c.Fail(c.KeyPath("magnitude"), magnitude, "expected clear or faint");
    cell.magnitude = m;
  } else if (c.Has("magnitude")) {
    c.Fail(c.KeyPath("magnitude"), c.Get("magnitude"), "a cell without an effect has no magnitude");
  }
  if (c.Has("confusable_with")) {
    const YAML::Node n = c.Get("confusable_with");
    try {
      cell.confusable_with = LoopEffectName(c.String("confusable_with", n));
    } catch (const std::invalid_argument& e) {
      c.Fail(c.KeyPath("confusable_with"), n, e.what());
    }
    if (cell.effect && *cell.confusable_with == LoopEffectName(*cell.effect)) {
      c.Fail(c.KeyPath("confusable_with"), n, "the effect the cell holds cannot be confused with itself");
    }
  }
  cell.name = cell.effect ? *cell.effect + "-" + *cell.magnitude : "none";
  if (c.Has("name")) {
    cell.name = c.String("name", c.Get("name"));
    if (!NameIsValid(cell.name)) {
      c.Fail(c.KeyPath("name"), c.Get("name"), "letters, digits, _ - . only, non-empty");
    }
  }
  return cell;
}

}  // namespace

const std::vector<std::string>& FamilyEffectNames() {
  static const std::vector<std::string> names{"plasticity", "uneven_stiffness", "strain_stiffening",
                                              "viscoelastic", "strong_friction"};
  return names;
}

std::string LoopEffectName(const std::string& effect) {
  if (effect == "strong_friction") return "table_friction";
  static const std::vector<std::string> loop_names{"inertia",           "table_friction", "plasticity",
                                                   "uneven_stiffness",  "strain_stiffening",
                                                   "viscoelastic",      "push_relaxation"};
  if (std::find(loop_names.begin(), loop_names.end(), effect) != loop_names.end()) return effect;
  throw std::invalid_argument(fmt::format(
      "effect '{}' is unknown; expected a synth effect ({}) or a name of the loop's ({})", effect,
      "plasticity, uneven_stiffness, strain_stiffening, viscoelastic, strong_friction",
      "inertia, table_friction, plasticity, uneven_stiffness, strain_stiffening, viscoelastic, "
      "push_relaxation"));
}

namespace family_detail {

YAML::Node ScenarioSchema() {
  Scenario full = DefaultScenario(ScenarioKind::kPush);
  full.object.corner_radius_mm = 1.0;
  full.object.notch = NotchSpec{};
  full.object.cutout = CutoutSpec{};
  full.push.position_mm = 1.0;
  full.effects.plasticity = PlasticityEffect{};
  full.effects.uneven_stiffness = UnevenStiffnessEffect{};
  full.effects.uneven_stiffness->regions.push_back(StiffnessRegionSpec{});
  full.effects.strain_stiffening = StrainStiffeningEffect{};
  full.effects.viscoelastic = ViscoelasticEffect{};
  full.effects.strong_friction = StrongFrictionEffect{};
  YAML::Node schema = YAML::Load(ScenarioToYaml(full));
  return schema;
}

}  // namespace family_detail

FamilySpec ParseFamilySpec(const std::string& yaml_text, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    throw FamilyError(fmt::format("{}: not valid YAML: {}", source, e.what()));
  }
  if (root.IsNull()) throw FamilyError(fmt::format("{}: empty family spec", source));
  MapReader top(root, "", &source, &RaiseFamilyError);

  const YAML::Node full_schema = family_detail::ScenarioSchema();
  // What sample trees may name: the scenario's keys less the generator's
  // own and kind (the base's).
  YAML::Node schema = YAML::Clone(full_schema);
  for (const auto& [key, why] : kGeneratorKeys) schema.remove(key);
  schema.remove("kind");
  schema.remove("notes");

  FamilySpec spec;
  spec.source = source;
  spec.name = std::filesystem::path(source).stem().string();
  top.Read("name", &spec.name);
  if (!NameIsValid(spec.name)) top.Fail("name", top.Get("name"), "letters, digits, _ - . only, non-empty");
  top.Read("seed", &spec.seed);
  int64_t count = spec.count;
  top.Read("count", &count);
  if (count < 1 || count > 10000) top.Fail("count", top.Get("count"), "expected 1 <= count <= 10000");
  spec.count = static_cast<int>(count);

  auto trees = std::make_shared<FamilySpec::Trees>();
  YAML::Node base_schema = YAML::Clone(schema);
  base_schema["notes"] = full_schema["notes"];
  trees->base = ReadBase(top, base_schema);
  const YAML::Node sample = ReadTree(top, "sample", schema, true);
  const YAML::Node holdout = ReadTree(top, "holdout", schema["push"]);
  const YAML::Node tail = top.Has("tail_s") ? ReadTree(top, "tail_s", YAML::Node("0")) : YAML::Node("1.5");

  const YAML::Node cells = top.Require("cells", "a list of cells (effect, magnitude, parameters)");
  if (!cells.IsSequence() || cells.size() == 0) top.Fail("cells", cells, "expected a non-empty list of cells");
  for (size_t i = 0; i < cells.size(); ++i) {
    MapReader c = top.Nested(cells[i], fmt::format("cells[{}]", i));
    FamilyCell cell = ReadCellLabels(c);
    for (const FamilyCell& other : spec.cells) {
      if (other.name == cell.name) {
        c.Fail(c.KeyPath("name"), YAML::Node(cell.name),
               "two cells share this name (give each cell of the same effect and magnitude a name)");
      }
    }
    FamilySpec::Trees::Cell t;
    t.parameters = YAML::Node(YAML::NodeType::Map);
    if (c.Has("parameters")) {
      if (!cell.effect) c.Fail(c.KeyPath("parameters"), c.Get("parameters"), "a cell without an effect has none");
      const YAML::Node p = ReadTree(c, "parameters", full_schema["effects"][*cell.effect]);
      if (p.IsMap()) t.parameters = p;
    }
    t.sample = family_detail::Merge(sample, ReadTree(c, "sample", schema, true));
    t.holdout = family_detail::Merge(holdout, ReadTree(c, "holdout", schema["push"]));
    t.tail_s = c.Has("tail_s") ? ReadTree(c, "tail_s", YAML::Node("0")) : tail;
    c.Finish();
    spec.cells.push_back(std::move(cell));
    trees->cells.push_back(std::move(t));
  }
  top.Finish();
  spec.trees = std::move(trees);
  return spec;
}

FamilySpec LoadFamilySpec(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw FamilyError(fmt::format("{}: cannot open family spec", path.string()));
  std::stringstream text;
  text << in.rdbuf();
  return ParseFamilySpec(text.str(), path.string());
}

}  // namespace calib::synth
