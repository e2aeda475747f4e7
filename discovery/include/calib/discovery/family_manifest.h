#pragma once
// The manifest of a family of recordings, FAMILY_DIR/family.json (written by
// `calib synth --family`, read by `calib loop-benchmark`; docs/loop.md, "Loop
// benchmark"): per object the effect it has, under the loop's name, how
// strong, which effect it can be mistaken for, and its recordings (the first
// is trained on, the others held out).
//
//   {"format": "calib-family/1", "name": "...", "spec": "...", "seed": S, "count": N,
//    "objects": [{"id": "plasticity-clear-00", "cell": "plasticity-clear",
//                 "effect": "plasticity" | null, "loop_effect": "plasticity" | null,
//                 "magnitude": "clear" | "faint" | null, "confusable_with": "table_friction" |
//                 null, "recordings": ["plasticity-clear-00/push-a", "plasticity-clear-00/push-b"],
//                 "scenario": {...}}, ...]}
//
// An object the generator could not make carries "not_made": the recording
// and the reason (`calib synth --family` writes it and goes on with the
// others); its recordings need not exist, and the benchmark leaves it out.
// Other keys are allowed and ignored (the scenario is not read).

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace calib {

inline constexpr const char* kFamilyManifestFormat = "calib-family/1";

struct FamilyObject {
  std::string id;               ///< unique in the family; a plain folder name
  std::string cell;             ///< the group of objects made alike (effect and magnitude)
  std::string effect;           ///< the generator's name of the effect; empty: null
  std::string loop_effect;      ///< a TracedEffects() name; empty: no effect the loop names
  std::string magnitude;        ///< e.g. "clear", "faint"; empty: null
  std::string confusable_with;  ///< a TracedEffects() name; empty: null
  /// Recording folders relative to the family folder (or absolute); the
  /// first is trained on, the others are held out. At least one.
  std::vector<std::string> recordings;
  /// Why the generator could not make the object's recordings ("push-b:
  /// SimulateTruth: ..."); empty: made.
  std::string not_made;
};

struct FamilyManifest {
  std::filesystem::path dir;  ///< the family folder (recordings are relative to it)
  std::string name;
  std::string spec;
  uint64_t seed = 0;
  int64_t count = 0;
  std::vector<FamilyObject> objects;

  /// The folder of `object.recordings[i]`.
  std::filesystem::path RecordingPath(const FamilyObject& object, size_t i) const;
};

/// The manifest in `doc`, validated: the format, every key's type, ids
/// unique and usable as folder names, cells non-empty, loop effect names
/// known to the loop, at least one recording per object. Does not touch the
/// file system. Throws std::invalid_argument naming `source`, the object
/// (index and id) and the key, e.g.
///   "fam/family.json: objects[3] (id 'plasticity-faint-01').loop_effect = "plastic": not an effect
///    the loop traces (inertia, table_friction, ...)".
FamilyManifest FamilyManifestFromJson(const nlohmann::json& doc, const std::string& source,
                                      const std::filesystem::path& dir);

/// Reads and validates `family_dir`/family.json, and checks that every
/// recording folder of the objects made exists (a missing one is named
/// with its object and key). Throws std::invalid_argument (or
/// std::runtime_error for an unreadable file), naming the file.
FamilyManifest ReadFamilyManifest(const std::filesystem::path& family_dir);

}  // namespace calib
