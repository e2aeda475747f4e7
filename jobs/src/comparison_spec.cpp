// Reading and validating comparison specs (comparison_spec.h). The
// objective's part is a job spec: each run's spec is the comparison's with
// its optimiser, seed and results set, read by the job spec reader, so the
// two formats cannot drift apart.

#include "calib/jobs/comparison_spec.h"

#include "calib/search/factory.h"
#include "spec_reader.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <set>

namespace calib {
namespace {

using YamlMapReader = yaml_reader::MapReader;

// Keys of a comparison that are not a job spec's.
const char* const kComparisonKeys[] = {"optimizers", "seeds", "targets"};
// Keys of a job spec that each run sets for itself.
const char* const kPerRunKeys[] = {"optimizer", "seed", "results"};

std::vector<ComparedOptimizer> ReadOptimizers(YamlMapReader& top) {
  const YAML::Node list = top.Require("optimizers", "a list of optimisers ({name, label, settings})");
  if (!list.IsSequence() || list.size() == 0) {
    top.Fail("optimizers", list, "expected a non-empty list of optimisers ({name, label, settings})");
  }
  const std::vector<std::string> names = search::AllOptimizerNames();
  std::vector<ComparedOptimizer> out;
  std::set<std::string> labels;
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string path = fmt::format("optimizers[{}]", i);
    YamlMapReader o = top.Nested(list[i], path);
    ComparedOptimizer c;
    const YAML::Node n = o.Require("name", fmt::format("one of {}", fmt::join(names, ", ")));
    c.name = o.String("name", n);
    if (std::find(names.begin(), names.end(), c.name) == names.end()) {
      o.Fail(path + ".name", n, fmt::format("unknown optimiser; one of {}", fmt::join(names, ", ")));
    }
    c.label = c.name;
    std::replace(c.label.begin(), c.label.end(), ':', '_');
    if (o.Has("label")) {
      const YAML::Node l = o.Get("label");
      c.label = o.String("label", l);
      if (!spec_reader::ValidName(c.label)) {
        o.Fail(path + ".label", l, "must be non-empty letters, digits, '_', '-', '.'");
      }
    }
    if (!labels.insert(c.label).second) {
      o.Fail(path + ".label", YAML::Node(c.label),
             "another optimiser has this label; give each a distinct `label`");
    }
    c.settings = spec_reader::ReadOptimizerSettings(o, path, c.name);
    c.seed_independent = search::SeedIndependent(c.name);
    o.Finish();
    out.push_back(std::move(c));
  }
  return out;
}

std::vector<uint64_t> ReadSeeds(YamlMapReader& top) {
  std::vector<uint64_t> seeds;
  if (!top.Has("seeds")) {
    for (uint64_t s = 1; s <= 15; ++s) seeds.push_back(s);
    return seeds;
  }
  const YAML::Node n = top.Get("seeds");
  if (n.IsScalar()) {
    const int64_t count = top.Int("seeds", n);
    if (count < 1) top.Fail("seeds", n, "must be >= 1 (seeds 1..N), or a list of seeds");
    for (int64_t s = 1; s <= count; ++s) seeds.push_back(static_cast<uint64_t>(s));
    return seeds;
  }
  if (!n.IsSequence() || n.size() == 0) top.Fail("seeds", n, "expected an integer N >= 1 or a list of seeds");
  for (size_t i = 0; i < n.size(); ++i) {
    const std::string path = fmt::format("seeds[{}]", i);
    const int64_t s = top.ToInt(n[i], path);
    if (s < 0) top.Fail(path, n[i], "must be >= 0");
    if (std::find(seeds.begin(), seeds.end(), static_cast<uint64_t>(s)) != seeds.end()) {
      top.Fail(path, n[i], "repeats an earlier seed");
    }
    seeds.push_back(static_cast<uint64_t>(s));
  }
  return seeds;
}

ComparisonTargets ReadTargets(YamlMapReader& top) {
  ComparisonTargets t;
  if (!top.Has("targets")) return t;
  YamlMapReader r = top.Child("targets");
  const bool relative = r.Has("relative");
  const bool absolute = r.Has("absolute");
  if (relative == absolute) {
    r.Fail("targets", r.node(), "expected exactly one of relative (fractions of the best score) or absolute (scores)");
  }
  const std::string key = relative ? "relative" : "absolute";
  t.kind = relative ? TargetKind::kRelative : TargetKind::kAbsolute;
  const YAML::Node list = r.Get(key);
  if (!list.IsSequence() || list.size() == 0) r.Fail(r.KeyPath(key), list, "expected a non-empty list of numbers");
  t.values.clear();
  for (size_t i = 0; i < list.size(); ++i) {
    const std::string path = fmt::format("targets.{}[{}]", key, i);
    const double v = r.ToDouble(list[i], path);
    if (relative && v < 0.0) r.Fail(path, list[i], "must be >= 0 (a fraction of the best score)");
    t.values.push_back(v);
  }
  r.Finish();
  return t;
}

// The run's job spec: the comparison's objective with this optimiser, seed
// and results. A JobSpecError about the optimiser is reported against the
// comparison's key (`optimizers[i].settings`).
JobSpec RunSpec(const YAML::Node& objective, const ComparedOptimizer& optimizer, size_t index,
                uint64_t seed, const std::string& job_name, const std::filesystem::path& store,
                const std::filesystem::path& out_dir, const std::string& source,
                const std::filesystem::path& base_dir, const JobSpecParseOptions& options) {
  YAML::Node node = YAML::Clone(objective);
  node["name"] = job_name;
  YAML::Node o;
  o["name"] = optimizer.name;
  if (!optimizer.settings.empty()) o["settings"] = YAML::Load(optimizer.settings.dump());
  node["optimizer"] = o;
  node["seed"] = seed;
  node["results"]["store"] = store.string();
  node["results"]["out_dir"] = (out_dir / "runs" / job_name).string();
  try {
    return ParseJobSpecYaml(node, source, base_dir, options);
  } catch (const JobSpecError& e) {
    std::string message = e.what();
    const std::string from = ": optimizer.";
    const std::string to = fmt::format(": optimizers[{}].", index);
    for (size_t at = message.find(from); at != std::string::npos; at = message.find(from, at + to.size())) {
      message.replace(at, from.size(), to);
    }
    throw JobSpecError(message);
  }
}

}  // namespace

