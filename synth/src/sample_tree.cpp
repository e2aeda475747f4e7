#include "sample_tree.h"

#include "calib/core/yaml_map_reader.h"
#include "calib/synth/family.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <exception>
#include <optional>
#include <vector>

namespace calib::synth::family_detail {
namespace {

using yaml_reader::Show;

[[noreturn]] void Fail(const std::string& source, const std::string& path, const YAML::Node& n,
                       const std::string& rule) {
  throw FamilyError(fmt::format("{}: {} = {}: {}", source, path, Show(n), rule));
}

std::string Join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

std::optional<double> Number(const YAML::Node& n) {
  if (!n.IsScalar()) return std::nullopt;
  try {
    const double v = n.as<double>();
    if (std::isfinite(v)) return v;
  } catch (const YAML::Exception&) {
  }
  return std::nullopt;
}

std::optional<int64_t> Integer(const YAML::Node& n) {
  if (!n.IsScalar()) return std::nullopt;
  try {
    size_t used = 0;
    const long long v = std::stoll(n.Scalar(), &used);
    if (used == n.Scalar().size()) return v;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

void CheckRange(const YAML::Node& tree, const YAML::Node& schema, const std::string& path,
                const std::string& source) {
  for (const auto& kv : tree) {
    const std::string key = kv.first.Scalar();
    if (key != "min" && key != "max" && key != "step") {
      Fail(source, Join(path, key), kv.second, "unknown key in a range (known: min, max, step)");
    }
  }
  const YAML::Node min = tree["min"], max = tree["max"], step = tree["step"];
  if (!min) Fail(source, Join(path, "min"), min, "missing; a range is {min: a, max: b}");
  if (!max) Fail(source, Join(path, "max"), max, "missing; a range is {min: a, max: b}");
  const auto lo = Number(min), hi = Number(max);
  if (!lo) Fail(source, Join(path, "min"), min, "expected a number");
  if (!hi) Fail(source, Join(path, "max"), max, "expected a number");
  if (*lo > *hi) Fail(source, Join(path, "max"), max, fmt::format("expected max >= min ({})", *lo));
  if (step) {
    const auto s = Number(step);
    if (!s || *s <= 0.0) Fail(source, Join(path, "step"), step, "expected a number > 0");
  }
  if (schema.IsMap() || schema.IsSequence()) {
    Fail(source, path, tree, schema.IsMap() ? "expected a map of keys here, not a range"
                                            : "expected a list here, not a range");
  }
}

// The keys of `schema` (a map) as a message lists them, and the nearest to
// `key` as a hint.
std::string KnownKeys(const YAML::Node& schema, const std::string& key) {
  std::vector<std::string> known;
  std::string hint;
  size_t best = 3;
  for (const auto& kv : schema) {
    known.push_back(kv.first.Scalar());
    const size_t d = yaml_reader::EditDistance(key, known.back());
    if (d < best) {
      best = d;
      hint = fmt::format("; did you mean '{}'?", known.back());
    }
  }
  std::string list;
  for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
  return fmt::format("unknown key (known here: {}){}", list, hint);
}

}  // namespace

bool IsRange(const YAML::Node& node) { return node.IsMap() && (node["min"] || node["max"]); }
bool IsChoice(const YAML::Node& node) { return node.IsMap() && node["choices"]; }
bool PlainMap(const YAML::Node& node) { return node.IsMap() && !IsRange(node) && !IsChoice(node); }

void CheckTree(const YAML::Node& tree, const YAML::Node& schema, const std::string& path,
               const std::string& source) {
  if (IsRange(tree)) return CheckRange(tree, schema, path, source);
  if (IsChoice(tree)) {
    const YAML::Node choices = tree["choices"];
    if (tree.size() != 1) Fail(source, path, tree, "a choice has the one key choices");
    if (!choices.IsSequence() || choices.size() == 0) {
      Fail(source, Join(path, "choices"), choices, "expected a non-empty list");
    }
    for (size_t i = 0; i < choices.size(); ++i) {
      CheckTree(choices[i], schema, fmt::format("{}.choices[{}]", path, i), source);
    }
    return;
  }
  if (tree.IsMap()) {
    if (!schema.IsMap()) {
      Fail(source, path, tree,
           schema.IsSequence() ? "expected a list (or a range or choice of lists)"
                               : "expected a value, a range {min, max} or a choice {choices: [...]}");
    }
    std::vector<std::string> seen;
    for (const auto& kv : tree) {
      const std::string key = kv.first.Scalar();
      if (std::find(seen.begin(), seen.end(), key) != seen.end()) {
        Fail(source, Join(path, key), kv.second, "the key appears more than once in its map");
      }
      seen.push_back(key);
      if (key != "one_of") {
        if (!schema[key]) Fail(source, Join(path, key), kv.second, KnownKeys(schema, key));
        CheckTree(kv.second, schema[key], Join(path, key), source);
        continue;
      }
      const YAML::Node branches = kv.second;
      if (!branches.IsSequence() || branches.size() == 0) {
        Fail(source, Join(path, key), branches, "expected a non-empty list of maps");
      }
      for (size_t i = 0; i < branches.size(); ++i) {
        const std::string branch_path = fmt::format("{}[{}]", Join(path, key), i);
        const YAML::Node branch = branches[i];
        if (!branch.IsMap() || IsRange(branch) || IsChoice(branch)) {
          Fail(source, branch_path, branch, "expected a map of keys (they join the map holding one_of)");
        }
        for (const auto& b : branch) {
          const YAML::Node mine = tree[b.first.Scalar()];
          const bool both_maps = mine && PlainMap(mine) && PlainMap(b.second);
          if (b.first.Scalar() == "one_of" || (mine && !both_maps)) {
            Fail(source, Join(branch_path, b.first.Scalar()), b.second,
                 "a one_of branch may repeat a key of its map only where both hold a map of keys "
                 "(and holds no one_of itself)");
          }
        }
        CheckTree(branch, schema, branch_path, source);
      }
    }
    return;
  }
  if (tree.IsSequence()) {
    if (!schema.IsSequence()) {
      Fail(source, path, tree, schema.IsMap() ? "expected a map of keys" : "expected a single value");
    }
    for (size_t i = 0; i < tree.size(); ++i) {
      CheckTree(tree[i], schema.size() > 0 ? schema[0] : YAML::Node(), fmt::format("{}[{}]", path, i),
                source);
    }
    return;
  }
  // A scalar (or an empty value): a fixed value, whose type the scenario's
  // own reader checks once drawn.
  if (schema.IsMap() && tree.IsScalar()) Fail(source, path, tree, "expected a map of keys");
}

YAML::Node Sample(const YAML::Node& tree, SplitMix64& rng) {
  if (IsRange(tree)) {
    const double lo = tree["min"].as<double>(), hi = tree["max"].as<double>();
    const double u = rng.Uniform();
    // Six significant digits: plenty for a drawn value, and readable.
    if (!tree["step"]) return YAML::Node(fmt::format("{:.6g}", lo + u * (hi - lo)));
    const double step = tree["step"].as<double>();
    const int64_t n = static_cast<int64_t>(std::floor((hi - lo) / step + 1e-9));
    const int64_t k = std::min(n, static_cast<int64_t>(std::floor(u * static_cast<double>(n + 1))));
    const auto ilo = Integer(tree["min"]), ihi = Integer(tree["max"]), istep = Integer(tree["step"]);
    if (ilo && ihi && istep) return YAML::Node(fmt::format("{}", *ilo + k * *istep));
    return YAML::Node(fmt::format("{}", lo + static_cast<double>(k) * step));
  }
  if (IsChoice(tree)) {
    const YAML::Node choices = tree["choices"];
    const size_t i = std::min(choices.size() - 1, static_cast<size_t>(rng.Uniform() * choices.size()));
    return Sample(choices[i], rng);
  }
  if (tree.IsMap()) {
    YAML::Node out(YAML::NodeType::Map);
    for (const auto& kv : tree) {
      if (kv.first.Scalar() != "one_of") out[kv.first.Scalar()] = Sample(kv.second, rng);
    }
    const YAML::Node branches = tree["one_of"];
    if (!branches) return out;
    const size_t i = std::min(branches.size() - 1, static_cast<size_t>(rng.Uniform() * branches.size()));
    return Merge(out, Sample(branches[i], rng));
  }
  if (tree.IsSequence()) {
    YAML::Node out(YAML::NodeType::Sequence);
    for (const auto& item : tree) out.push_back(Sample(item, rng));
    return out;
  }
  return YAML::Clone(tree);
}

YAML::Node Merge(const YAML::Node& under, const YAML::Node& over) {
  if (!over || over.IsNull()) return YAML::Clone(under);
  if (!PlainMap(under) || !PlainMap(over)) return YAML::Clone(over);
  YAML::Node out = YAML::Clone(under);
  for (const auto& kv : over) {
    const std::string key = kv.first.Scalar();
    const YAML::Node& base = under;  // const: a missing key is not created
    out[key] = base[key] ? Merge(base[key], kv.second) : YAML::Clone(kv.second);
  }
  return out;
}

}  // namespace calib::synth::family_detail
