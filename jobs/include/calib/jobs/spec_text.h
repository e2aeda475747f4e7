#pragma once
// What calib's spec formats share at the edge (job specs, comparison specs,
// the service's loop specs): the rule for names and the reading of the text.

#include <yaml-cpp/yaml.h>

#include <string>

namespace calib {

/// Whether `name` may name a job, a loop or a comparison: non-empty letters,
/// digits, '_', '-', '.'.
bool IsValidSpecName(const std::string& name);

/// YAML (or JSON) text as a document: UTF-8 text, valid YAML, and small once
/// its aliases are expanded, else a JobSpecError (job_spec.h) naming
/// `source`.
YAML::Node LoadSpecYaml(const std::string& text, const std::string& source);

}  // namespace calib
