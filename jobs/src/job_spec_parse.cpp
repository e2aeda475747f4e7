// Reading and validating job specs: LoadJobSpec, ParseJobSpec and
// CheckRecordings (job_spec.h). Every error names the file, the field path,
// the value and the rule (spec_reader.h).

#include "calib/jobs/job_spec.h"

#include "calib/evaluator/recording.h"
#include "calib/search/factory.h"
#include "spec_reader.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <string_view>
#include <vector>

namespace calib {
namespace {

using spec_reader::MapReader;
using spec_reader::ValidName;
using spec_reader::Show;
using spec_reader::YamlToJson;

// The errors of a spec's independent parts (name, recordings, model,
// parameters, budget, optimiser, ...), so that a spec with several errors
// names all of them at once rather than one per attempt. A part that
// depends on another (the parameters on the model's effects) is read only
// when that one is sound: its errors would only echo the first.
class SpecErrors {
 public:
  /// Runs `read`, keeping the JobSpecError it throws; false when it threw.
  template <class Read>
  bool Check(Read&& read) {
    try {
      read();
      return true;
    } catch (const JobSpecError& e) {
      messages_.emplace_back(e.what());
      return false;
    }
  }

  size_t count() const { return messages_.size(); }

  /// One JobSpecError naming every error, one a line; nothing when none.
  void ThrowIfAny(const std::string& source) const {
    if (messages_.empty()) return;
    if (messages_.size() == 1) throw JobSpecError(messages_.front());
    throw JobSpecError(fmt::format("{}: {} errors:\n{}", source, messages_.size(),
                                   fmt::join(messages_, "\n")));
  }

