#pragma once
// Reading the YAML input files (job specs, jobs/; scenarios, synth/) one map
// at a time, with every failure naming the file, the key path, the value and
// the rule:
//   "<source>: <path> = <value>: <rule>"       a value of the wrong type or breaking a rule
//   "<source>: <path>: missing; <rule>"         a required key left out
//   "<source>: <path> = <value>: unknown key (known here: a, b, ...); did you mean 'a'?"
// A MapReader remembers every key it was asked about (whether present or
// not), so that Finish reports the rest as unknown (a typo), suggesting the
// nearest known key. Each format throws its own error type: the reader of
// the top-level map is given a Raise function (throwing, say, JobSpecError),
// and the readers of nested maps inherit it. It lives in core, below both
// libraries that read YAML.

#include "calib/core/types.h"

#include <yaml-cpp/yaml.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace calib::yaml_reader {

/// Throws the format's error with `message`; must not return.
using Raise = void (*)(const std::string& message);

/// What a key written without a value (`key:` or `key: ~`) means.
enum class EmptyValue {
  kAbsent,   ///< as if the key were left out (job specs)
  kPresent,  ///< the key is there with nothing in it: a map reads as `{}`, a
             ///< number or string is an error (scenarios: `plasticity:` turns
             ///< the effect on with its defaults)
};

/// A value as messages show it: scalars quoted, maps and lists on one line
/// (shortened past 160 characters), a missing or empty value as null.
std::string Show(const YAML::Node& node);

/// Levenshtein distance (for "did you mean" hints).
std::size_t EditDistance(const std::string& a, const std::string& b);

// Reads one YAML map; see the top of this file.
class MapReader {
 public:
  /// `path`: the map's key path ("" at the top level); `source`: the file
  /// name messages start with (must outlive the reader). Raises "must be a
  /// map of keys" when `node` is not a map, and names a key that appears
  /// twice in it.
  MapReader(YAML::Node node, std::string path, const std::string* source, Raise raise,
            EmptyValue empty = EmptyValue::kAbsent);

  std::string KeyPath(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }

  /// Declares a key known (whether present or not) and returns its node.
  YAML::Node Get(const std::string& key);
  /// Declares the key known; whether the map has it (with a value, for
  /// EmptyValue::kAbsent).
  bool Has(const std::string& key);
  /// Declares the key known and returns its node; raises "missing; <rule>"
  /// when it is absent or has no value.
  YAML::Node Require(const std::string& key, const std::string& rule);

  /// The reader of the map under `key` (declared known).
  MapReader Child(const std::string& key);
  /// As Child, but `key:` without a value reads as an empty map.
  MapReader OptionalChild(const std::string& key);
  /// The reader of a map found elsewhere (in a list), named `key_path`.
  MapReader Nested(const YAML::Node& node, const std::string& key_path) const;

  /// The value of `n` (the node of `key`) as a type; raises naming the key.
  double Double(const std::string& key, const YAML::Node& n) const { return ToDouble(n, KeyPath(key)); }
  int64_t Int(const std::string& key, const YAML::Node& n) const { return ToInt(n, KeyPath(key)); }
  std::string String(const std::string& key, const YAML::Node& n) const;
  bool Bool(const std::string& key, const YAML::Node& n) const;

  /// Reads `key` into *value when the map has it (Has); leaves *value as
  /// it is otherwise.
  void Read(const std::string& key, double* value);
  void Read(const std::string& key, std::optional<double>* value);
  void Read(const std::string& key, int* value);  ///< a 32-bit integer
  void Read(const std::string& key, int64_t* value);
  void Read(const std::string& key, uint64_t* value);  ///< a non-negative integer
  void Read(const std::string& key, bool* value);
  void Read(const std::string& key, std::string* value);
  void Read(const std::string& key, Vec2* value);                ///< a list of 2 numbers
  void Read(const std::string& key, std::array<int, 3>* value);  ///< a list of 3 integers

  /// Raises for the first key of the map not declared known, suggesting the
  /// nearest known one.
  void Finish() const;

  [[noreturn]] void Fail(const std::string& key_path, const YAML::Node& n, const std::string& rule) const;
  [[noreturn]] void Missing(const std::string& key_path, const std::string& rule) const;

  /// A finite number / an integer, or a failure naming `key_path`.
  double ToDouble(const YAML::Node& n, const std::string& key_path) const;
  int64_t ToInt(const YAML::Node& n, const std::string& key_path) const;

  const YAML::Node& node() const { return node_; }
  const std::string& source() const { return *source_; }

 private:
  [[noreturn]] void Throw(const std::string& message) const;

  YAML::Node node_;
  std::string path_;
  const std::string* source_;
  Raise raise_;
  EmptyValue empty_;
  std::vector<std::string> known_;
};

}  // namespace calib::yaml_reader
