// family.json of a family of recordings: a good manifest reads back field by
// field; each kind of bad input is an error naming the file, the object
// (index and id) and the key.

#include "calib/discovery/family_manifest.h"
#include "calib/discovery/hypotheses.h"

#include "support/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <functional>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json GoodManifest() {
  return json::parse(R"({
    "format": "calib-family/1", "name": "two-cells", "spec": "plasticity:clear,none", "seed": 7,
    "count": 1,
    "objects": [
      {"id": "plasticity-clear-00", "cell": "plasticity-clear", "effect": "plasticity",
       "loop_effect": "plasticity", "magnitude": "clear", "confusable_with": "table_friction",
       "recordings": ["plasticity-clear-00/push-a", "plasticity-clear-00/push-b"],
       "scenario": {"effects": {"plasticity": {}}}},
      {"id": "none-00", "cell": "none", "effect": null, "loop_effect": null, "magnitude": null,
       "confusable_with": null, "recordings": ["none-00/push-a", "none-00/push-b", "none-00/push-c"]}
    ]})");
}

// The message of FamilyManifestFromJson on `doc`, or "" when it reads.
std::string ErrorOf(const json& doc) {
  try {
    FamilyManifestFromJson(doc, "fam/family.json", "fam");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_NAMES(message, part) \
  EXPECT_NE((message).find(part), std::string::npos) << "message: " << (message)

TEST(FamilyManifest, ReadsEveryField) {
  const FamilyManifest m = FamilyManifestFromJson(GoodManifest(), "fam/family.json", "fam");
  EXPECT_EQ(m.name, "two-cells");
  EXPECT_EQ(m.spec, "plasticity:clear,none");
  EXPECT_EQ(m.seed, 7u);
  EXPECT_EQ(m.count, 1);
  ASSERT_EQ(m.objects.size(), 2u);
  const FamilyObject& p = m.objects[0];
  EXPECT_EQ(p.id, "plasticity-clear-00");
  EXPECT_EQ(p.cell, "plasticity-clear");
  EXPECT_EQ(p.effect, "plasticity");
  EXPECT_EQ(p.loop_effect, "plasticity");
  EXPECT_EQ(p.magnitude, "clear");
  EXPECT_EQ(p.confusable_with, "table_friction");
  EXPECT_EQ(p.recordings,
            (std::vector<std::string>{"plasticity-clear-00/push-a", "plasticity-clear-00/push-b"}));
  EXPECT_EQ(m.RecordingPath(p, 1), fs::path("fam/plasticity-clear-00/push-b"));
  const FamilyObject& n = m.objects[1];
  EXPECT_EQ(n.effect, "");
  EXPECT_EQ(n.loop_effect, "");
  EXPECT_EQ(n.magnitude, "");
  EXPECT_EQ(n.confusable_with, "");
  EXPECT_EQ(n.recordings.size(), 3u);
}

TEST(FamilyManifest, ReadsTheFileAndChecksTheRecordingFolders) {
  const fs::path dir = testing::ScratchDir("family_manifest_file");
  for (const char* r : {"plasticity-clear-00/push-a", "plasticity-clear-00/push-b",
                        "none-00/push-a", "none-00/push-b", "none-00/push-c"}) {
    fs::create_directories(dir / r);
  }
  std::ofstream(dir / "family.json") << GoodManifest().dump();
  EXPECT_EQ(ReadFamilyManifest(dir).objects.size(), 2u);

  fs::remove(dir / "none-00/push-c");
  try {
    ReadFamilyManifest(dir);
    FAIL() << "a missing recording folder was not named";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NAMES(message, (dir / "family.json").string());
    EXPECT_NAMES(message, "objects[1] (id 'none-00').recordings[2]");
    EXPECT_NAMES(message, "none-00/push-c");
    EXPECT_NAMES(message, "not found");
  }
}

// An object the generator could not make: its reason is read, and its
// recording folders need not exist; the other objects' still must.
TEST(FamilyManifest, AnObjectNotMadeNeedsNoRecordingFolders) {
  const fs::path dir = testing::ScratchDir("family_manifest_not_made");
  for (const char* r : {"none-00/push-a", "none-00/push-b", "none-00/push-c"}) fs::create_directories(dir / r);
  json doc = GoodManifest();
  doc["objects"][0]["not_made"] = "push-b: SimulateTruth: frame 113: no convergence";
  std::ofstream(dir / "family.json") << doc.dump();
  const FamilyManifest m = ReadFamilyManifest(dir);
  EXPECT_EQ(m.objects[0].not_made, "push-b: SimulateTruth: frame 113: no convergence");
  EXPECT_EQ(m.objects[1].not_made, "");

  doc["objects"][0]["not_made"] = nullptr;  // null: made
  std::ofstream(dir / "family.json") << doc.dump();
  try {
    ReadFamilyManifest(dir);
    FAIL() << "a missing recording folder of an object made was not named";
  } catch (const std::invalid_argument& e) {
    EXPECT_NAMES(std::string(e.what()), "objects[0] (id 'plasticity-clear-00').recordings[0]");
  }
}

TEST(FamilyManifest, AMissingOrMalformedFileIsNamed) {
  const fs::path dir = testing::ScratchDir("family_manifest_bad_file");
  try {
    ReadFamilyManifest(dir);
    FAIL() << "a missing family.json was not named";
  } catch (const std::runtime_error& e) {
    EXPECT_NAMES(std::string(e.what()), (dir / "family.json").string());
  }
  std::ofstream(dir / "family.json") << "{\"format\": ";
  try {
    ReadFamilyManifest(dir);
    FAIL() << "a file that is not JSON was not named";
  } catch (const std::invalid_argument& e) {
    EXPECT_NAMES(std::string(e.what()), (dir / "family.json").string());
    EXPECT_NAMES(std::string(e.what()), "not JSON");
  }
}

// One case per kind of bad input: the change to the good manifest and what
// the message must name.
struct BadCase {
  const char* name;
  std::function<void(json&)> change;
  std::vector<std::string> named;
};

TEST(FamilyManifest, EachKindOfBadInputNamesTheFileObjectAndKey) {
  const std::vector<BadCase> cases = {
      {"not an object",
       [](json& j) { j = json::array(); },
       {"fam/family.json", "expected an object"}},
      {"wrong format",
       [](json& j) { j["format"] = "calib-family/2"; },
       {"fam/family.json: format", "calib-family/2", "calib-family/1"}},
      {"missing name", [](json& j) { j.erase("name"); }, {"fam/family.json: name: missing"}},
      {"seed not a count",
       [](json& j) { j["seed"] = "seven"; },
       {"seed", "\"seven\"", "non-negative integer"}},
      {"count negative", [](json& j) { j["count"] = -1; }, {"count", "-1"}},
      {"objects not an array",
       [](json& j) { j["objects"] = json::object(); },
       {"objects", "not an array"}},
      {"no objects", [](json& j) { j["objects"] = json::array(); }, {"objects: empty"}},
      {"object not an object",
       [](json& j) { j["objects"][1] = 3; },
       {"objects[1]", "expected an object"}},
      {"missing cell",
       [](json& j) { j["objects"][1].erase("cell"); },
       {"objects[1] (id 'none-00').cell: missing"}},
      {"missing id", [](json& j) { j["objects"][0].erase("id"); }, {"objects[0].id: missing"}},
      {"id not a folder name",
       [](json& j) { j["objects"][0]["id"] = "a/b"; },
       {"objects[0] (id 'a/b').id", "not a folder name"}},
      {"duplicate id",
       [](json& j) { j["objects"][1]["id"] = "plasticity-clear-00"; },
       {"objects[1] (id 'plasticity-clear-00').id", "earlier object"}},
      {"unknown loop effect",
       [](json& j) { j["objects"][0]["loop_effect"] = "plastic"; },
       {"objects[0] (id 'plasticity-clear-00').loop_effect", "\"plastic\"",
        "not an effect the loop traces", "table_friction"}},
      {"effect not a string",
       [](json& j) { j["objects"][0]["effect"] = 1; },
       {"objects[0] (id 'plasticity-clear-00').effect", "not a string or null"}},
      {"magnitude missing",
       [](json& j) { j["objects"][0].erase("magnitude"); },
       {"objects[0] (id 'plasticity-clear-00').magnitude: missing"}},
      {"unknown confusable effect",
       [](json& j) { j["objects"][0]["confusable_with"] = "friction"; },
       {"objects[0] (id 'plasticity-clear-00').confusable_with", "\"friction\""}},
      {"confusable with itself",
       [](json& j) { j["objects"][0]["confusable_with"] = "plasticity"; },
       {"confusable_with", "own loop_effect"}},
      {"no recordings",
       [](json& j) { j["objects"][1]["recordings"] = json::array(); },
       {"objects[1] (id 'none-00').recordings: empty"}},
      {"recording not a string",
       [](json& j) { j["objects"][1]["recordings"][2] = 5; },
       {"objects[1] (id 'none-00').recordings[2]", "not a string"}},
      {"recording empty",
       [](json& j) { j["objects"][1]["recordings"][0] = ""; },
       {"objects[1] (id 'none-00').recordings[0]", "empty"}},
      {"not_made not a string",
       [](json& j) { j["objects"][1]["not_made"] = true; },
       {"objects[1] (id 'none-00').not_made", "not a string or null"}},
  };
  for (const BadCase& c : cases) {
    json doc = GoodManifest();
    c.change(doc);
    const std::string message = ErrorOf(doc);
    ASSERT_FALSE(message.empty()) << c.name << ": accepted";
    EXPECT_EQ(message.rfind("fam/family.json: ", 0), 0u) << c.name << ": " << message;
    for (const std::string& part : c.named) {
      EXPECT_NE(message.find(part), std::string::npos)
          << c.name << ": '" << part << "' not in: " << message;
    }
  }
}

TEST(FamilyManifest, OtherKeysAreIgnored) {
  json doc = GoodManifest();
  doc["generator"] = "calib synth 1.0";
  doc["objects"][0]["truth"] = {{"anything", 1}};
  EXPECT_EQ(ErrorOf(doc), "");
}

// The bundled example pairs as a family (examples/bundled/family.json, the
// input of the documented bundled-pairs benchmark): it reads, every
// recording folder is there, and each effect the loop traces has exactly
// one object, besides one without an effect.
TEST(FamilyManifest, TheBundledPairsAreAFamilyWithEveryTracedEffectOnce) {
  const FamilyManifest m = ReadFamilyManifest(std::filesystem::path(CALIB_SOURCE_DIR) / "examples" / "bundled");
  std::vector<std::string> effects;
  int without = 0;
  for (const FamilyObject& o : m.objects) {
    EXPECT_EQ(o.recordings.size(), 2u) << o.id;
    if (o.loop_effect.empty()) ++without;
    else effects.push_back(o.loop_effect);
  }
  EXPECT_EQ(without, 1);
  std::vector<std::string> traced = TracedEffects();
  traced.erase(std::remove(traced.begin(), traced.end(), "push_relaxation"), traced.end());
  std::sort(traced.begin(), traced.end());
  std::sort(effects.begin(), effects.end());
  EXPECT_EQ(effects, traced);
}

}  // namespace
}  // namespace calib