nlohmann::json ComparisonSpec::ToJson() const {
  nlohmann::json j;
  j["name"] = name;
  j["seeds"] = seeds;
  j["budget_evaluations"] = budget_evaluations;
  j["targets"] = {{"kind", targets.kind == TargetKind::kRelative ? "relative" : "absolute"},
                  {"values", targets.values}};
  j["optimizers"] = nlohmann::json::array();
  for (const ComparedOptimizer& o : optimizers) {
    j["optimizers"].push_back({{"label", o.label},
                               {"name", o.name},
                               {"settings", o.settings},
                               {"seed_independent", o.seed_independent}});
  }
  j["runs"] = nlohmann::json::array();
  for (const ComparisonRun& r : runs) {
    j["runs"].push_back({{"label", r.label}, {"seed", r.seed}, {"job", calib::ToJson(r.job)}});
  }
  return j;
}

ComparisonSpec ParseComparisonSpec(const std::string& text, const std::string& source,
                                   const std::filesystem::path& base_dir,
                                   const std::filesystem::path& out_dir,
                                   const JobSpecParseOptions& options) {
  const YAML::Node root = spec_reader::LoadSpecYaml(text, source);
  if (!root.IsDefined() || root.IsNull()) throw JobSpecError(fmt::format("{}: empty comparison spec", source));
  ComparisonSpec spec;
  spec.source = source;
  spec_reader::MapReader top(root, "", &spec.source);
  for (const char* key : kPerRunKeys) {
    if (top.Has(key)) {
      top.Fail(key, top.Get(key),
               "set per run by the comparison (optimizers, seeds, --out); leave it out");
    }
  }
  spec.optimizers = ReadOptimizers(top);
  spec.seeds = ReadSeeds(top);
  spec.targets = ReadTargets(top);

  // The objective: everything else, read as a job spec (its errors name the
  // file and key as a job spec's do) with the first optimiser and seed.
  YAML::Node objective = YAML::Clone(root);
  for (const char* key : kComparisonKeys) objective.remove(key);
  const YAML::Node name = top.Require("name", "a comparison name (letters, digits, '_', '-', '.')");
  spec.name = top.String("name", name);
  if (!spec_reader::ValidName(spec.name)) top.Fail("name", name, "must be non-empty letters, digits, '_', '-', '.'");
  // Every output's default place is under out/ in the current folder.
  const std::filesystem::path out =
      std::filesystem::absolute(out_dir.empty() ? kDefaultComparisonRoot / spec.name : out_dir)
          .lexically_normal();
  spec.out_dir = out;
  spec.store = out / "comparison.sqlite";
  for (size_t i = 0; i < spec.optimizers.size(); ++i) {
    const ComparedOptimizer& o = spec.optimizers[i];
    for (const uint64_t seed : spec.seeds) {
      ComparisonRun run;
      run.label = o.label;
      run.seed = seed;
      const std::string job_name = fmt::format("{}.{}.s{}", spec.name, o.label, seed);
      run.job = RunSpec(objective, o, i, seed, job_name, spec.store, out, source, base_dir, options);
      spec.runs.push_back(std::move(run));
      if (o.seed_independent) break;
    }
  }
  spec.budget_evaluations = spec.runs.front().job.budget.evaluations;
  return spec;
}

ComparisonSpec LoadComparisonSpec(const std::filesystem::path& path,
                                  const std::filesystem::path& out_dir,
                                  const JobSpecParseOptions& options,
                                  const std::filesystem::path& base_dir) {
  const std::string text = spec_reader::ReadSpecFile(path, "comparison spec");
  const std::filesystem::path base =
      base_dir.empty() ? std::filesystem::absolute(path).parent_path() : std::filesystem::absolute(base_dir);
  return ParseComparisonSpec(text, path.string(), base, out_dir, options);
}

}  // namespace calib
