#pragma once
// A YAML document as JSON (private to synth: truth.json's scenario, the
// family manifest's summaries).

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

namespace calib::synth {

/// `node` as JSON: maps and lists as such, plain scalars as integers,
/// numbers or booleans where they read as such, quoted scalars as strings,
/// null for anything else.
nlohmann::json YamlToJson(const YAML::Node& node);

}  // namespace calib::synth
