#pragma once
// The loop benchmark's report (loop_benchmark.h, docs/loop.md "Loop
// benchmark"): the family, the command, every object's outcome and their
// aggregate, written as benchmark.json, benchmark.csv (one row per object)
// and benchmark.html (benchmark_html.h).

#include "calib/discovery/benchmark_aggregate.h"
#include "calib/discovery/benchmark_outcome.h"

#include <nlohmann/json_fwd.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace calib {

/// What benchmark.json holds: the family, the command, every object's
/// outcome (in manifest order) and, derived, their aggregate.
struct LoopBenchmarkReport {
  std::string family_dir;
  std::string family_name;
  std::string family_spec;
  uint64_t family_seed = 0;
  std::string command;
  std::vector<ObjectOutcome> outcomes;
  BenchmarkAggregate aggregate;  ///< AggregateOutcomes(outcomes, TracedEffects())
};

/// benchmark.json ("format": "calib-loop-benchmark/1"); NaN as null.
nlohmann::json ToJson(const LoopBenchmarkReport& report);
/// Reads what ToJson writes (the aggregate is recomputed from the
/// outcomes). Throws std::invalid_argument naming `source` and the key.
LoopBenchmarkReport LoopBenchmarkReportFromJson(const nlohmann::json& doc,
                                                const std::string& source);

/// benchmark.csv: OutcomeCsvHeader(TracedEffects()) and one row per object.
/// Throws std::runtime_error naming the path when it cannot be written.
void WriteBenchmarkCsv(const std::filesystem::path& path,
                       const std::vector<ObjectOutcome>& outcomes);

/// Writes `path` (ToJson). Throws std::runtime_error naming the path.
void WriteBenchmarkJson(const std::filesystem::path& path, const LoopBenchmarkReport& report);

}  // namespace calib
