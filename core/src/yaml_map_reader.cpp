#include "calib/core/yaml_map_reader.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace calib::yaml_reader {
namespace {

void SetFlowStyle(YAML::Node node) {
  if (!node.IsMap() && !node.IsSequence()) return;
  node.SetStyle(YAML::EmitterStyle::Flow);
  for (auto it = node.begin(); it != node.end(); ++it) SetFlowStyle(node.IsMap() ? it->second : *it);
}

}  // namespace

std::string Show(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "null";
  if (node.IsScalar()) return "'" + node.Scalar() + "'";
  YAML::Node copy = YAML::Clone(node);
  SetFlowStyle(copy);
  YAML::Emitter out;
  out << copy;
  std::string text = out.c_str();
  if (text.size() > 160) text = text.substr(0, 157) + "...";
  return text;
}

std::size_t EditDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

MapReader::MapReader(YAML::Node node, std::string path, const std::string* source, Raise raise,
                     EmptyValue empty)
    : node_(std::move(node)), path_(std::move(path)), source_(source), raise_(raise), empty_(empty) {
  if (!node_.IsMap()) Fail(path_.empty() ? "(top level)" : path_, node_, "must be a map of keys");
  // YAML (and JSON) readers keep one of two equal keys silently; a
  // duplicate is almost always an edit gone wrong, so it is an error.
  std::vector<std::string> seen;
  for (const auto& entry : node_) {
    if (!entry.first.IsScalar()) continue;
    const std::string& key = entry.first.Scalar();
    if (std::find(seen.begin(), seen.end(), key) != seen.end()) {
      Fail(KeyPath(key), entry.second, "the key appears more than once in its map");
    }
    seen.push_back(key);
  }
}

YAML::Node MapReader::Get(const std::string& key) {
  if (std::find(known_.begin(), known_.end(), key) == known_.end()) known_.push_back(key);
  return node_[key];
}

bool MapReader::Has(const std::string& key) {
  const YAML::Node n = Get(key);
  return n.IsDefined() && (empty_ == EmptyValue::kPresent || !n.IsNull());
}

YAML::Node MapReader::Require(const std::string& key, const std::string& rule) {
  YAML::Node n = Get(key);
  if (!n.IsDefined() || n.IsNull()) {
    // A key of the map that is nearly this one is a typo of it: say so
    // rather than only that the key is missing.
    for (const auto& kv : node_) {
      if (!kv.first.IsScalar()) continue;
      const std::string& found = kv.first.Scalar();
      if (found != key && EditDistance(found, key) <= 2) {
        Missing(KeyPath(key), fmt::format("{} (found '{}': a misspelling?)", rule, KeyPath(found)));
      }
    }
    Missing(KeyPath(key), rule);
  }
  return n;
}

MapReader MapReader::Child(const std::string& key) { return Nested(Get(key), KeyPath(key)); }

MapReader MapReader::OptionalChild(const std::string& key) {
  const YAML::Node n = Get(key);
  return Nested(n.IsNull() ? YAML::Node(YAML::NodeType::Map) : n, KeyPath(key));
}

MapReader MapReader::Nested(const YAML::Node& node, const std::string& key_path) const {
  return MapReader(node, key_path, source_, raise_, empty_);
}

std::string MapReader::String(const std::string& key, const YAML::Node& n) const {
  if (!n.IsScalar()) Fail(KeyPath(key), n, "expected a string");
  return n.Scalar();
}

bool MapReader::Bool(const std::string& key, const YAML::Node& n) const {
  try {
    if (!n.IsScalar()) throw YAML::Exception({}, "");
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    Fail(KeyPath(key), n, "expected true or false");
  }
}

void MapReader::Read(const std::string& key, double* value) {
  if (Has(key)) *value = Double(key, node_[key]);
}

void MapReader::Read(const std::string& key, std::optional<double>* value) {
  if (Has(key)) *value = Double(key, node_[key]);
}

void MapReader::Read(const std::string& key, int* value) {
  if (!Has(key)) return;
  const int64_t v = Int(key, node_[key]);
  if (v < INT32_MIN || v > INT32_MAX) Fail(KeyPath(key), node_[key], "expected a 32-bit integer");
  *value = static_cast<int>(v);
}

void MapReader::Read(const std::string& key, int64_t* value) {
  if (Has(key)) *value = Int(key, node_[key]);
}

void MapReader::Read(const std::string& key, uint64_t* value) {
  if (!Has(key)) return;
  const YAML::Node n = node_[key];
  try {
    if (!n.IsScalar() || n.Scalar().empty() || n.Scalar()[0] == '-') throw YAML::Exception({}, "");
    *value = n.as<uint64_t>();
  } catch (const YAML::Exception&) {
    Fail(KeyPath(key), n, "expected a non-negative integer");
  }
}

void MapReader::Read(const std::string& key, bool* value) {
  if (Has(key)) *value = Bool(key, node_[key]);
}

void MapReader::Read(const std::string& key, std::string* value) {
  if (Has(key)) *value = String(key, node_[key]);
}

void MapReader::Read(const std::string& key, Vec2* value) {
  if (!Has(key)) return;
  const YAML::Node n = node_[key];
  if (!n.IsSequence() || n.size() != 2) Fail(KeyPath(key), n, "expected a list of 2 numbers");
  for (int i = 0; i < 2; ++i) (*value)[i] = ToDouble(n[i], fmt::format("{}[{}]", KeyPath(key), i));
}

void MapReader::Read(const std::string& key, std::array<int, 3>* value) {
  if (!Has(key)) return;
  const YAML::Node n = node_[key];
  if (!n.IsSequence() || n.size() != 3) Fail(KeyPath(key), n, "expected a list of 3 integers");
  for (int i = 0; i < 3; ++i) {
    const std::string path = fmt::format("{}[{}]", KeyPath(key), i);
    const int64_t v = ToInt(n[i], path);
    if (v < INT32_MIN || v > INT32_MAX) Fail(path, n[i], "expected a 32-bit integer");
    (*value)[i] = static_cast<int>(v);
  }
}

void MapReader::Finish() const {
  for (const auto& kv : node_) {
    const std::string key = kv.first.Scalar();
    if (std::find(known_.begin(), known_.end(), key) != known_.end()) continue;
    std::string hint;
    std::size_t best = 3;
    for (const auto& k : known_) {
      const std::size_t d = EditDistance(key, k);
      if (d < best) {
        best = d;
        hint = fmt::format("; did you mean '{}'?", k);
      }
    }
    Throw(fmt::format("{}: {} = {}: unknown key (known here: {}){}", *source_, KeyPath(key),
                      Show(kv.second), fmt::join(known_, ", "), hint));
  }
}

void MapReader::Fail(const std::string& key_path, const YAML::Node& n, const std::string& rule) const {
  Throw(fmt::format("{}: {} = {}: {}", *source_, key_path, Show(n), rule));
}

void MapReader::Missing(const std::string& key_path, const std::string& rule) const {
  Throw(fmt::format("{}: {}: missing; {}", *source_, key_path, rule));
}

double MapReader::ToDouble(const YAML::Node& n, const std::string& key_path) const {
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

int64_t MapReader::ToInt(const YAML::Node& n, const std::string& key_path) const {
  try {
    if (!n.IsScalar()) throw YAML::Exception({}, "");
    return n.as<int64_t>();
  } catch (const YAML::Exception&) {
    Fail(key_path, n, "expected an integer");
  }
}

void MapReader::Throw(const std::string& message) const {
  raise_(message);
  throw std::logic_error("yaml_reader::MapReader: the Raise function returned: " + message);
}

}  // namespace calib::yaml_reader
