#include "calib/jobs/checkpoint.h"

#include <fmt/format.h>

#include <stdexcept>
#include <string>

namespace calib {

nlohmann::json RunnerCheckpoint::ToJson() const {
  return {{"format", kRunnerCheckpointFormat},
          {"optimizer", optimizer},
          {"told", told},
          {"failed", failed},
          {"run_seconds", run_seconds},
          {"seed", seed}};
}

namespace {

const nlohmann::json& Field(const nlohmann::json& state, const char* key,
                            nlohmann::json::value_t type) {
  const auto it = state.find(key);
  if (it == state.end()) {
    throw std::invalid_argument(fmt::format("checkpoint: field '{}' is missing", key));
  }
  const bool ok = type == nlohmann::json::value_t::number_integer
                      ? it->is_number_integer()
                      : (type == nlohmann::json::value_t::number_float ? it->is_number()
                                                                       : it->type() == type);
  if (!ok) {
    throw std::invalid_argument(
        fmt::format("checkpoint: field '{}' = {} has the wrong type", key, it->dump()));
  }
  return *it;
}

}  // namespace

RunnerCheckpoint RunnerCheckpoint::FromJson(const nlohmann::json& state) {
  using V = nlohmann::json::value_t;
  if (!state.is_object()) throw std::invalid_argument("checkpoint: not a JSON object");
  const std::string format = Field(state, "format", V::string).get<std::string>();
  if (format != kRunnerCheckpointFormat) {
    throw std::invalid_argument(fmt::format("checkpoint: format '{}' is not '{}'", format,
                                            kRunnerCheckpointFormat));
  }
  RunnerCheckpoint cp;
  cp.optimizer = Field(state, "optimizer", V::object);
  cp.told = Field(state, "told", V::number_integer).get<int64_t>();
  cp.failed = Field(state, "failed", V::number_integer).get<int64_t>();
  cp.run_seconds = Field(state, "run_seconds", V::number_float).get<double>();
  cp.seed = Field(state, "seed", V::number_integer).get<uint64_t>();
  if (cp.told < 0 || cp.failed < 0 || cp.failed > cp.told) {
    throw std::invalid_argument(
        fmt::format("checkpoint: counters told = {}, failed = {} are inconsistent", cp.told,
                    cp.failed));
  }
  return cp;
}

}  // namespace calib
