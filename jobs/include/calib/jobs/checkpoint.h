#pragma once
// What the runner saves in a checkpoint (the JSON object kept by
// ResultStore::SaveCheckpoint) and reads back on resume.
//
// The optimiser's state (search::CheckedOptimizer::SaveState) holds its RNG,
// its counters and the outstanding candidates; the runner adds its own
// counters. The runner draws no random numbers of its own, so there is no
// runner RNG to save. Everything that decides the history is here; wall
// times are kept for reports only.

#include <nlohmann/json.hpp>

#include <cstdint>

namespace calib {

inline constexpr const char* kRunnerCheckpointFormat = "calib-runner-checkpoint/1";

struct RunnerCheckpoint {
  nlohmann::json optimizer;  ///< CheckedOptimizer::SaveState()
  /// Candidates told to the optimiser: always the ids [0, told).
  int64_t told = 0;
  /// Failed evaluations among them (the failure policy's abort counter).
  int64_t failed = 0;
  /// Wall time of every run and resume of the job up to this checkpoint.
  double run_seconds = 0.0;
  uint64_t seed = 0;  ///< the job's seed, checked on resume

  nlohmann::json ToJson() const;
  /// Throws std::invalid_argument naming the field when `state` is not a
  /// checkpoint of this format.
  static RunnerCheckpoint FromJson(const nlohmann::json& state);
};

}  // namespace calib
