#pragma once
// The spec of an optimiser comparison (`calib compare-optimizers`,
// docs/compare.md): a job spec's objective (recordings, model, parameters,
// budget, threads, checkpoints, failure policy) without its `optimizer`,
// `seed` and `results`, plus
//   optimizers  a list of {name, label, settings}: the optimisers compared
//   seeds       an integer N (seeds 1..N, default 15) or a list of seeds
//   targets     {relative: [...]} (default [0.1, 0.03, 0.01, 0.003, 0.001]:
//               within that fraction of the best score any run found) or
//               {absolute: [...]} (scores)
// Each optimiser runs once per seed, as an ordinary job of the comparison's
// results store; an optimiser that ignores its seed
// (search::SeedIndependent: grid, DIRECT, ...) runs once, with the first.
//
// The whole spec is validated before any work, every run's job spec
// included: errors are JobSpecErrors naming the file, the key path
// (`optimizers[2].settings`), the value and the rule, as job specs do.

#include "calib/jobs/job_spec.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace calib {

/// One optimiser of the comparison.
struct ComparedOptimizer {
  std::string label;   ///< unique; letters, digits, '_', '-', '.'; default: name with ':' as '_'
  std::string name;    ///< a search::OptimizerNames() name
  nlohmann::json settings = nlohmann::json::object();  ///< as written (the budget filled in per run)
  bool seed_independent = false;  ///< search::SeedIndependent(name): runs once
};

enum class TargetKind { kRelative, kAbsolute };

/// The scores runs are asked to reach (fixed-target view).
struct ComparisonTargets {
  /// kRelative: score <= best + value * |best|, best over every run;
  /// kAbsolute: score <= value.
  TargetKind kind = TargetKind::kRelative;
  std::vector<double> values{0.1, 0.03, 0.01, 0.003, 0.001};
};

/// One run: an optimiser with a seed, as a job.
struct ComparisonRun {
  std::string label;  ///< ComparedOptimizer::label
  uint64_t seed = 0;
  JobSpec job;        ///< name "<comparison>.<label>.s<seed>"; results in the comparison's store
};

struct ComparisonSpec {
  std::string source;  ///< the file it was read from, for messages
  std::string name;
  std::vector<ComparedOptimizer> optimizers;  ///< >= 1, spec order
  std::vector<uint64_t> seeds;                ///< >= 1, distinct
  ComparisonTargets targets;
  int64_t budget_evaluations = 0;             ///< per run
  std::filesystem::path out_dir;              ///< absolute; default out/compare/<name>/
  std::filesystem::path store;                ///< <out_dir>/comparison.sqlite
  std::vector<ComparisonRun> runs;            ///< optimiser-major, then seed order

  /// The canonical JSON of the comparison (its keys and every run's
  /// canonical job spec), written beside the report.
  nlohmann::json ToJson() const;
};

/// Where a comparison's results go when no folder is given:
/// kDefaultComparisonRoot/<name>/, relative to the current folder (as every
/// output of calib has its default place under out/).
inline const std::filesystem::path kDefaultComparisonRoot = "out/compare";

/// Reads and validates a comparison spec; the runs' results go to
/// `out_dir` (the store `out_dir/comparison.sqlite`), or when it is empty to
/// kDefaultComparisonRoot/<name>/ (ComparisonSpec::out_dir says which).
/// Relative paths in the spec are resolved against its folder, or against
/// `base_dir` when it is not empty. `options` as for job specs.
ComparisonSpec LoadComparisonSpec(const std::filesystem::path& path,
                                  const std::filesystem::path& out_dir,
                                  const JobSpecParseOptions& options = {},
                                  const std::filesystem::path& base_dir = {});

/// The same from YAML (or JSON) text; `source` names it in messages.
ComparisonSpec ParseComparisonSpec(const std::string& text, const std::string& source,
                                   const std::filesystem::path& base_dir,
                                   const std::filesystem::path& out_dir,
                                   const JobSpecParseOptions& options = {});

}  // namespace calib
