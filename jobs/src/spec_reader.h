#pragma once
// Reading the job spec's YAML (jobs' private helper): MapReader reads one
// map, remembering the keys consumed so that the rest are reported as
// unknown, and every failure is a JobSpecError naming the source, the key
// path, the value and the rule: "<source>: <path> = <value>: <rule>".

#include "calib/jobs/job_spec.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace calib::spec_reader {

/// A value as messages show it: scalars quoted, maps and lists on one line
/// (shortened past 160 characters).
std::string Show(const YAML::Node& node);

/// Levenshtein distance (for "did you mean" hints).
size_t EditDistance(const std::string& a, const std::string& b);

/// A YAML value as JSON: quoted scalars are strings; plain ones integers,
/// numbers, booleans or null where they read as such.
nlohmann::json YamlToJson(const YAML::Node& n);

// Reads one YAML map, remembering the keys consumed so the rest are reported
// as unknown. Messages: "<source>: <path> = <value>: <rule>".
class MapReader {
 public:
  MapReader(YAML::Node node, std::string path, const std::string* source)
      : node_(std::move(node)), path_(std::move(path)), source_(source) {
    if (!node_.IsMap()) Fail(path_.empty() ? "(top level)" : path_, node_, "must be a map of keys");
  }

  std::string KeyPath(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }

  // Declares a key known (whether present or not) and returns its node.
  YAML::Node Get(const std::string& key) {
    if (std::find(known_.begin(), known_.end(), key) == known_.end()) known_.push_back(key);
    return node_[key];
  }
  bool Has(const std::string& key) {
    const YAML::Node n = Get(key);
    return n.IsDefined() && !n.IsNull();
  }
  YAML::Node Require(const std::string& key, const std::string& rule) {
    YAML::Node n = Get(key);
    if (!n.IsDefined() || n.IsNull()) Missing(KeyPath(key), rule);
    return n;
  }

  double Double(const std::string& key, const YAML::Node& n) const { return ToDouble(n, KeyPath(key)); }
  int64_t Int(const std::string& key, const YAML::Node& n) const { return ToInt(n, KeyPath(key)); }
  std::string String(const std::string& key, const YAML::Node& n) const {
    if (!n.IsScalar()) Fail(KeyPath(key), n, "expected a string");
    return n.Scalar();
  }
  bool Bool(const std::string& key, const YAML::Node& n) const {
    try {
      if (!n.IsScalar()) throw YAML::Exception({}, "");
      return n.as<bool>();
    } catch (const YAML::Exception&) {
      Fail(KeyPath(key), n, "expected true or false");
    }
  }

  void Read(const std::string& key, double* value) {
    if (Has(key)) *value = Double(key, node_[key]);
  }
  void Read(const std::string& key, int* value) {
    if (!Has(key)) return;
    const int64_t v = Int(key, node_[key]);
    if (v < INT32_MIN || v > INT32_MAX) Fail(KeyPath(key), node_[key], "expected a 32-bit integer");
    *value = static_cast<int>(v);
  }
  void Read(const std::string& key, int64_t* value) {
    if (Has(key)) *value = Int(key, node_[key]);
  }
  void Read(const std::string& key, bool* value) {
    if (Has(key)) *value = Bool(key, node_[key]);
  }
  void Read(const std::string& key, std::string* value) {
    if (Has(key)) *value = String(key, node_[key]);
  }

  // Throws for a key not declared known, suggesting the nearest known one.
  void Finish() const {
    for (const auto& kv : node_) {
      const std::string key = kv.first.Scalar();
      if (std::find(known_.begin(), known_.end(), key) != known_.end()) continue;
      std::string hint;
      size_t best = 3;
      for (const auto& k : known_) {
        const size_t d = EditDistance(key, k);
        if (d < best) {
          best = d;
          hint = fmt::format("; did you mean '{}'?", k);
        }
      }
      throw JobSpecError(fmt::format("{}: {} = {}: unknown key (known here: {}){}", *source_,
                                     KeyPath(key), Show(kv.second), fmt::join(known_, ", "), hint));
    }
  }

  [[noreturn]] void Fail(const std::string& key_path, const YAML::Node& n,
                         const std::string& rule) const {
    throw JobSpecError(fmt::format("{}: {} = {}: {}", *source_, key_path, Show(n), rule));
  }
  [[noreturn]] void Missing(const std::string& key_path, const std::string& rule) const {
    throw JobSpecError(fmt::format("{}: {}: missing; {}", *source_, key_path, rule));
  }

  double ToDouble(const YAML::Node& n, const std::string& key_path) const {
    double v = 0.0;
    try {
      if (!n.IsScalar()) throw YAML::Exception({}, "");
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      Fail(key_path, n, "expected a number");
    }
    if (!std::isfinite(v)) Fail(key_path, n, "must be finite");
    return v;
  }
  int64_t ToInt(const YAML::Node& n, const std::string& key_path) const {
    try {
      if (!n.IsScalar()) throw YAML::Exception({}, "");
      return n.as<int64_t>();
    } catch (const YAML::Exception&) {
      Fail(key_path, n, "expected an integer");
    }
  }

  const YAML::Node& node() const { return node_; }
  const std::string& source() const { return *source_; }

 private:
  YAML::Node node_;
  std::string path_;
  const std::string* source_;
  std::vector<std::string> known_;
};

}  // namespace calib::spec_reader