 private:
  std::vector<std::string> messages_;
};

std::filesystem::path Resolve(const std::filesystem::path& base, const std::string& written) {
  return (base / std::filesystem::path(written)).lexically_normal();
}

std::vector<std::filesystem::path> ReadRecordings(MapReader& r, const std::string& key, bool required,
                                                  const std::filesystem::path& base,
                                                  RecordingCheck check) {
  std::vector<std::filesystem::path> out;
  const YAML::Node list = required ? r.Require(key, "a list of recording folders (at least one)")
                                   : r.Get(key);
  if (!list.IsDefined() || list.IsNull()) return out;
  if (!list.IsSequence()) r.Fail(r.KeyPath(key), list, "expected a list of recording folders");
  if (required && list.size() == 0) r.Fail(r.KeyPath(key), list, "must list at least one recording folder");
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string path = fmt::format("{}[{}]", r.KeyPath(key), i);
    if (!list[i].IsScalar() || list[i].Scalar().empty()) {
      r.Fail(path, list[i], "expected a recording folder path");
    }
    const std::filesystem::path dir = Resolve(base, list[i].Scalar());
    if (check == RecordingCheck::kExists) {
      if (!std::filesystem::is_directory(dir)) {
        r.Fail(path, list[i], fmt::format("recording folder {} does not exist", dir.string()));
      }
      if (!std::filesystem::is_regular_file(dir / "recording.json")) {
        r.Fail(path, list[i], fmt::format("{} holds no recording.json", dir.string()));
      }
    }
    out.push_back(dir);
  }
  return out;
}

void ReadModel(MapReader r, ModelSpec* m, const ModelCatalog& catalog) {
  const YAML::Node effects = r.Get("effects");
  if (effects.IsDefined() && !effects.IsNull()) {
    if (!effects.IsSequence()) r.Fail(r.KeyPath("effects"), effects, "expected a list of effect names");
    std::vector<std::string> known;
    for (const auto& [name, specs] : catalog.effects) known.push_back(name);
    for (size_t i = 0; i < effects.size(); ++i) {
      const std::string path = fmt::format("{}[{}]", r.KeyPath("effects"), i);
      if (!effects[i].IsScalar()) r.Fail(path, effects[i], "expected an effect name");
      const std::string name = effects[i].Scalar();
      if (!catalog.effects.contains(name)) {
        r.Fail(path, effects[i],
               fmt::format("unknown model effect; known: {}",
                           known.empty() ? std::string("none yet") : fmt::format("{}", fmt::join(known, ", "))));
      }
      if (std::find(m->effects.begin(), m->effects.end(), name) != m->effects.end()) {
        r.Fail(path, effects[i], "listed twice");
      }
      m->effects.push_back(name);
    }
  }
  SimulationOptions& sim = m->simulation;
  r.Read("substeps", &sim.substeps);
  if (sim.substeps < 1) r.Fail(r.KeyPath("substeps"), r.node()["substeps"], "must be >= 1");
  if (r.Has("integrator")) {
    const YAML::Node n = r.node()["integrator"];
    const std::string name = r.String("integrator", n);
    try {
      sim.integrator = IntegratorKindFromString(name);
    } catch (const std::invalid_argument&) {
      r.Fail(r.KeyPath("integrator"), n, "must be " + IntegratorKindNames());
    }
  }
  r.Read("constraint_iterations", &sim.constraint_iterations);
  if (sim.constraint_iterations < 1) {
    r.Fail(r.KeyPath("constraint_iterations"), r.node()["constraint_iterations"], "must be >= 1");
  }
  r.Read("outline_contact", &sim.outline_contact);
  r.Read("contact_friction", &sim.contact_friction);
  if (!(std::isfinite(sim.contact_friction) && sim.contact_friction >= 0.0)) {
    r.Fail(r.KeyPath("contact_friction"), r.node()["contact_friction"], "must be >= 0");
  }
  r.Read("min_area_fraction", &sim.min_area_fraction);
  if (!(sim.min_area_fraction > 0.0 && sim.min_area_fraction < 1.0)) {
    r.Fail(r.KeyPath("min_area_fraction"), r.node()["min_area_fraction"], "must be in (0, 1)");
  }
  r.Read("divergence_diameters", &sim.divergence_diameters);
  if (!(sim.divergence_diameters > 0.0)) {
    r.Fail(r.KeyPath("divergence_diameters"), r.node()["divergence_diameters"], "must be > 0");
  }
  r.Read("area_weighted", &sim.area_weighted);
  if (sim.area_weighted &&
      std::find(m->effects.begin(), m->effects.end(), "inertia") == m->effects.end()) {
    r.Fail(r.KeyPath("area_weighted"), r.node()["area_weighted"],
           "needs the inertia effect in model.effects (it weights masses, which only a "
           "second-order model has)");
  }

  PreparationOptions& prep = m->preparation;
  if (r.Has("segmentation")) {
    MapReader s(r.Get("segmentation"), r.KeyPath("segmentation"), &r.source());
    s.Read("open_radius_px", &prep.segmentation.open_radius_px);
    if (prep.segmentation.open_radius_px < 0) {
      s.Fail(s.KeyPath("open_radius_px"), s.node()["open_radius_px"], "must be >= 0");
    }
    s.Read("close_radius_px", &prep.segmentation.close_radius_px);
    if (prep.segmentation.close_radius_px < 0) {
      s.Fail(s.KeyPath("close_radius_px"), s.node()["close_radius_px"], "must be >= 0");
    }
    s.Read("fill_holes", &prep.segmentation.fill_holes);
    s.Finish();
  }
  if (r.Has("mesh")) {
    MapReader s(r.Get("mesh"), r.KeyPath("mesh"), &r.source());
    s.Read("edge_length_px", &prep.mesher.edge_length_px);
    if (!(prep.mesher.edge_length_px > 0.0)) {
      s.Fail(s.KeyPath("edge_length_px"), s.node()["edge_length_px"], "must be > 0");
    }
    s.Read("min_edges_across", &prep.mesher.min_edges_across);
    if (prep.mesher.min_edges_across < 0 || prep.mesher.min_edges_across > MesherOptions::kMaxEdgesAcross) {
      s.Fail(s.KeyPath("min_edges_across"), s.node()["min_edges_across"],
             fmt::format("must be in [0, {}] (0: edge_length_px whatever the width)",
                         MesherOptions::kMaxEdgesAcross));
    }
    s.Finish();
  }
  r.Read("outline_tolerance_px", &prep.outline_tolerance_px);
  if (!(prep.outline_tolerance_px >= 0.0)) {
    r.Fail(r.KeyPath("outline_tolerance_px"), r.node()["outline_tolerance_px"], "must be >= 0");
  }
  r.Read("frames", &prep.max_frames);
  if (prep.max_frames < 0) {
    r.Fail(r.KeyPath("frames"), r.node()["frames"], "must be >= 0 (0: every frame)");
  }
  r.Finish();
  // Guards against rules added to the options after this reader was written.
  std::string error;
  if (!sim.IsValid(&error) || !prep.IsValid(&error)) {
    throw JobSpecError(fmt::format("{}: model: {}", r.source(), error));
  }
}

std::string AllowedRange(const ParameterSpec& s) {
  return fmt::format("{}{}, {}]", s.lower_open ? "(" : "[", s.lower, s.upper);
}

bool InRange(const ParameterSpec& s, double v) {
  const bool below = s.lower_open ? v <= s.lower : v < s.lower;
  return !below && v <= s.upper;
}

// Entry i of the parameters list; `before` holds the entries read so far.
ParameterSetting ReadParameter(MapReader& top, const YAML::Node& entry, size_t i,
                               const std::vector<ParameterSpec>& specs,
                               const std::vector<ParameterSetting>& before) {
  std::vector<std::string> known;
  for (const auto& s : specs) known.push_back(s.name);
  const std::string path = fmt::format("parameters[{}]", i);
  MapReader r(entry, path, &top.source());
  ParameterSetting p;
  const YAML::Node name_node = r.Require("name", fmt::format("one of {}", fmt::join(known, ", ")));
  p.name = r.String("name", name_node);
  const auto spec = std::find_if(specs.begin(), specs.end(),
                                 [&](const ParameterSpec& s) { return s.name == p.name; });
  if (spec == specs.end()) {
    r.Fail(r.KeyPath("name"), name_node,
           fmt::format("unknown parameter; the model's are {}", fmt::join(known, ", ")));
  }
  for (const auto& q : before) {
    if (q.name == p.name) r.Fail(r.KeyPath("name"), name_node, "parameter listed twice");
  }
  const bool has_fixed = r.Has("fixed");
  const bool has_lower = r.Has("lower");
  const bool has_upper = r.Has("upper");
  const bool has_scale = r.Has("scale");
  if (has_fixed) {
    if (has_lower || has_upper || has_scale) {
      const std::string other = has_lower ? "lower" : has_upper ? "upper" : "scale";
      r.Fail(r.KeyPath(other), r.node()[other],
             "a fixed parameter takes no lower, upper or scale (give fixed, or lower and upper)");
    }
    const double v = r.Double("fixed", r.node()["fixed"]);
    if (!InRange(*spec, v)) {
      r.Fail(r.KeyPath("fixed"), r.node()["fixed"],
             fmt::format("must be within {}'s allowed range {}", p.name, AllowedRange(*spec)));
    }
    p.fixed = v;
  } else {
    if (!has_lower) r.Missing(r.KeyPath("lower"), "a searched parameter needs lower and upper (or give fixed)");
    if (!has_upper) r.Missing(r.KeyPath("upper"), "a searched parameter needs lower and upper (or give fixed)");
    p.lower = r.Double("lower", r.node()["lower"]);
    p.upper = r.Double("upper", r.node()["upper"]);
    if (has_scale) {
      const std::string s = r.String("scale", r.node()["scale"]);
      try {
        p.scale = ParameterScaleFromString(s);
      } catch (const std::invalid_argument&) {
        r.Fail(r.KeyPath("scale"), r.node()["scale"], "must be linear or log");
      }
    }
    if (!InRange(*spec, p.lower)) {
      r.Fail(r.KeyPath("lower"), r.node()["lower"],
             fmt::format("must be within {}'s allowed range {}", p.name, AllowedRange(*spec)));
    }
    if (!InRange(*spec, p.upper)) {
      r.Fail(r.KeyPath("upper"), r.node()["upper"],
             fmt::format("must be within {}'s allowed range {}", p.name, AllowedRange(*spec)));
    }
    if (!(p.lower < p.upper)) {
      r.Fail(r.KeyPath("upper"), r.node()["upper"],
             fmt::format("must be > {} ({})", r.KeyPath("lower"), p.lower));
    }
    if (p.scale == ParameterScale::kLog && !(p.lower > 0.0)) {
      r.Fail(r.KeyPath("lower"), r.node()["lower"], "must be > 0 on a log scale");
    }
  }
  r.Finish();
  return p;
}

// Every entry of the parameters list, each entry's error kept in `errors`;
// then whether every model parameter is listed and one searched.
std::vector<ParameterSetting> ReadParameters(MapReader& top, const std::vector<ParameterSpec>& specs,
                                             SpecErrors& errors) {
  const YAML::Node list =
      top.Require("parameters", "a list of {name, lower, upper, scale} or {name, fixed}");
  if (!list.IsSequence()) top.Fail("parameters", list, "expected a list of parameters");
  std::vector<ParameterSetting> out;
  bool every_entry_read = true;
  for (size_t i = 0; i < list.size(); ++i) {
    every_entry_read &= errors.Check([&] { out.push_back(ReadParameter(top, list[i], i, specs, out)); });
  }
  if (!every_entry_read) return out;  // what is missing would only echo the entries' errors
  for (const auto& s : specs) {
    const bool listed = std::any_of(out.begin(), out.end(),
                                    [&](const ParameterSetting& p) { return p.name == s.name; });
    if (!listed) {
      top.Missing(fmt::format("parameters ('{}')", s.name),
                  fmt::format("every model parameter must be searched or fixed: add {{name: {}, lower: "
                              "L, upper: U}} or {{name: {}, fixed: V}} ({}, {}, allowed {})",
                              s.name, s.name, s.description, s.unit, AllowedRange(s)));
    }
  }
  if (std::none_of(out.begin(), out.end(), [](const ParameterSetting& p) { return p.searched(); })) {
    top.Fail("parameters", list, "at least one parameter must be searched (have lower and upper)");
  }
  return out;
}

/// The byte offset of the first byte of `text` that breaks UTF-8 (an
/// overlong form, a surrogate, past U+10FFFF, a stray or missing
/// continuation byte), or npos when it is all UTF-8.
size_t FirstNonUtf8(std::string_view text) {
  const auto byte = [&](size_t i) { return static_cast<unsigned char>(text[i]); };
  size_t i = 0;
  while (i < text.size()) {
    const unsigned char c = byte(i);
    if (c < 0x80) {
      ++i;
      continue;
    }
    // Lead byte: the sequence length and the range of its second byte
    // (Unicode 15, table 3-7).
    size_t length = 0;
    unsigned char low = 0x80;
    unsigned char high = 0xBF;
    if (c >= 0xC2 && c <= 0xDF) {
      length = 2;
    } else if (c >= 0xE0 && c <= 0xEF) {
      length = 3;
      if (c == 0xE0) low = 0xA0;
      if (c == 0xED) high = 0x9F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      length = 4;
      if (c == 0xF0) low = 0x90;
      if (c == 0xF4) high = 0x8F;
    } else {
      return i;
    }
    if (i + length > text.size()) return i;
    if (byte(i + 1) < low || byte(i + 1) > high) return i;
    for (size_t k = 2; k < length; ++k) {
      if (byte(i + k) < 0x80 || byte(i + k) > 0xBF) return i;
    }
    i += length;
  }
  return std::string_view::npos;
}

/// Aliases make a YAML document a graph: an alias inside its own anchor
/// (`a: &x [*x]`) is a cycle, and aliases of aliases grow exponentially as a
/// tree ("billion laughs"). Every reader of the spec walks it as a tree (the
/// fields, their messages, optimiser settings as JSON), which would overflow
/// the stack or never end: the document as a tree must stay small. Walked
/// without recursion, so that a cycle is only counted. Each value and key
/// must be UTF-8 as read (JSON needs it): UTF-8 text is not enough, yaml-cpp
/// reads a NUL byte and the byte after it as one byte that is not UTF-8.
void CheckYamlValues(const YAML::Node& root, const std::string& source) {
  constexpr size_t kMaxValues = 100000;
  std::vector<YAML::Node> pending{root};
  size_t values = 0;
  while (!pending.empty()) {
    const YAML::Node node = pending.back();
    pending.pop_back();
    if (++values > kMaxValues) {
      throw JobSpecError(fmt::format(
          "{}: holds more than {} values once its aliases are expanded (an alias inside its own "
          "anchor, or aliases of aliases)",
          source, kMaxValues));
    }
    if (node.IsScalar() && FirstNonUtf8(node.Scalar()) != std::string_view::npos) {
      throw JobSpecError(fmt::format("{}: line {}: a value or key is not UTF-8 once read as YAML "
                                     "(a NUL byte in the text makes one)",
                                     source, node.Mark().line + 1));
    }
    if (node.IsSequence()) {
      for (const YAML::Node& item : node) pending.push_back(item);
    } else if (node.IsMap()) {
      for (const auto& kv : node) {
        pending.push_back(kv.first);
        pending.push_back(kv.second);
      }
    }
  }
}

}  // namespace

