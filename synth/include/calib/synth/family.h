#pragma once
// Scene families: many synthetic push recordings drawn at random from one
// spec, to tune the closed loop on one family and judge it on another, so
// that no threshold is tuned on the data it is judged on.
//
// A family spec (YAML, docs/scenario.md "Scene families") gives a base
// scenario, ranges and choices for what varies (shape, size, rotation, the
// push, the material law and its E and nu, the mesh, the table friction,
// the camera), a held-out push, and cells: an effect (or none) at a
// magnitude, sometimes one that another effect may be mistaken for, with the
// effect's parameter ranges. Each cell gets `count` objects; each object is
// pushed twice (push-a, trained on; push-b, held out: same object, material,
// effect and camera, another push position and depth).
//
// Everything random derives from (family seed, cell name, object index)
// through the synth RNG (random.h), one stream per top-level scenario
// section: the same spec and seed give the same scenarios bit for bit, and
// one object can be made again alone.

#include "calib/synth/scenario.h"
#include "calib/synth/synthesize.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib::synth {

/// A family spec that cannot be read or is malformed, or a sampled scenario
/// that is invalid; what() names the file and the key (and, for a sampled
/// scenario, the cell and object).
class FamilyError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The synth effects a cell may hold (Effects::EnabledNames's names, push
/// only): plasticity, uneven_stiffness, strain_stiffening, viscoelastic,
/// strong_friction.
const std::vector<std::string>& FamilyEffectNames();

/// The closed loop's name of a synth effect (kSignatures in
/// discovery/src/hypotheses.cpp): strong_friction -> table_friction, the
/// others as they are. Also accepts the loop's names (returned as they are).
/// Throws std::invalid_argument for a name neither knows.
std::string LoopEffectName(const std::string& effect);

/// One cell of a family: what its objects hold.
struct FamilyCell {
  std::string name;                            ///< e.g. "plasticity-clear", "none"
  std::optional<std::string> effect;           ///< a synth effect; empty: none
  std::optional<std::string> magnitude;        ///< "clear" or "faint"; empty for none
  std::optional<std::string> confusable_with;  ///< the loop's name of the effect it may be taken for
};

/// A parsed, validated family spec. The sampling trees are opaque here.
struct FamilySpec {
  std::string name;
  std::string source;        ///< the file it was read from (messages, manifest)
  uint64_t seed = 1;         ///< default family seed (the command's --seed overrides)
  int count = 1;             ///< default objects per cell (--count overrides)
  std::vector<FamilyCell> cells;
  struct Trees;              ///< base scenario, sample and holdout trees per cell
  std::shared_ptr<const Trees> trees;
};

/// Parses and validates a family spec from YAML text; `source` names it in
/// messages. Unknown keys, malformed ranges or choices, scenario keys that do
/// not exist, and a base scenario that is invalid throw FamilyError naming
/// source and key path.
FamilySpec ParseFamilySpec(const std::string& yaml_text, const std::string& source);

/// Reads `path` and parses it as ParseFamilySpec does.
FamilySpec LoadFamilySpec(const std::filesystem::path& path);

/// One object of a family with its recordings' scenarios.
struct FamilyObject {
  std::string id;                          ///< "<cell>-<index>", index zero-padded
  int index = 0;                           ///< within its cell
  FamilyCell cell;                         ///< its cell's labels
  std::vector<std::string> recordings;     ///< "push-a" (trained on), "push-b" (held out)
  std::vector<Scenario> scenarios;         ///< one per recording, valid, colours separable
};

/// Every object of a family: cells in spec order, `count` objects each.
struct FamilyPlan {
  std::string name;
  std::string spec_path;                   ///< as given (written into the manifest)
  uint64_t seed = 0;
  int count = 0;
  std::vector<FamilyObject> objects;
};

/// Samples every object's scenarios. Deterministic in (spec, seed, count);
/// an object's scenarios depend only on the spec, the seed, its cell's name
/// and its index. Colours that ColoursSeparate rejects are drawn again (from
/// the next stream of the camera section, up to 100 times). Throws
/// FamilyError naming the spec file, cell, object and scenario key for a
/// sampled scenario that is invalid.
FamilyPlan PlanFamily(const FamilySpec& spec, uint64_t seed, int count);

/// The manifest (family.json, format calib-family/1) of `plan`: name, spec,
/// seed, count and per object its id, cell, effect (synth name or null),
/// loop_effect, magnitude, confusable_with, recordings (relative to the
/// family folder; the first is trained on) and a summary of its sampled
/// scenario (shape, law, E, nu, friction, camera, effect parameters, the
/// pushes, the scenario files). An object named in `not_made` (id ->
/// reason) carries "not_made": the reason (the benchmark leaves it out).
std::string FamilyManifestJson(const FamilyPlan& plan,
                               const std::map<std::string, std::string>& not_made = {});

/// What MakeFamily wrote.
struct FamilySummary {
  int objects = 0;
  int recordings = 0;            ///< synthesised (0 for a plan only)
  double simulation_s = 0.0;     ///< summed over the recordings
  double rendering_s = 0.0;
  double total_s = 0.0;          ///< wall time of the whole call
  uint64_t bytes = 0;
  /// Objects of this call the generator could not make, id -> "recording:
  /// reason" (the truth model did not converge, a file could not be
  /// written); family.json marks them not_made.
  std::map<std::string, std::string> not_made;
};

struct FamilyOptions {
  /// Write family.json and the scenario files only: no simulation, no video.
  bool plan_only = false;
  /// Make only this object (its id); the manifest is written whole.
  std::optional<std::string> only;
  /// Called with a line after each recording (and each scenario file in a
  /// plan); may be empty.
  std::function<void(const std::string&)> progress;
  /// Makes one recording; empty: Synthesize. (Tests replace it.)
  std::function<SynthesisSummary(const Scenario&, const std::filesystem::path&)> synthesize;
};

/// Writes `plan` into `out_dir`: family.json, and per object
/// <id>/<recording>.yaml (the scenario, for `calib synth`) and, unless
/// plan_only, the recording folder <id>/<recording>/ (Synthesize). A
/// recording that cannot be made (Synthesize throws) leaves its object out:
/// the object's other recordings are not made, the reason goes into the
/// summary and family.json ("not_made"), and the other objects are made.
/// With `only`, the marks of the other objects in an earlier family.json of
/// the same plan (name, seed, count) are kept. Throws FamilyError for an
/// unknown `only` id, std::runtime_error when the folder or family.json
/// cannot be written.
FamilySummary MakeFamily(const FamilyPlan& plan, const std::filesystem::path& out_dir,
                         const FamilyOptions& options = {});

}  // namespace calib::synth
