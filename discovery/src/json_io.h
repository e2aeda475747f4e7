#pragma once
// The discovery library's JSON files (private helpers of family.json and
// the loop benchmark's summaries): reading and writing a whole file, and
// reading one JSON object with every failure naming the file, where in it,
// the key and what was found:
//   "<source>: <where>.<key>: missing"
//   "<source>: <where>.<key>: <value> is <rule>"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib::json_io {

/// The JSON document in `path`. Throws std::runtime_error when it cannot be
/// opened, std::invalid_argument when it is not JSON; both name the path
/// and `what` the file is.
inline nlohmann::json ReadFile(const std::filesystem::path& path, const std::string& what) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open the {}", path.string(), what));
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::invalid_argument(
        fmt::format("{}: the {} is not JSON: {}", path.string(), what, e.what()));
  }
}

/// Writes `doc` (indented by one space, as report.json). Throws
/// std::runtime_error naming the path.
inline void WriteFile(const std::filesystem::path& path, const nlohmann::json& doc) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  out << doc.dump(1) << '\n';
  if (!out) throw std::runtime_error(fmt::format("{}: write failed", path.string()));
}

/// A JSON value as messages show it (shortened past 80 characters).
inline std::string Shown(const nlohmann::json& v) {
  std::string s = v.dump();
  return s.size() > 80 ? s.substr(0, 77) + "..." : s;
}

class Keys {
 public:
  /// `source` must outlive the reader; `where` is the object's path in the
  /// document ("" at the top, "objects[3] (id 'x')").
  Keys(const nlohmann::json& map, const std::string& source, std::string where)
      : map_(map), source_(source), where_(std::move(where)) {
    if (!map_.is_object()) Fail("", "expected an object, found " + Shown(map_));
  }

  const std::string& where() const { return where_; }

  [[noreturn]] void Fail(const std::string& key, const std::string& what) const {
    std::string at = where_;
    if (!key.empty()) at += (at.empty() ? "" : ".") + key;
    throw std::invalid_argument(
        fmt::format("{}: {}{}", source_, at.empty() ? "" : at + ": ", what));
  }
  [[noreturn]] void FailValue(const std::string& key, const std::string& rule) const {
    Fail(key, fmt::format("{} is {}", Shown(map_.at(key)), rule));
  }

  const nlohmann::json& Required(const std::string& key) const {
    if (!map_.contains(key)) Fail(key, "missing");
    return map_.at(key);
  }
  std::string Text(const std::string& key) const {
    const nlohmann::json& v = Required(key);
    if (!v.is_string()) FailValue(key, "not a string");
    return v.get<std::string>();
  }
  /// A non-empty string, or null (read as ""); the key must be there.
  std::string TextOrNull(const std::string& key) const {
    const nlohmann::json& v = Required(key);
    if (v.is_null()) return "";
    if (!v.is_string() || v.get<std::string>().empty()) FailValue(key, "not a string or null");
    return v.get<std::string>();
  }
  uint64_t Count(const std::string& key) const {
    const nlohmann::json& v = Required(key);
    if (!v.is_number_unsigned()) FailValue(key, "not a non-negative integer");
    return v.get<uint64_t>();
  }
  /// A number, or null (read as NaN).
  double Number(const std::string& key) const {
    const nlohmann::json& v = Required(key);
    if (v.is_null()) return NAN;
    if (!v.is_number()) FailValue(key, "not a number or null");
    return v.get<double>();
  }
  bool Bool(const std::string& key) const {
    const nlohmann::json& v = Required(key);
    if (!v.is_boolean()) FailValue(key, "not true or false");
    return v.get<bool>();
  }
  const nlohmann::json& Array(const std::string& key) const {
    const nlohmann::json& v = Required(key);
    if (!v.is_array()) FailValue(key, "not an array");
    return v;
  }
  std::vector<std::string> Texts(const std::string& key) const {
    std::vector<std::string> out;
    const nlohmann::json& list = Array(key);
    for (size_t i = 0; i < list.size(); ++i) {
      if (!list[i].is_string())
        Fail(fmt::format("{}[{}]", key, i), Shown(list[i]) + " is not a string");
      out.push_back(list[i].get<std::string>());
    }
    return out;
  }
  /// The reader of the object at `key`[i] (or at `key` when i < 0).
  Keys Child(const std::string& key, int i = -1) const {
    const nlohmann::json& v = i < 0 ? Required(key) : Array(key).at(static_cast<size_t>(i));
    return Keys(v, source_, Path(i < 0 ? key : fmt::format("{}[{}]", key, i)));
  }

 private:
  std::string Path(const std::string& key) const {
    return where_.empty() ? key : where_ + "." + key;
  }

  const nlohmann::json& map_;
  const std::string& source_;
  std::string where_;
};

}  // namespace calib::json_io