JobSpec ParseJobSpecYaml(const YAML::Node& root, const std::string& source,
                         const std::filesystem::path& base_dir,
                         const JobSpecParseOptions& options) {
  const ModelCatalog& catalog = options.catalog != nullptr ? *options.catalog : DefaultModelCatalog();
  if (!root.IsDefined() || root.IsNull()) throw JobSpecError(fmt::format("{}: empty job spec", source));
  CheckYamlValues(root, source);
  JobSpec spec;
  spec.source = source;
  spec.base_dir = std::filesystem::absolute(base_dir).lexically_normal();
  MapReader top(root, "", &spec.source);
  SpecErrors errors;

  errors.Check([&] {
    const YAML::Node name = top.Require("name", "a job name (letters, digits, '_', '-', '.')");
    spec.name = top.String("name", name);
    if (!ValidName(spec.name)) top.Fail("name", name, "must be non-empty letters, digits, '_', '-', '.'");
    if (options.overrides.name) {
      spec.name = *options.overrides.name;
      if (!ValidName(spec.name)) {
        throw JobSpecError(fmt::format("{}: name = '{}' (given with --name): must be non-empty "
                                       "letters, digits, '_', '-', '.'",
                                       spec.source, spec.name));
      }
    }
  });

  errors.Check([&] { spec.train = ReadRecordings(top, "train", true, spec.base_dir, options.recordings); });
  errors.Check(
      [&] { spec.holdout = ReadRecordings(top, "holdout", false, spec.base_dir, options.recordings); });

  const bool model_read = errors.Check([&] {
    if (top.Has("model")) {
      ReadModel(MapReader(top.Get("model"), "model", &spec.source), &spec.model, catalog);
    } else {
      top.Get("model");
    }
  });
  // The parameters a model needs depend on its effects.
  bool parameters_read = false;
  if (model_read) {
    spec.parameter_specs = catalog.ParameterSpecsFor(spec.model.effects);
    const size_t known_errors = errors.count();
    errors.Check([&] { spec.parameters = ReadParameters(top, spec.parameter_specs, errors); });
    parameters_read = errors.count() == known_errors;
  } else {
    top.Get("parameters");
  }

  // budget before optimizer: the optimiser's own budget defaults to it.
  const bool budget_read = errors.Check([&] {
    MapReader b(top.Require("budget",
                            "a map with evaluations (and optional wall_time_s, prune_factor)"),
                "budget", &spec.source);
    const YAML::Node ev = b.Require("evaluations", "an integer >= 1");
    spec.budget.evaluations = b.Int("evaluations", ev);
    if (spec.budget.evaluations < 1) b.Fail("budget.evaluations", ev, "must be >= 1");
    if (options.overrides.budget_evaluations) {
      spec.budget.evaluations = *options.overrides.budget_evaluations;
      if (spec.budget.evaluations < 1) {
        throw JobSpecError(fmt::format("{}: budget.evaluations = {} (given with --budget): must be >= 1",
                                       spec.source, spec.budget.evaluations));
      }
    }
    if (b.Has("wall_time_s")) {
      const YAML::Node n = b.node()["wall_time_s"];
      const double w = b.Double("wall_time_s", n);
      if (!(w > 0.0)) b.Fail("budget.wall_time_s", n, "must be > 0");
      spec.budget.wall_time_s = w;
    }
    if (b.Has("prune_factor")) {
      const YAML::Node n = b.node()["prune_factor"];
      const double f = b.Double("prune_factor", n);
      if (!(f > 1.0)) {
        b.Fail("budget.prune_factor", n,
               "must be > 1 (a candidate is pruned when its score so far exceeds this factor "
               "times the best score before it)");
      }
      spec.budget.prune_factor = f;
    }
    b.Finish();
  });

  errors.Check([&] {
    if (top.Has("seed")) {
      const YAML::Node n = top.node()["seed"];
      try {
        if (!n.IsScalar() || n.Scalar().empty() || n.Scalar()[0] == '-') throw YAML::Exception({}, "");
        spec.seed = n.as<uint64_t>();
      } catch (const YAML::Exception&) {
        top.Fail("seed", n, "expected an integer >= 0");
      }
    }
    if (options.overrides.seed) spec.seed = *options.overrides.seed;
  });
  errors.Check([&] {
    top.Read("threads", &spec.threads);
    if (spec.threads < 0) top.Fail("threads", top.node()["threads"], "must be >= 0 (0: all cores)");
  });
  errors.Check([&] {
    top.Read("processes", &spec.processes);
    if (spec.processes < 1) top.Fail("processes", top.node()["processes"], "must be >= 1");
  });

  const bool optimizer_read = errors.Check([&] {
    MapReader o(top.Require("optimizer", "a map with name and settings"), "optimizer", &spec.source);
    const std::vector<std::string> names = search::AllOptimizerNames();
    const YAML::Node n = o.Require("name", fmt::format("one of {}", fmt::join(names, ", ")));
    spec.optimizer.name = o.String("name", n);
    if (std::find(names.begin(), names.end(), spec.optimizer.name) == names.end()) {
      o.Fail("optimizer.name", n, fmt::format("unknown optimiser; one of {}", fmt::join(names, ", ")));
    }
    spec.optimizer.settings = spec_reader::ReadOptimizerSettings(o, "optimizer", spec.optimizer.name);
    o.Finish();
  });
  // The optimiser is made with the budget and the search space.
  if (optimizer_read && budget_read && parameters_read) {
    errors.Check([&] {
      std::string filled;
      const std::string budget_key = search::BudgetSetting(spec.optimizer.name);
      if (!budget_key.empty() && !spec.optimizer.settings.contains(budget_key)) {
        filled = fmt::format(" ({} = {} filled in from budget.evaluations)", budget_key,
                             spec.budget.evaluations);
      }
      spec.optimizer.settings =
          search::WithBudget(spec.optimizer.name, std::move(spec.optimizer.settings), spec.budget.evaluations);
      try {
        (void)MakeRequestOptimizer(spec);
      } catch (const std::exception& e) {
        throw JobSpecError(fmt::format("{}: optimizer.settings = {}{}: {}", spec.source,
                                       spec.optimizer.settings.dump(), filled, e.what()));
      }
    });
  }

  errors.Check([&] {
    if (top.Has("checkpoint")) {
      MapReader c(top.Get("checkpoint"), "checkpoint", &spec.source);
      c.Read("every_evaluations", &spec.checkpoint.every_evaluations);
      if (spec.checkpoint.every_evaluations < 0) {
        c.Fail("checkpoint.every_evaluations", c.node()["every_evaluations"], "must be >= 0 (0: off)");
      }
      c.Read("every_seconds", &spec.checkpoint.every_seconds);
      if (spec.checkpoint.every_seconds < 0.0) {
        c.Fail("checkpoint.every_seconds", c.node()["every_seconds"], "must be >= 0 (0: off)");
      }
      if (spec.checkpoint.every_evaluations == 0 && spec.checkpoint.every_seconds == 0.0) {
        c.Fail("checkpoint", c.node(), "every_evaluations and every_seconds cannot both be 0");
      }
      c.Finish();
    } else {
      top.Get("checkpoint");
    }
  });

  errors.Check([&] {
    if (top.Has("failure_policy")) {
      MapReader f(top.Get("failure_policy"), "failure_policy", &spec.source);
      FailurePolicy& fp = spec.failure_policy;
      if (f.Has("mode")) {
        const YAML::Node n = f.node()["mode"];
        try {
          fp.mode = FailureModeFromString(f.String("mode", n));
        } catch (const std::invalid_argument&) {
          f.Fail("failure_policy.mode", n, "must be penalty, retry or abort");
        }
      }
      if (f.Has("penalty_score")) fp.penalty_score = f.Double("penalty_score", f.node()["penalty_score"]);
      if (f.Has("max_retries")) {
        const YAML::Node n = f.node()["max_retries"];
        if (fp.mode != FailureMode::kRetry) {
          f.Fail("failure_policy.max_retries", n,
                 fmt::format("only used with mode retry (mode is {})", ToString(fp.mode)));
        }
        f.Read("max_retries", &fp.max_retries);
        if (fp.max_retries < 1) f.Fail("failure_policy.max_retries", n, "must be >= 1");
      }
      if (fp.mode == FailureMode::kAbort) fp.abort_after = 1;
      f.Read("abort_after", &fp.abort_after);
      if (fp.abort_after < 0) f.Fail("failure_policy.abort_after", f.node()["abort_after"], "must be >= 0 (0: never)");
      if (fp.mode == FailureMode::kAbort && fp.abort_after < 1) {
        f.Fail("failure_policy.abort_after", f.node()["abort_after"], "must be >= 1 with mode abort");
      }
      f.Finish();
    } else {
      top.Get("failure_policy");
    }
  });

  errors.Check([&] {
    const std::filesystem::path root = std::filesystem::absolute(options.results_root);
    spec.results.store = (root / (spec.name + ".sqlite")).lexically_normal();
    spec.results.out_dir = (root / spec.name).lexically_normal();
    spec.results.earlier_default_store = spec.base_dir / "results" / (spec.name + ".sqlite");
    if (top.Has("results")) {
      MapReader r(top.Get("results"), "results", &spec.source);
      std::string store, out_dir;
      r.Read("store", &store);
      r.Read("out_dir", &out_dir);
      if (r.Has("store")) {
        if (store.empty()) r.Fail("results.store", r.node()["store"], "must be a file path");
        spec.results.store = Resolve(spec.base_dir, store);
        spec.results.earlier_default_store.clear();
      }
      if (r.Has("out_dir")) {
        if (out_dir.empty()) r.Fail("results.out_dir", r.node()["out_dir"], "must be a folder path");
        spec.results.out_dir = Resolve(spec.base_dir, out_dir);
      }
      r.Finish();
    } else {
      top.Get("results");
    }
  });
  errors.Check([&] { top.Finish(); });
  errors.ThrowIfAny(spec.source);
  return spec;
}

