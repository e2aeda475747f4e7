#pragma once
// The job spec: everything a calibration job needs, read from one YAML file
// (JSON is valid YAML; both are accepted) and validated completely before any
// work starts. The schema is documented in docs/job_spec.md; an example is
// examples/jobs/push_centre_cmaes.yaml.
//
// Every error is a JobSpecError whose message names the file, the field path
// (`parameters[2].upper`), the value found and the rule violated, e.g.
//   job.yaml: parameters[2].upper = 0.5: must be > lower (2)
//
// The search space: the optimiser searches the unit box [0, 1]^n, one
// coordinate per searched parameter in the order of `parameters`. Coordinate
// u maps to lower + u (upper - lower) on a linear scale and to
// exp(ln lower + u (ln upper - ln lower)) on a log scale (SearchSpace below).
// Optimiser settings that hold points (x0 of cmaes / nlopt) are therefore in
// unit-box coordinates.

#include "calib/core/parameters.h"
#include "calib/core/simulator.h"
#include "calib/evaluator/evaluation.h"
#include "calib/search/checked_optimizer.h"
#include "calib/search/types.h"

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

enum class ParameterScale { kLinear, kLog };
std::string ToString(ParameterScale scale);  ///< "linear" / "log"
/// Throws std::invalid_argument naming the value.
ParameterScale ParameterScaleFromString(const std::string& name);

/// One model parameter: searched within [lower, upper] (both finite,
/// lower < upper, inside the parameter's allowed range; log scale: lower > 0)
/// or held fixed at `fixed`.
struct ParameterSetting {
  std::string name;
  std::optional<double> fixed;  ///< set: not searched
  double lower = 0.0;           ///< searched only
  double upper = 0.0;           ///< searched only
  ParameterScale scale = ParameterScale::kLinear;

  bool searched() const { return !fixed.has_value(); }
};

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

struct OptimizerSpec {
  std::string name;  ///< a name search::OptimizerNames() lists
  /// What search::MakeOptimizer receives: the spec's settings object, plus
  /// the optimiser's own evaluation budget set to budget.evaluations when the
  /// spec leaves it out (max_evals for grid, random, annealing, cmaes;
  /// maxeval for nlopt:*; genetic's budget follows population and
  /// generations).
  nlohmann::json settings = nlohmann::json::object();
};

struct BudgetSpec {
  int64_t evaluations = 0;            ///< >= 1; the runner never evaluates more
  std::optional<double> wall_time_s;  ///< > 0 when set; the runner stops (resumably) after it
};

/// A checkpoint is written when either trigger fires (0 disables a trigger;
/// at least one is on). The runner checkpoints between batches.
struct CheckpointSpec {
  int64_t every_evaluations = 100;
  double every_seconds = 60.0;
};

enum class FailureMode {
  kPenalty,  ///< record the failure; tell the optimiser failed (or penalty_score)
  kRetry,    ///< re-evaluate up to max_retries times, then as kPenalty
  kAbort,    ///< as kPenalty, and stop the job after abort_after failures
};
std::string ToString(FailureMode mode);  ///< "penalty" / "retry" / "abort"
/// Throws std::invalid_argument naming the value.
FailureMode FailureModeFromString(const std::string& name);

/// What happens to a candidate whose evaluation failed (its simulation blew
/// up or its worker was lost). Every failure is recorded with its reason.
struct FailurePolicy {
  FailureMode mode = FailureMode::kPenalty;
  /// Unset: the optimiser is told the evaluation failed (worse than any
  /// finite score). Set (finite): the optimiser is told this score instead.
  std::optional<double> penalty_score;
  int max_retries = 1;      ///< kRetry: >= 1 further attempts
  int64_t abort_after = 0;  ///< stop the job after this many failed candidates; 0: never
                            ///< (kAbort: >= 1, default 1)
};

struct ResultsSpec {
  /// The SQLite results store. Default: <spec folder>/results/<name>.sqlite.
  std::filesystem::path store;
  /// Reports, best parameters, overlays. Default: <spec folder>/results/<name>.
  std::filesystem::path out_dir;
};

struct JobSpec {
  std::string source;                 ///< the file (or name) it was read from, for messages
  std::filesystem::path base_dir;     ///< absolute; relative paths were resolved against it
  std::string name;                   ///< letters, digits, '_', '-', '.'; non-empty
  std::vector<std::filesystem::path> train;    ///< recording folders, >= 1, resolved
  std::vector<std::filesystem::path> holdout;  ///< recording folders, may be empty, resolved
  ModelSpec model;
  std::vector<ParameterSetting> parameters;    ///< every model parameter once, in spec order
  OptimizerSpec optimizer;
  BudgetSpec budget;
  uint64_t seed = 1;
  int threads = 0;    ///< OpenMP threads; 0: all cores
  int processes = 1;  ///< MPI ranks the job is meant for (informational)
  CheckpointSpec checkpoint;
  FailurePolicy failure_policy;
  ResultsSpec results;

  /// The model's parameter specs (base + effects) from the catalog the spec
  /// was validated against; what ValidateParameters and parameter files use.
  std::vector<ParameterSpec> parameter_specs;

  /// The names of the searched parameters, in search-space order.
  std::vector<std::string> SearchedNames() const;
};

/// How recordings are checked while parsing.
enum class RecordingCheck {
  kNone,    ///< paths are resolved only (tests of other fields, stored specs)
  kExists,  ///< each folder exists and holds recording.json (default)
};

struct JobSpecParseOptions {
  RecordingCheck recordings = RecordingCheck::kExists;
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

/// The canonical JSON of a spec: every field, defaults filled in, keys
/// sorted, paths relative to base_dir, doubles round-trip exact. Equal specs
/// give equal dumps, so the results store keeps it to detect a changed spec
/// on resume; ParseJobSpec(ToJson(spec), ..., spec.base_dir) gives the spec
/// back.
nlohmann::json ToJson(const JobSpec& spec);

/// Maps the optimiser's unit box to parameter values and back.
class SearchSpace {
 public:
  /// From a validated spec's parameters.
  explicit SearchSpace(const std::vector<ParameterSetting>& parameters);
  explicit SearchSpace(const JobSpec& spec) : SearchSpace(spec.parameters) {}

  int dimension() const { return static_cast<int>(searched_.size()); }
  /// Searched parameter names, coordinate order.
  std::vector<std::string> names() const;
  /// [0, 1]^n.
  search::Bounds UnitBounds() const;

  /// Every parameter (searched and fixed) for the point u of the unit box
  /// (size dimension(); each coordinate clamped to [0, 1]). Results are
  /// clamped to [lower, upper] so rounding in exp/log never leaves the
  /// bounds; u = 0 and u = 1 give lower and upper exactly.
  ParameterValues ToParameters(std::span<const double> u) const;
  /// The unit-box point of the searched values in `values` (which must hold
  /// every searched name; std::invalid_argument otherwise). Values outside
  /// [lower, upper] map outside [0, 1].
  std::vector<double> ToUnit(const ParameterValues& values) const;

 private:
  struct Axis {
    std::string name;
    double lower, upper;
    bool log;
  };
  std::vector<Axis> searched_;
  ParameterValues fixed_;
};

/// The job's optimiser: search::MakeOptimizer(spec.optimizer.name,
/// spec.optimizer.settings, SearchSpace(spec).UnitBounds(), spec.seed).
search::CheckedOptimizer MakeJobOptimizer(const JobSpec& spec);

}  // namespace calib
