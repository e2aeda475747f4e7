#pragma once
// The job spec: everything a calibration job needs, read from one YAML file
// (JSON is valid YAML; both are accepted) and validated completely before any
// work starts. The schema is documented in docs/job_spec.md; an example is
// examples/jobs/push_centre_cmaes.yaml.
//
// Every error is a JobSpecError whose message names the file, the field path
// (`parameters[2].upper`), the value found and the rule violated, e.g.
//   job.yaml: parameters[2].upper = 0.5: must be > lower (2)
// A spec with errors in several parts (name, recordings, model, each
// parameter, budget, optimiser, ...) is one JobSpecError naming all of them,
// one a line after "job.yaml: N errors:". A part that depends on another
// (the parameters on the model's effects, the optimiser on the budget and
// the parameters) is checked only when that one is sound.
//
// A job spec is a calibration request (calibration_request.h: the search
// space, optimiser, budget, seed, checkpoints, failure policy) plus the
// recordings, the model and where results go. This file's reader only
// parses and validates; the runner takes the request.

#include "calib/core/parameters.h"
#include "calib/core/simulator.h"
#include "calib/evaluator/evaluation.h"
#include "calib/jobs/calibration_request.h"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace YAML {
class Node;
}

namespace calib {

/// A malformed job spec; what() names the file, field path, value and rule.
class JobSpecError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The parameters a model can have: the base model's and, per optional model
/// effect (model.effects in the spec), the extra parameters it adds. A spec
/// must search or fix exactly the base parameters plus those of the effects
/// it names. Adding an effect is one entry in DefaultModelCatalog().
struct ModelCatalog {
  std::vector<ParameterSpec> base;                               ///< BaseModelParameterSpecs()
  std::map<std::string, std::vector<ParameterSpec>> effects;     ///< effect name -> extra specs

  /// base followed by each named effect's specs (in the order given).
  /// Precondition: every name is a key of `effects`.
  std::vector<ParameterSpec> ParameterSpecsFor(const std::vector<std::string>& effect_names) const;
};

/// The base model and every effect of core's EffectTermCatalogue() (effects.h).
const ModelCatalog& DefaultModelCatalog();

/// The model and its fixed settings.
struct ModelSpec {
  std::vector<std::string> effects;  ///< names from ModelCatalog::effects, no duplicates
  /// substeps, integrator, constraint_iterations, min_area_fraction,
  /// divergence_diameters (spec keys of the same names).
  SimulationOptions simulation;
  /// segmentation.{open_radius_px, close_radius_px, fill_holes},
  /// mesh.edge_length_px, outline_tolerance_px. cache_dir is not part of the
  /// spec: it keeps its default (the runner or command line may change it).
  PreparationOptions preparation;
};

struct ResultsSpec {
  /// The SQLite results store. Default: out/jobs/<name>.sqlite under the
  /// current folder (JobSpecParseOptions::results_root).
  std::filesystem::path store;
  /// Reports, best parameters, overlays. Default: out/jobs/<name>/.
  std::filesystem::path out_dir;
  /// Set when the spec gives no store: where builds before the out/ default
  /// put it (<spec folder>/results/<name>.sqlite), so that a job stored
  /// there is found and named rather than started again elsewhere.
  std::filesystem::path earlier_default_store;
};

/// The request's `name` is the job's (letters, digits, '_', '-', '.';
/// non-empty); its `parameters` hold every model parameter once, in spec
/// order.
struct JobSpec : CalibrationRequest {
  std::string source;                 ///< the file (or name) it was read from, for messages
  std::filesystem::path base_dir;     ///< absolute; relative paths were resolved against it
  std::vector<std::filesystem::path> train;    ///< recording folders, >= 1, resolved
  std::vector<std::filesystem::path> holdout;  ///< recording folders, may be empty, resolved
  ModelSpec model;
  int threads = 0;    ///< OpenMP threads; 0: all cores
  int processes = 1;  ///< MPI ranks the job is meant for (informational)
  ResultsSpec results;

  /// The model's parameter specs (base + effects) from the catalog the spec
  /// was validated against; what ValidateParameters and parameter files use.
  std::vector<ParameterSpec> parameter_specs;

  /// The request part.
  const CalibrationRequest& request() const { return *this; }
};

/// How recordings are checked while parsing.
enum class RecordingCheck {
  kNone,    ///< paths are resolved only (tests of other fields, stored specs)
  kExists,  ///< each folder exists and holds recording.json (default)
};

/// Values that replace the spec's (`calib run --name/--seed/--budget`),
/// checked by the spec's own rules and named as the field they replace.
struct JobSpecOverrides {
  std::optional<std::string> name;
  std::optional<uint64_t> seed;
  std::optional<int64_t> budget_evaluations;
};

struct JobSpecParseOptions {
  RecordingCheck recordings = RecordingCheck::kExists;
  JobSpecOverrides overrides;
  /// The default results.store is <results_root>/<name>.sqlite and
  /// results.out_dir <results_root>/<name>/; relative: to the current folder.
  std::filesystem::path results_root = "out/jobs";
  /// The catalog parameters and effects are validated against; null: the
  /// default catalog.
  const ModelCatalog* catalog = nullptr;
};

/// Reads and validates a job spec file. Relative paths in it are resolved
/// against the file's folder.
JobSpec LoadJobSpec(const std::filesystem::path& path, const JobSpecParseOptions& options = {});

/// Validates a spec given as YAML (or JSON) text. `source` names it in
/// messages; relative paths are resolved against `base_dir` (made absolute).
JobSpec ParseJobSpec(const std::string& text, const std::string& source,
                     const std::filesystem::path& base_dir, const JobSpecParseOptions& options = {});
/// From ToJson output (e.g. the spec kept in a results store), or any JSON
/// document of the schema.
JobSpec ParseJobSpec(const nlohmann::json& doc, const std::string& source,
                     const std::filesystem::path& base_dir, const JobSpecParseOptions& options = {});
/// From a parsed YAML document. (Another name than ParseJobSpec: YAML::Node
/// is incomplete here, and an overload on it would break calls with JSON.)
JobSpec ParseJobSpecYaml(const YAML::Node& root, const std::string& source,
                         const std::filesystem::path& base_dir,
                         const JobSpecParseOptions& options = {});

/// Loads every train and holdout recording (LoadRecording: recording.json,
/// track.csv, the video's frame count and size) and rethrows a failure as
/// JobSpecError naming the field (`holdout[0]`) and the recording's message.
/// The runner calls it before any work; ParseJobSpec only checks existence.
void CheckRecordings(const JobSpec& spec);
/// The same for recordings of another spec (a loop's), `source` naming it.
void CheckRecordings(const std::string& source, const std::vector<std::filesystem::path>& train,
                     const std::vector<std::filesystem::path>& holdout);

/// The canonical JSON of a spec: every field, defaults filled in, keys
/// sorted, paths relative to base_dir, doubles round-trip exact. Equal specs
/// give equal dumps, so the results store keeps it to detect a changed spec
/// on resume; ParseJobSpec(ToJson(spec), ..., spec.base_dir) gives the spec
/// back.
nlohmann::json ToJson(const JobSpec& spec);

}  // namespace calib
