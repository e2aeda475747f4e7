#include "calib/discovery/loop_spec.h"

#include "calib/core/yaml_map_reader.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/spec_text.h"
#include "calib/search/factory.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <limits>

namespace calib {
namespace {

namespace fs = std::filesystem;

[[noreturn]] void RaiseLoopSpecError(const std::string& message) { throw LoopSpecError(message); }

// A number key with the range `calib loop` holds its option to.
template <typename T>
void ReadInRange(yaml_reader::MapReader& r, const std::string& key, T low, T high, T* value) {
  if (!r.Has(key)) return;
  const YAML::Node n = r.Get(key);
  double v = 0.0;
  if constexpr (std::is_integral_v<T>) {
    v = static_cast<double>(r.Int(key, n));
  } else {
    v = r.Double(key, n);
  }
  if (!(v >= static_cast<double>(low) && v <= static_cast<double>(high))) {
    if (high == std::numeric_limits<T>::max()) r.Fail(key, n, fmt::format("must be >= {}", low));
    r.Fail(key, n, fmt::format("must be in [{}, {}]", low, high));
  }
  *value = static_cast<T>(v);
}

template <typename T>
void ReadInRange(yaml_reader::MapReader& r, const std::string& key, LoopOptionRange<T> range,
                 T* value) {
  ReadInRange(r, key, range.low, range.high, value);
}

std::vector<fs::path> ReadRecordings(yaml_reader::MapReader& r, const std::string& key,
                                     const fs::path& base_dir, bool required) {
  std::vector<fs::path> out;
  const std::string rule = "a list of recording folders";
  const YAML::Node list = required ? r.Require(key, rule) : r.Get(key);
  if (!list.IsDefined() || list.IsNull()) return out;
  if (!list.IsSequence() || (required && list.size() == 0)) {
    r.Fail(key, list, fmt::format("expected {}{}", required ? "a non-empty " : "", rule.substr(2)));
  }
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string at = fmt::format("{}[{}]", key, i);
    if (!list[i].IsScalar() || list[i].Scalar().empty()) r.Fail(at, list[i], "expected a recording folder");
    out.push_back(base_dir / list[i].Scalar());
  }
  return out;
}

}  // namespace

LoopSpec ParseLoopSpec(const std::string& text, const std::string& source, const fs::path& base_dir) {
  YAML::Node root;
  try {
    root = LoadSpecYaml(text, source);
  } catch (const JobSpecError& e) {
    throw LoopSpecError(e.what());
  }
  yaml_reader::MapReader r(root, "", &source, &RaiseLoopSpecError);
  LoopSpec spec;
  LoopOptions& o = spec.options;
  const YAML::Node name = r.Require("name", "the loop's name (letters, digits, '_', '-', '.')");
  spec.name = r.String("name", name);
  if (!IsValidSpecName(spec.name)) r.Fail("name", name, "must be non-empty letters, digits, '_', '-', '.'");
  o.train = ReadRecordings(r, "train", base_dir, true);
  o.holdout = ReadRecordings(r, "holdout", base_dir, false);

  r.Read("seed", &o.seed);
  ReadInRange(r, "budget", kLoopBudgetRange, &o.budget);
  ReadInRange<int64_t>(r, "effect_budget", 0, std::numeric_limits<int64_t>::max(), &o.effect_budget);
  if (r.Has("optimizer")) {
    const YAML::Node n = r.Get("optimizer");
    o.optimizer = r.String("optimizer", n);
    const std::vector<std::string> names = search::AllOptimizerNames();
    if (std::find(names.begin(), names.end(), o.optimizer) == names.end()) {
      r.Fail("optimizer", n, fmt::format("unknown optimiser; one of {}", fmt::join(names, ", ")));
    }
  }
  ReadInRange<int>(r, "max_effects", 0, std::numeric_limits<int>::max(), &o.max_effects);
  ReadInRange<int>(r, "tries", 1, std::numeric_limits<int>::max(), &o.tries_per_round);
  ReadInRange(r, "min_confidence", kLoopMinConfidenceRange, &o.min_confidence);
  if (r.Has("rank_by")) {
    const YAML::Node n = r.Get("rank_by");
    const std::string rank_by = r.String("rank_by", n);
    if (rank_by != "confidence" && rank_by != "rate") r.Fail("rank_by", n, "must be confidence or rate");
    o.rank_by_rate = rank_by == "rate";
  }
  ReadInRange(r, "fdr", kLoopFdrRange, &o.false_discovery_rate);
  ReadInRange(r, "min_drop", kLoopMinDropRange, &o.min_relative_drop);
  ReadInRange(r, "held_out_stretch", kLoopHeldOutStretchRange, &o.held_out_stretch);
  ReadInRange<int>(r, "equally_good_fits", 0, std::numeric_limits<int>::max(), &o.equally_good_fits);
  ReadInRange<int>(r, "refit_candidates", 0, std::numeric_limits<int>::max(), &o.refit_candidates);
  ReadInRange<int>(r, "restarts", 1, std::numeric_limits<int>::max(), &o.restarts);
  ReadInRange<int>(r, "effect_restarts", 1, std::numeric_limits<int>::max(), &o.effect_restarts);
  ReadInRange<int>(r, "overlays", 0, std::numeric_limits<int>::max(), &o.overlays_per_recording);
  r.Read("outline_contact", &o.simulation.outline_contact);
  ReadInRange(r, "contact_friction", 0.0, std::numeric_limits<double>::max(),
              &o.simulation.contact_friction);
  if (r.Has("integrator")) {
    const YAML::Node n = r.Get("integrator");
    const std::string integrator = r.String("integrator", n);
    if (integrator != "first_order" && integrator != "implicit_first_order") {
      r.Fail("integrator", n, "must be first_order or implicit_first_order");
    }
    o.simulation.integrator = IntegratorKindFromString(integrator);
  }
  r.Read("html", &o.write_html);
  r.Finish();
  return spec;
}

nlohmann::json ToJson(const LoopSpec& spec) {
  const LoopOptions& o = spec.options;
  auto paths = [](const std::vector<fs::path>& list) {
    nlohmann::json out = nlohmann::json::array();
    for (const fs::path& p : list) out.push_back(p.string());
    return out;
  };
  return {{"name", spec.name},
          {"train", paths(o.train)},
          {"holdout", paths(o.holdout)},
          {"seed", o.seed},
          {"budget", o.budget},
          {"effect_budget", o.effect_budget},
          {"optimizer", o.optimizer},
          {"max_effects", o.max_effects},
          {"tries", o.tries_per_round},
          {"min_confidence", o.min_confidence},
          {"rank_by", o.rank_by_rate ? "rate" : "confidence"},
          {"fdr", o.false_discovery_rate},
          {"min_drop", o.min_relative_drop},
          {"held_out_stretch", o.held_out_stretch},
          {"equally_good_fits", o.equally_good_fits},
          {"refit_candidates", o.refit_candidates},
          {"restarts", o.restarts},
          {"effect_restarts", o.effect_restarts},
          {"overlays", o.overlays_per_recording},
          {"outline_contact", o.simulation.outline_contact},
          {"contact_friction", o.simulation.contact_friction},
          {"integrator", ToString(o.simulation.integrator)},
          {"html", o.write_html}};
}

}  // namespace calib
