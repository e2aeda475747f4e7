#pragma once
// Reading the job spec's YAML (jobs' private helper): the project's YAML map
// reader (calib/core/yaml_map_reader.h) raising JobSpecError, a key without a
// value being as if left out, so every failure reads
// "<source>: <path> = <value>: <rule>"; and YAML values as JSON.

#include "calib/core/yaml_map_reader.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/spec_text.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <string>
#include <utility>

namespace calib::spec_reader {

using yaml_reader::Show;

/// A YAML value as JSON: quoted scalars are strings; plain ones integers,
/// numbers, booleans or null where they read as such.
nlohmann::json YamlToJson(const YAML::Node& n);

/// Whether `name` may name a job: non-empty letters, digits, '_', '-', '.'.
inline bool ValidName(const std::string& name) { return IsValidSpecName(name); }

using calib::LoadSpecYaml;

/// The text of a spec file; JobSpecError "<path>: cannot open <what>".
std::string ReadSpecFile(const std::filesystem::path& path, const char* what);

/// An optimiser map's settings as JSON (`settings`, and `command` for an
/// external optimiser, which goes into them); `path` names the map.
nlohmann::json ReadOptimizerSettings(yaml_reader::MapReader& o, const std::string& path, const std::string& name);

/// Throws JobSpecError(message).
[[noreturn]] void RaiseJobSpecError(const std::string& message);

// A map of the job spec: the shared reader with the job spec's error.
class MapReader : public yaml_reader::MapReader {
 public:
  MapReader(YAML::Node node, std::string path, const std::string* source)
      : yaml_reader::MapReader(std::move(node), std::move(path), source, &RaiseJobSpecError,
                               yaml_reader::EmptyValue::kAbsent) {}
};

}  // namespace calib::spec_reader