bool IsValidSpecName(const std::string& name) {
  if (name.empty()) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.';
  });
}

YAML::Node LoadSpecYaml(const std::string& text, const std::string& source) {
  // Its strings end up in JSON (the store keeps the spec as JSON; optimiser
  // settings are JSON), which must be UTF-8.
  if (const size_t at = FirstNonUtf8(text); at != std::string_view::npos) {
    const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<ptrdiff_t>(at), '\n');
    throw JobSpecError(fmt::format("{}: not UTF-8 text: byte {} (0x{:02X}) on line {}", source, at,
                                   static_cast<unsigned char>(text[at]), line));
  }
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw JobSpecError(fmt::format("{}: not valid YAML or JSON: {}", source, e.what()));
  }
  if (root.IsDefined() && !root.IsNull()) CheckYamlValues(root, source);
  return root;
}

namespace spec_reader {

nlohmann::json ReadOptimizerSettings(yaml_reader::MapReader& o, const std::string& path, const std::string& name) {
  nlohmann::json out = nlohmann::json::object();
  const YAML::Node settings = o.Get("settings");
  if (settings.IsDefined() && !settings.IsNull()) {
    if (!settings.IsMap()) o.Fail(path + ".settings", settings, "expected a map of settings");
    // The optimiser checks the names; the reader names a repeated one,
    // which the conversion to JSON would keep silently.
    (void)o.Nested(settings, path + ".settings");
    out = YamlToJson(settings);
  }
  if (o.Has("command")) {
    const YAML::Node command = o.Get("command");
    if (name != "external") o.Fail(path + ".command", command, "only an external optimiser runs a command");
    if (out.contains("command")) o.Fail(path + ".command", command, "given twice: here and in settings");
    out["command"] = YamlToJson(command);
  }
  return out;
}

std::string ReadSpecFile(const std::filesystem::path& path, const char* what) {
  std::ifstream in(path);
  if (!in) throw JobSpecError(fmt::format("{}: cannot open {}", path.string(), what));
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace spec_reader

JobSpec ParseJobSpec(const std::string& text, const std::string& source,
                     const std::filesystem::path& base_dir, const JobSpecParseOptions& options) {
  return ParseJobSpecYaml(spec_reader::LoadSpecYaml(text, source), source, base_dir, options);
}

JobSpec ParseJobSpec(const nlohmann::json& doc, const std::string& source,
                     const std::filesystem::path& base_dir, const JobSpecParseOptions& options) {
  // JSON is YAML; dump() writes doubles with round-trip precision.
  return ParseJobSpec(doc.dump(), source, base_dir, options);
}

JobSpec LoadJobSpec(const std::filesystem::path& path, const JobSpecParseOptions& options) {
  const std::string text = spec_reader::ReadSpecFile(path, "job spec");
  const std::filesystem::path base = std::filesystem::absolute(path).parent_path();
  return ParseJobSpec(text, path.string(), base, options);
}

void CheckRecordings(const JobSpec& spec) { CheckRecordings(spec.source, spec.train, spec.holdout); }

void CheckRecordings(const std::string& source, const std::vector<std::filesystem::path>& train,
                     const std::vector<std::filesystem::path>& holdout) {
  auto check = [&](const std::vector<std::filesystem::path>& dirs, const char* key) {
    for (size_t i = 0; i < dirs.size(); ++i) {
      try {
        (void)LoadRecording(dirs[i]);
      } catch (const std::exception& e) {
        throw JobSpecError(fmt::format("{}: {}[{}] = '{}': {}", source, key, i,
                                       dirs[i].string(), e.what()));
      }
    }
  };
  check(train, "train");
  check(holdout, "holdout");
}

}  // namespace calib
