// family.json of a family of recordings (family_manifest.h).

#include "calib/discovery/family_manifest.h"

#include "calib/discovery/hypotheses.h"
#include "json_io.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <set>
#include <stdexcept>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using json_io::Keys;

// A loop effect name or empty.
void CheckLoopEffect(const Keys& keys, const std::string& key, const std::string& name) {
  if (name.empty()) return;
  const std::vector<std::string>& known = TracedEffects();
  if (std::find(known.begin(), known.end(), name) == known.end()) {
    keys.Fail(key, fmt::format("\"{}\" is not an effect the loop traces ({})", name,
                               fmt::join(known, ", ")));
  }
}

FamilyObject ReadObject(const json& j, size_t index, const std::string& source,
                        std::set<std::string>* ids) {
  std::string where = fmt::format("objects[{}]", index);
  if (j.is_object() && j.contains("id") && j["id"].is_string()) {
    where += fmt::format(" (id '{}')", j["id"].get<std::string>());
  }
  const Keys keys(j, source, where);
  FamilyObject o;
  o.id = keys.Text("id");
  if (o.id.empty() || o.id == "." || o.id == ".." ||
      o.id.find_first_of("/\\") != std::string::npos) {
    keys.FailValue("id", "not a folder name (non-empty, no '/', not '.' or '..')");
  }
  if (!ids->insert(o.id).second) keys.FailValue("id", "the id of an earlier object too");
  o.cell = keys.Text("cell");
  if (o.cell.empty()) keys.FailValue("cell", "empty");
  o.effect = keys.TextOrNull("effect");
  o.loop_effect = keys.TextOrNull("loop_effect");
  CheckLoopEffect(keys, "loop_effect", o.loop_effect);
  o.magnitude = keys.TextOrNull("magnitude");
  o.confusable_with = keys.TextOrNull("confusable_with");
  CheckLoopEffect(keys, "confusable_with", o.confusable_with);
  if (!o.confusable_with.empty() && o.confusable_with == o.loop_effect) {
    keys.FailValue("confusable_with", "the object's own loop_effect");
  }
  o.recordings = keys.Texts("recordings");
  if (o.recordings.empty()) {
    keys.Fail("recordings", "empty; expected at least one (the first is trained on)");
  }
  for (size_t i = 0; i < o.recordings.size(); ++i) {
    if (o.recordings[i].empty()) keys.Fail(fmt::format("recordings[{}]", i), "empty folder path");
  }
  if (j.contains("not_made")) o.not_made = keys.TextOrNull("not_made");
  return o;
}

}  // namespace

fs::path FamilyManifest::RecordingPath(const FamilyObject& object, size_t i) const {
  return (dir / object.recordings.at(i)).lexically_normal();
}

FamilyManifest FamilyManifestFromJson(const json& doc, const std::string& source,
                                      const fs::path& dir) {
  const Keys top(doc, source, "");
  const std::string format = top.Text("format");
  if (format != kFamilyManifestFormat) {
    top.FailValue("format", fmt::format("not \"{}\"", kFamilyManifestFormat));
  }
  FamilyManifest m;
  m.dir = dir;
  m.name = top.Text("name");
  m.spec = top.Text("spec");
  m.seed = top.Count("seed");
  m.count = static_cast<int64_t>(top.Count("count"));
  const json& objects = top.Array("objects");
  if (objects.empty()) top.Fail("objects", "empty; expected at least one object");
  std::set<std::string> ids;
  for (size_t i = 0; i < objects.size(); ++i) {
    m.objects.push_back(ReadObject(objects[i], i, source, &ids));
  }
  return m;
}

FamilyManifest ReadFamilyManifest(const fs::path& family_dir) {
  const fs::path path = family_dir / "family.json";
  const json doc = json_io::ReadFile(path, "family manifest");
  FamilyManifest m = FamilyManifestFromJson(doc, path.string(), family_dir);
  for (size_t k = 0; k < m.objects.size(); ++k) {
    const FamilyObject& o = m.objects[k];
    if (!o.not_made.empty()) continue;
    for (size_t i = 0; i < o.recordings.size(); ++i) {
      const fs::path folder = m.RecordingPath(o, i);
      std::error_code ec;
      if (!fs::is_directory(folder, ec)) {
        throw std::invalid_argument(
            fmt::format("{}: objects[{}] (id '{}').recordings[{}]: recording folder {} not found",
                        path.string(), k, o.id, i, folder.string()));
      }
    }
  }
  return m;
}

}  // namespace calib
