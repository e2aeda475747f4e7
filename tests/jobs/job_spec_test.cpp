// The job spec: a valid spec round-trips through its canonical JSON; every
// kind of bad input is rejected with a message naming the field, the value
// and the rule; the search space maps the unit box to parameter values.

#include "calib/jobs/job_spec.h"

#include "support/test_support.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <utility>

namespace calib {
namespace {

namespace fs = std::filesystem;

constexpr const char* kValidSpec = R"yaml(
name: push_test
train: [rec_a]
holdout: [rec_b]
model:
  effects: []
  substeps: 12
  integrator: verlet
  constraint_iterations: 6
  outline_contact: true
  contact_friction: 0.4
  segmentation: {open_radius_px: 2, close_radius_px: 3, fill_holes: false}
  mesh: {edge_length_px: 18.5}
parameters:
  - {name: k_D, lower: 10, upper: 1000, scale: log}
  - {name: k_d, lower: 0, upper: 5}
  - {name: k_A, lower: 1, upper: 500, scale: log}
  - {name: k_phi, fixed: 0.25}
  - {name: mass, fixed: 1}
  - {name: tau, lower: 0, upper: 1, scale: linear}
optimizer:
  name: cmaes
  settings: {population: 6, initial_sigma: 0.25}
budget: {evaluations: 120, wall_time_s: 3600, prune_factor: 2.5}
seed: 42
threads: 2
processes: 3
checkpoint: {every_evaluations: 24, every_seconds: 30}
failure_policy: {mode: retry, max_retries: 2, penalty_score: 1.0e9}
results: {store: out/push_test.sqlite, out_dir: out/push_test}
)yaml";

// A folder with two fake recordings (rec_a, rec_b: recording.json present).
fs::path MakeJobFolder(const std::string& name) {
  const fs::path dir = testing::ScratchDir(name);
  for (const char* rec : {"rec_a", "rec_b"}) {
    fs::create_directories(dir / rec);
    std::ofstream(dir / rec / "recording.json") << "{}\n";
  }
  return dir;
}

// The valid spec with one edit applied, parsed; returns the error message
// ("" when it parsed).
std::string ErrorOf(const std::function<void(YAML::Node&)>& edit,
                    const std::string& folder = "job_spec_errors") {
  const fs::path dir = MakeJobFolder(folder);
  YAML::Node root = YAML::Load(kValidSpec);
  edit(root);
  YAML::Emitter out;
  out << root;
  try {
    ParseJobSpec(std::string(out.c_str()), "job.yaml", dir);
  } catch (const JobSpecError& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "message: " << (text) << "\nmissing: " << (part)

TEST(JobSpec, ValidSpecIsReadCompletely) {
  const fs::path dir = MakeJobFolder("job_spec_valid");
  const JobSpec spec = ParseJobSpec(std::string(kValidSpec), "job.yaml", dir);
  EXPECT_EQ(spec.name, "push_test");
  ASSERT_EQ(spec.train.size(), 1u);
  EXPECT_EQ(spec.train[0], (fs::absolute(dir) / "rec_a").lexically_normal());
  ASSERT_EQ(spec.holdout.size(), 1u);
  EXPECT_EQ(spec.model.simulation.substeps, 12);
  EXPECT_EQ(spec.model.simulation.integrator, IntegratorKind::kVerlet);
  EXPECT_EQ(spec.model.simulation.constraint_iterations, 6);
  EXPECT_TRUE(spec.model.simulation.outline_contact);
  EXPECT_EQ(spec.model.simulation.contact_friction, 0.4);
  EXPECT_EQ(spec.model.preparation.segmentation.open_radius_px, 2);
  EXPECT_FALSE(spec.model.preparation.segmentation.fill_holes);
  EXPECT_EQ(spec.model.preparation.mesher.edge_length_px, 18.5);
  ASSERT_EQ(spec.parameters.size(), 6u);
  EXPECT_EQ(spec.parameters[0].scale, ParameterScale::kLog);
  EXPECT_EQ(*spec.parameters[3].fixed, 0.25);
  EXPECT_EQ(spec.SearchedNames(), (std::vector<std::string>{"k_D", "k_d", "k_A", "tau"}));
  EXPECT_EQ(spec.optimizer.name, "cmaes");
  EXPECT_EQ(spec.optimizer.settings["population"], 6);
  EXPECT_EQ(spec.optimizer.settings["max_evals"], 120) << "the budget fills the optimiser's own";
  EXPECT_EQ(spec.budget.evaluations, 120);
  EXPECT_EQ(*spec.budget.wall_time_s, 3600.0);
  EXPECT_EQ(*spec.budget.prune_factor, 2.5);
  EXPECT_EQ(spec.seed, 42u);
  EXPECT_EQ(spec.threads, 2);
  EXPECT_EQ(spec.processes, 3);
  EXPECT_EQ(spec.checkpoint.every_evaluations, 24);
  EXPECT_EQ(spec.failure_policy.mode, FailureMode::kRetry);
  EXPECT_EQ(spec.failure_policy.max_retries, 2);
  EXPECT_EQ(*spec.failure_policy.penalty_score, 1e9);
  EXPECT_EQ(spec.results.store, (fs::absolute(dir) / "out/push_test.sqlite").lexically_normal());
}

TEST(JobSpec, CanonicalJsonRoundTrips) {
  const fs::path dir = MakeJobFolder("job_spec_round_trip");
  const JobSpec spec = ParseJobSpec(std::string(kValidSpec), "job.yaml", dir);
  const nlohmann::json canonical = ToJson(spec);
  EXPECT_EQ(canonical["train"][0], "rec_a") << "paths are kept relative to the spec's folder";
  const JobSpec again = ParseJobSpec(canonical, "stored spec", dir);
  EXPECT_EQ(ToJson(again).dump(), canonical.dump());
  EXPECT_EQ(again.train, spec.train);
  EXPECT_EQ(again.results.store, spec.results.store);
  // The same spec as JSON text parses to the same canonical form.
  const JobSpec from_text = ParseJobSpec(canonical.dump(2), "job.json", dir);
  EXPECT_EQ(ToJson(from_text), canonical);
  const JobSpec from_tabs = ParseJobSpec(canonical.dump(1, '\t'), "job.json", dir);
  EXPECT_EQ(ToJson(from_tabs), canonical) << "JSON indented with tabs";
}

TEST(JobSpec, AreaWeightingNeedsInertiaAndRoundTrips) {
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["area_weighted"] = true; }),
                  "model.area_weighted = 'true': needs the inertia effect");
  const fs::path dir = MakeJobFolder("job_spec_area_weighted");
  YAML::Node root = YAML::Load(kValidSpec);
  root["model"]["effects"].push_back("inertia");
  root["model"]["area_weighted"] = true;
  for (const char* name : {"inertia_damping_per_s", "gravity_px_s2", "gravity_angle_deg"}) {
    YAML::Node p;
    p["name"] = name;
    p["fixed"] = 1.0;
    root["parameters"].push_back(p);
  }
  YAML::Emitter out;
  out << root;
  const JobSpec spec = ParseJobSpec(std::string(out.c_str()), "job.yaml", dir);
  EXPECT_TRUE(spec.model.simulation.area_weighted);
  const nlohmann::json canonical = ToJson(spec);
  EXPECT_EQ(canonical["model"]["area_weighted"], true);
  EXPECT_TRUE(ParseJobSpec(canonical, "stored spec", dir).model.simulation.area_weighted);
  // Off is the default and left out, as for a job stored before the key.
  EXPECT_FALSE(ToJson(ParseJobSpec(std::string(kValidSpec), "job.yaml", dir))["model"].contains(
      "area_weighted"));
}

TEST(JobSpec, MinEdgesAcrossRoundTripsAndABadValueIsNamed) {
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["mesh"]["min_edges_across"] = 17; }),
                  "model.mesh.min_edges_across = '17': must be in [0, 16]");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["mesh"]["min_edges_across"] = -1; }),
                  "model.mesh.min_edges_across = '-1'");
  const fs::path dir = MakeJobFolder("job_spec_min_edges_across");
  YAML::Node root = YAML::Load(kValidSpec);
  root["model"]["mesh"]["min_edges_across"] = 2;
  YAML::Emitter out;
  out << root;
  const JobSpec spec = ParseJobSpec(std::string(out.c_str()), "job.yaml", dir);
  EXPECT_EQ(spec.model.preparation.mesher.min_edges_across, 2);
  const nlohmann::json canonical = ToJson(spec);
  EXPECT_EQ(canonical["model"]["mesh"]["min_edges_across"], 2);
  EXPECT_EQ(ParseJobSpec(canonical, "stored spec", dir).model.preparation.mesher.min_edges_across, 2);
  // Off is the default and left out, as for a job stored before the key.
  EXPECT_FALSE(ToJson(ParseJobSpec(std::string(kValidSpec), "job.yaml", dir))["model"]["mesh"].contains(
      "min_edges_across"));
}

TEST(JobSpec, DefaultsAreFilledIn) {
  const fs::path dir = MakeJobFolder("job_spec_defaults");
  const JobSpec spec = ParseJobSpec(std::string(R"yaml(
name: minimal
train: [rec_a]
parameters:
  - {name: k_D, lower: 1, upper: 100}
  - {name: k_d, fixed: 0}
  - {name: k_A, fixed: 1}
  - {name: k_phi, fixed: 0}
  - {name: mass, fixed: 1}
  - {name: tau, fixed: 0}
optimizer: {name: "nlopt:BOBYQA"}
budget: {evaluations: 30}
)yaml"),
                                    "min.yaml", dir);
  EXPECT_TRUE(spec.holdout.empty());
  EXPECT_EQ(spec.model.simulation.substeps, 10);
  EXPECT_FALSE(spec.model.simulation.outline_contact);
  // Off is the default and left out of the canonical JSON, so that jobs
  // stored before the key existed resume with the same spec.
  EXPECT_FALSE(ToJson(spec)["model"].contains("outline_contact"));
  EXPECT_EQ(spec.model.simulation.contact_friction, 0.0);
  EXPECT_FALSE(ToJson(spec)["model"].contains("contact_friction"));
  EXPECT_EQ(spec.seed, 1u);
  EXPECT_EQ(spec.threads, 0);
  EXPECT_EQ(spec.optimizer.settings["maxeval"], 30);
  EXPECT_EQ(spec.failure_policy.mode, FailureMode::kPenalty);
  EXPECT_EQ(spec.failure_policy.abort_after, 0);
  // Every output's default place is under out/ in the current folder.
  EXPECT_EQ(spec.results.store, (fs::absolute("out/jobs") / "minimal.sqlite").lexically_normal());
  EXPECT_EQ(spec.results.out_dir, (fs::absolute("out/jobs") / "minimal").lexically_normal());
  EXPECT_EQ(spec.results.earlier_default_store, fs::absolute(dir) / "results/minimal.sqlite")
      << "where a job stored before the out/ default is looked for";
}

TEST(JobSpec, OverridesReplaceTheSpecsValuesAndAreCheckedByItsRules) {
  const fs::path dir = MakeJobFolder("job_spec_overrides");
  JobSpecParseOptions options;
  options.overrides.name = "renamed";
  options.overrides.seed = 77;
  options.overrides.budget_evaluations = 240;
  options.results_root = dir / "elsewhere";
  const JobSpec spec = ParseJobSpec(std::string(kValidSpec), "job.yaml", dir, options);
  EXPECT_EQ(spec.name, "renamed");
  EXPECT_EQ(spec.seed, 77u);
  EXPECT_EQ(spec.budget.evaluations, 240);
  EXPECT_EQ(spec.optimizer.settings["max_evals"], 240) << "the optimiser's own budget follows";
  EXPECT_EQ(spec.results.store, (fs::absolute(dir) / "out/push_test.sqlite").lexically_normal())
      << "a store the spec names is kept";

  options.overrides.name = "bad name!";
  try {
    (void)ParseJobSpec(std::string(kValidSpec), "job.yaml", dir, options);
    ADD_FAILURE() << "an invalid --name was accepted";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "job.yaml: name = 'bad name!' (given with --name)");
  }
  options.overrides.name.reset();
  options.overrides.budget_evaluations = 0;
  try {
    (void)ParseJobSpec(std::string(kValidSpec), "job.yaml", dir, options);
    ADD_FAILURE() << "--budget 0 was accepted";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "budget.evaluations = 0 (given with --budget): must be >= 1");
  }
}

TEST(JobSpec, LoadResolvesPathsAgainstTheFileFolder) {
  const fs::path dir = MakeJobFolder("job_spec_load");
  fs::create_directories(dir / "specs");
  std::string text = kValidSpec;
  text.replace(text.find("[rec_a]"), 7, "[../rec_a]");
  text.replace(text.find("[rec_b]"), 7, "[../rec_b]");
  std::ofstream(dir / "specs" / "job.yaml") << text;
  const JobSpec spec = LoadJobSpec(dir / "specs" / "job.yaml");
  EXPECT_EQ(spec.train[0], (fs::absolute(dir) / "rec_a").lexically_normal());
  EXPECT_EQ(spec.source, (dir / "specs" / "job.yaml").string());
  EXPECT_EQ(ToJson(spec)["train"][0], "../rec_a");
}

TEST(JobSpec, UnreadableFileIsNamed) {
  try {
    LoadJobSpec(testing::ScratchDir("job_spec_absent") / "absent.yaml");
    FAIL() << "no error";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "absent.yaml");
  }
}

TEST(JobSpec, InvalidYamlIsNamed) {
  try {
    ParseJobSpec(std::string("name: [unclosed"), "broken.yaml", ".");
    FAIL() << "no error";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "broken.yaml");
  }
}

// Found by fuzz/fuzz_job_spec (scripts/fuzz.sh): a byte that is not UTF-8 in
// an optimiser setting escaped as nlohmann::json::type_error (the setting's
// message writes the settings as JSON); in a path it gave an accepted spec
// whose canonical JSON (ToJson, kept by the store) cannot be written.
TEST(JobSpec, TextThatIsNotUtf8IsNamed) {
  const fs::path dir = MakeJobFolder("job_spec_utf8");
  const auto edited = [](const std::string& from, const std::string& to) {
    std::string text = kValidSpec;
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return text.replace(at, from.size(), to);
  };
  const std::string setting = edited("population: 6", "population: 6      \xA0");
  try {
    ParseJobSpec(setting, "job.yaml", dir);
    FAIL() << "no error";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "job.yaml: not UTF-8 text: byte 603 (0xA0) on line 23");
  }
  for (const std::string& bad : {edited("train: [rec_a]", "train: [\"rec_\xFF\"]"),
                                 std::string(kValidSpec) + "# overlong \xE0\x80\xAF\n",
                                 std::string(kValidSpec) + "# cut \xF0\x9F\x93"}) {
    try {
      ParseJobSpec(bad, "job.yaml", dir);
      ADD_FAILURE() << "no error for: " << bad;
    } catch (const JobSpecError& e) {
      EXPECT_CONTAINS(e.what(), "job.yaml: not UTF-8 text: byte ");
    }
  }
  // Later, at 422 498 executions: UTF-8 text in which yaml-cpp reads a NUL
  // byte and the one after it as 0xA0 (a key of optimizer.settings).
  const std::string nul = edited("initial_sigma", std::string("initial\0_sigma", 14));
  try {
    ParseJobSpec(nul, "job.yaml", dir);
    FAIL() << "no error";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "job.yaml: line 23: a value or key is not UTF-8 once read as YAML");
  }
  // UTF-8 beyond ASCII is fine.
  EXPECT_NO_THROW(ParseJobSpec(std::string(kValidSpec) + "# Gr\xC3\xB6\xC3\x9F" "e \xF0\x9F\x93\x8F\n",
                               "job.yaml", dir));
}

// Found by running fuzz/fuzz_job_spec on YAML aliases: an alias inside its
// own anchor overflowed the stack (AddressSanitizer: stack-overflow, in the
// message that shows the value), and aliases of aliases ("billion laughs")
// ran past libFuzzer's 10 s timeout.
TEST(JobSpec, AliasCyclesAndAliasBombsAreNamed) {
  const fs::path dir = MakeJobFolder("job_spec_aliases");
  std::string laughs = "  settings:\n    a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n";
  for (int i = 1; i < 9; ++i) {
    laughs += "    a" + std::to_string(i) + ": &a" + std::to_string(i) + " [";
    for (int k = 0; k < 10; ++k) laughs += (k ? ", *a" : "*a") + std::to_string(i - 1);
    laughs += "]\n";
  }
  for (const std::string& bad :
       {std::string("name: &a [*a]\n"), std::string("optimizer: {name: cmaes, settings: &s {x: *s}}\n"),
        "optimizer:\n  name: cmaes\n" + laughs}) {
    try {
      ParseJobSpec(bad, "job.yaml", dir);
      ADD_FAILURE() << "no error for: " << bad;
    } catch (const JobSpecError& e) {
      EXPECT_CONTAINS(e.what(), "job.yaml: holds more than 100000 values once its aliases are expanded");
    }
  }
  // An alias used as a shorthand is fine.
  std::string shared = kValidSpec;
  shared.replace(shared.find("settings: {population: 6"), 9, "settings: &s");
  shared += "unused_here: *s\n";
  const std::string m = [&] {
    try {
      ParseJobSpec(shared, "job.yaml", dir);
    } catch (const JobSpecError& e) {
      return std::string(e.what());
    }
    return std::string();
  }();
  EXPECT_CONTAINS(m, "unused_here");  // an unknown key, not the alias
}

TEST(JobSpec, MissingFieldIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r.remove("budget"); });
  EXPECT_CONTAINS(m, "job.yaml: budget: missing");
  const std::string n = ErrorOf([](YAML::Node& r) { r["optimizer"].remove("name"); });
  EXPECT_CONTAINS(n, "optimizer.name: missing");
}

TEST(JobSpec, WrongTypeIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["budget"]["evaluations"] = "many"; });
  EXPECT_CONTAINS(m, "budget.evaluations = 'many': expected an integer");
  const std::string n = ErrorOf([](YAML::Node& r) { r["parameters"][1]["upper"] = "high"; });
  EXPECT_CONTAINS(n, "parameters[1].upper = 'high': expected a number");
  const std::string t = ErrorOf([](YAML::Node& r) { r["train"] = "rec_a"; });
  EXPECT_CONTAINS(t, "train = 'rec_a': expected a list");
}

TEST(JobSpec, TheFramesKeyLimitsTheScoredFramesAndANegativeCountIsNamed) {
  const fs::path dir = MakeJobFolder("job_spec_frames");
  YAML::Node root = YAML::Load(kValidSpec);
  EXPECT_EQ(ParseJobSpec(std::string(kValidSpec), "job.yaml", dir).model.preparation.max_frames, 0)
      << "every frame by default";
  root["model"]["frames"] = 240;
  YAML::Emitter out;
  out << root;
  const JobSpec spec = ParseJobSpec(std::string(out.c_str()), "job.yaml", dir);
  EXPECT_EQ(spec.model.preparation.max_frames, 240);
  const nlohmann::json canonical = ToJson(spec);
  EXPECT_EQ(canonical["model"]["frames"], 240);
  EXPECT_EQ(ParseJobSpec(canonical, "stored spec", dir).model.preparation.max_frames, 240);
  const std::string m = ErrorOf([](YAML::Node& r) { r["model"]["frames"] = -5; });
  EXPECT_CONTAINS(m, "model.frames = '-5': must be >= 0");
}

TEST(JobSpec, UnknownKeyIsNamedWithASuggestion) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["optimiser"] = r["optimizer"]; });
  EXPECT_CONTAINS(m, "job.yaml: optimiser = {name: cmaes, ");
  EXPECT_CONTAINS(m, "unknown key");
  EXPECT_CONTAINS(m, "did you mean 'optimizer'?");
  const std::string n = ErrorOf([](YAML::Node& r) { r["parameters"][1]["uper"] = 4; });
  EXPECT_CONTAINS(n, "parameters[1].uper = '4': unknown key");
  EXPECT_CONTAINS(n, "did you mean 'upper'?");
  const std::string t = ErrorOf([](YAML::Node& r) { r["sed"] = 3; });
  EXPECT_CONTAINS(t, "sed = '3': unknown key");
  EXPECT_CONTAINS(t, "did you mean 'seed'?");
}

TEST(JobSpec, ReversedBoundsAreNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) {
    r["parameters"][2]["lower"] = 50;
    r["parameters"][2]["upper"] = 5;
  });
  EXPECT_CONTAINS(m, "parameters[2].upper = '5': must be > parameters[2].lower (50)");
}

TEST(JobSpec, LogScaleNeedsPositiveLowerBound) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["parameters"][0]["lower"] = 0; });
  EXPECT_CONTAINS(m, "parameters[0].lower = '0': must be > 0 on a log scale");
}

TEST(JobSpec, BoundsOutsideTheAllowedRangeAreNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["parameters"][5]["upper"] = 2; });
  EXPECT_CONTAINS(m, "parameters[5].upper = '2': must be within tau's allowed range [0, 1]");
  const std::string f = ErrorOf([](YAML::Node& r) { r["parameters"][4]["fixed"] = 0; });
  EXPECT_CONTAINS(f, "parameters[4].fixed = '0': must be within mass's allowed range (0");
  const std::string s = ErrorOf([](YAML::Node& r) { r["parameters"][4]["lower"] = 1; });
  EXPECT_CONTAINS(s, "parameters[4].lower = '1': a fixed parameter takes no lower");
  const std::string inf = ErrorOf([](YAML::Node& r) { r["parameters"][1]["upper"] = ".inf"; });
  EXPECT_CONTAINS(inf, "parameters[1].upper = '.inf': must be finite");
}

TEST(JobSpec, ParameterNeitherSearchedNorFixedIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["parameters"].remove(5); });
  EXPECT_CONTAINS(m, "parameters ('tau'): missing");
  EXPECT_CONTAINS(m, "searched or fixed");
  const std::string n = ErrorOf([](YAML::Node& r) { r["parameters"][5].remove("upper"); });
  EXPECT_CONTAINS(n, "parameters[5].upper: missing");
}

TEST(JobSpec, UnknownAndDuplicateParametersAreNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) {
    YAML::Node p;
    p["name"] = "k_X";
    p["fixed"] = 1;
    r["parameters"].push_back(p);
  });
  EXPECT_CONTAINS(m, "parameters[6].name = 'k_X': unknown parameter");
  const std::string d = ErrorOf([](YAML::Node& r) { r["parameters"][1]["name"] = "k_D"; });
  EXPECT_CONTAINS(d, "parameters[1].name = 'k_D': parameter listed twice");
  const std::string s = ErrorOf([](YAML::Node& r) { r["parameters"][1]["scale"] = "cubic"; });
  EXPECT_CONTAINS(s, "parameters[1].scale = 'cubic': must be linear or log");
}

// YAML keeps one of two equal keys silently; the spec names the repeat.
TEST(JobSpec, ARepeatedKeyIsNamed) {
  const fs::path dir = MakeJobFolder("job_spec_duplicate_key");
  auto error_of = [&](const std::string& text) {
    try {
      ParseJobSpec(text, "job.yaml", dir);
    } catch (const JobSpecError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_CONTAINS(error_of(std::string(kValidSpec) + "seed: 7\n"),
                  "job.yaml: seed = '7': the key appears more than once");
  std::string nested(kValidSpec);
  nested.replace(nested.find("budget: {evaluations: 120,"), 26,
                 "budget: {evaluations: 120, evaluations: 5,");
  EXPECT_CONTAINS(error_of(nested), "budget.evaluations = '5': the key appears more than once");
  std::string settings(kValidSpec);
  settings.replace(settings.find("{population: 6,"), 15, "{population: 6, population: 8,");
  EXPECT_CONTAINS(error_of(settings),
                  "optimizer.settings.population = '8': the key appears more than once");
}

// A misspelt required key is named as such, not only as the key missing.
TEST(JobSpec, AMisspeltRequiredKeyIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) {
    r["budjet"] = r["budget"];
    r.remove("budget");
  });
  EXPECT_CONTAINS(m, "job.yaml: budget: missing");
  EXPECT_CONTAINS(m, "found 'budjet': a misspelling?");
}

TEST(JobSpec, ASpecWithSeveralErrorsNamesEveryOne) {
  const std::string m = ErrorOf([](YAML::Node& r) {
    r["name"] = "bad name";
    r["train"][0] = "nope";
    r["parameters"][0]["lower"] = -1;  // on a log scale
    r["parameters"][2]["upper"] = 0.5;  // below lower
    r["budget"]["evaluations"] = 0;
    r["optimizer"]["name"] = "simplex";
    r["checkpoint"]["every_seconds"] = -1;
    r["colour"] = "blue";
  });
  EXPECT_CONTAINS(m, "job.yaml: 8 errors:\n");
  EXPECT_CONTAINS(m, "job.yaml: name = 'bad name'");
  EXPECT_CONTAINS(m, "job.yaml: train[0] = 'nope'");
  EXPECT_CONTAINS(m, "job.yaml: parameters[0].lower");
  EXPECT_CONTAINS(m, "job.yaml: parameters[2].upper = '0.5'");
  EXPECT_CONTAINS(m, "job.yaml: budget.evaluations = '0'");
  EXPECT_CONTAINS(m, "job.yaml: optimizer.name = 'simplex'");
  EXPECT_CONTAINS(m, "job.yaml: checkpoint.every_seconds = '-1'");
  EXPECT_CONTAINS(m, "job.yaml: colour = 'blue': unknown key");
  // One error is one line, as before.
  const std::string one = ErrorOf([](YAML::Node& r) { r["budget"]["evaluations"] = 0; });
  EXPECT_EQ(one.find('\n'), std::string::npos) << one;
  // The parameters are not checked against a model that is itself wrong:
  // their errors would only echo it.
  const std::string effect = ErrorOf([](YAML::Node& r) { r["model"]["effects"].push_back("nope"); });
  EXPECT_CONTAINS(effect, "model.effects[0] = 'nope'");
  EXPECT_EQ(effect.find("parameters"), std::string::npos) << effect;
}

TEST(JobSpec, UnknownOptimiserIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["optimizer"]["name"] = "simplex"; });
  EXPECT_CONTAINS(m, "optimizer.name = 'simplex': unknown optimiser");
  EXPECT_CONTAINS(m, "cmaes");
}

TEST(JobSpec, BadOptimiserSettingIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["optimizer"]["settings"]["population"] = 1; });
  EXPECT_CONTAINS(m, "optimizer.settings");
  EXPECT_CONTAINS(m, "population");
  const std::string u = ErrorOf([](YAML::Node& r) { r["optimizer"]["settings"]["sigma"] = 0.2; });
  EXPECT_CONTAINS(u, "optimizer.settings");
  EXPECT_CONTAINS(u, "sigma");
}

TEST(JobSpec, BadBudgetIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["budget"]["evaluations"] = 0; });
  EXPECT_CONTAINS(m, "budget.evaluations = '0': must be >= 1");
  const std::string w = ErrorOf([](YAML::Node& r) { r["budget"]["wall_time_s"] = -5; });
  EXPECT_CONTAINS(w, "budget.wall_time_s = '-5': must be > 0");
}

TEST(JobSpec, BadPruneFactorIsNamed) {
  for (const auto& [factor, shown] : {std::pair{1.0, "1"}, {0.5, "0.5"}, {-2.0, "-2"}}) {
    const std::string m = ErrorOf([&](YAML::Node& r) { r["budget"]["prune_factor"] = factor; });
    EXPECT_CONTAINS(m, "job.yaml: budget.prune_factor = '" + std::string(shown) + "': must be > 1");
  }
  const std::string text = ErrorOf([](YAML::Node& r) { r["budget"]["prune_factor"] = "twice"; });
  EXPECT_CONTAINS(text, "budget.prune_factor = 'twice': expected a number");
  const std::string nan = ErrorOf([](YAML::Node& r) {
    r["budget"]["prune_factor"] = std::numeric_limits<double>::quiet_NaN();
  });
  EXPECT_CONTAINS(nan, "budget.prune_factor = '.nan': must be finite");
}

TEST(JobSpec, MissingRecordingFolderIsNamed) {
  const std::string m = ErrorOf([](YAML::Node& r) { r["train"][0] = "nope"; });
  EXPECT_CONTAINS(m, "train[0] = 'nope': recording folder");
  EXPECT_CONTAINS(m, "does not exist");
  const std::string h = ErrorOf([](YAML::Node& r) { r["holdout"].push_back("."); });
  EXPECT_CONTAINS(h, "holdout[1] = '.'");
  EXPECT_CONTAINS(h, "no recording.json");
}

TEST(JobSpec, OtherRulesAreNamed) {
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["name"] = "a b"; }), "name = 'a b'");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["threads"] = -1; }), "threads = '-1': must be >= 0");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["seed"] = -1; }), "seed = '-1'");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["substeps"] = 0; }),
                  "model.substeps = '0': must be >= 1");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["outline_contact"] = "sometimes"; }),
                  "model.outline_contact");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["contact_friction"] = -0.5; }),
                  "model.contact_friction = '-0.5': must be >= 0");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["integrator"] = "rk4"; }),
                  "model.integrator = 'rk4': must be first_order, verlet or implicit_first_order");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["model"]["effects"].push_back("magnetism"); }),
                  "model.effects[0] = 'magnetism': unknown model effect");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["failure_policy"]["mode"] = "ignore"; }),
                  "failure_policy.mode = 'ignore'");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) { r["failure_policy"]["mode"] = "penalty"; }),
                  "failure_policy.max_retries = '2': only used with mode retry");
  EXPECT_CONTAINS(ErrorOf([](YAML::Node& r) {
                    r["checkpoint"]["every_evaluations"] = 0;
                    r["checkpoint"]["every_seconds"] = 0;
                  }),
                  "checkpoint = ");
}

TEST(JobSpec, EffectsAddTheirParameters) {
  ModelCatalog catalog = DefaultModelCatalog();
  ParameterSpec yield;
  yield.name = "yield";
  yield.unit = "1";
  yield.description = "plastic yield strain";
  yield.upper = 1.0;
  catalog.effects["test_effect"] = {yield};
  const fs::path dir = MakeJobFolder("job_spec_effects");
  YAML::Node root = YAML::Load(kValidSpec);
  root["model"]["effects"].push_back("test_effect");
  YAML::Emitter out;
  out << root;
  JobSpecParseOptions options;
  options.catalog = &catalog;
  try {
    ParseJobSpec(std::string(out.c_str()), "job.yaml", dir, options);
    FAIL() << "the effect's parameter is neither searched nor fixed";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "parameters ('yield'): missing");
  }
  YAML::Node p;
  p["name"] = "yield";
  p["lower"] = 0.01;
  p["upper"] = 0.5;
  root["parameters"].push_back(p);
  YAML::Emitter out2;
  out2 << root;
  const JobSpec spec = ParseJobSpec(std::string(out2.c_str()), "job.yaml", dir, options);
  EXPECT_EQ(spec.parameter_specs.size(), 7u);
  EXPECT_EQ(SearchSpace(spec).dimension(), 5);
}

TEST(JobSpec, TheDefaultCatalogueHoldsCoresEffects) {
  const ModelCatalog& catalog = DefaultModelCatalog();
  EXPECT_EQ(catalog.base.size(), BaseModelParameterSpecs().size());
  ASSERT_FALSE(catalog.effects.empty());
  const auto& [effect, specs] = *catalog.effects.begin();
  ASSERT_FALSE(specs.empty());
  const std::string m =
      ErrorOf([&](YAML::Node& r) { r["model"]["effects"].push_back(effect); }, "job_spec_core_effect");
  EXPECT_CONTAINS(m, "parameters ('" + specs[0].name + "'): missing");
}

TEST(SearchSpace, MapsTheUnitBoxToParametersAndBack) {
  const fs::path dir = MakeJobFolder("search_space");
  const JobSpec spec = ParseJobSpec(std::string(kValidSpec), "job.yaml", dir);
  const SearchSpace space(spec);
  ASSERT_EQ(space.dimension(), 4);
  EXPECT_EQ(space.names(), spec.SearchedNames());
  const search::Bounds b = space.UnitBounds();
  EXPECT_EQ(b.lower, std::vector<double>(4, 0.0));
  EXPECT_EQ(b.upper, std::vector<double>(4, 1.0));

  // Corners are the bounds exactly; fixed parameters ride along.
  const std::vector<double> zero(4, 0.0), one(4, 1.0);
  const ParameterValues lo = space.ToParameters(zero), hi = space.ToParameters(one);
  EXPECT_EQ(lo.at("k_D"), 10.0);
  EXPECT_EQ(hi.at("k_D"), 1000.0);
  EXPECT_EQ(hi.at("k_A"), 500.0);
  EXPECT_EQ(lo.at("k_phi"), 0.25);
  EXPECT_EQ(lo.at("mass"), 1.0);
  EXPECT_EQ(lo.size(), 6u);

  // Log scale: the middle of the box is the geometric mean.
  const std::vector<double> mid(4, 0.5);
  const ParameterValues m = space.ToParameters(mid);
  EXPECT_NEAR(m.at("k_D"), 100.0, 1e-9);
  EXPECT_NEAR(m.at("k_d"), 2.5, 1e-15);
  EXPECT_NEAR(m.at("tau"), 0.5, 1e-15);

  // Round trips, both ways.
  for (double t : {0.0, 0.1, 0.37, 0.5, 0.9, 1.0}) {
    const std::vector<double> u = {t, 1.0 - t, t * t, 0.5 * t};
    const std::vector<double> back = space.ToUnit(space.ToParameters(u));
    for (int i = 0; i < 4; ++i) EXPECT_NEAR(back[i], u[i], 1e-12) << "t " << t << " axis " << i;
  }
  ParameterValues v = lo;
  v["k_D"] = 314.0;
  v["k_A"] = 2.0;
  v["k_d"] = 1.25;
  v["tau"] = 0.75;
  const ParameterValues again = space.ToParameters(space.ToUnit(v));
  for (const auto& [name, value] : v) EXPECT_NEAR(again.at(name), value, 1e-12 * std::abs(value)) << name;

  // Every mapped point is valid for the model.
  EXPECT_NO_THROW(ValidateParameters(m, spec.parameter_specs, "mapped"));
  // Out-of-box points are clamped into the bounds.
  EXPECT_EQ(space.ToParameters(std::vector<double>{-1.0, 2.0, 0.0, 0.0}).at("k_D"), 10.0);
  EXPECT_THROW(space.ToParameters(std::vector<double>{0.5}), std::invalid_argument);
}

TEST(SearchSpace, TheJobOptimiserSearchesTheUnitBox) {
  const fs::path dir = MakeJobFolder("search_space_optimizer");
  const JobSpec spec = ParseJobSpec(std::string(kValidSpec), "job.yaml", dir);
  search::CheckedOptimizer opt = MakeRequestOptimizer(spec);
  EXPECT_EQ(opt.name(), "cmaes");
  EXPECT_EQ(opt.dimension(), 4);
  const std::vector<search::Candidate> batch = opt.Ask(100);
  ASSERT_EQ(batch.size(), 6u) << "one generation of population 6";
  const SearchSpace space(spec);
  for (const auto& c : batch) {
    EXPECT_NO_THROW(ValidateParameters(space.ToParameters(c.x), spec.parameter_specs, "candidate"));
  }
}

TEST(JobSpec, CheckRecordingsNamesTheFieldOfABadRecording) {
  const fs::path dir = MakeJobFolder("job_spec_check_recordings");
  const JobSpec spec = ParseJobSpec(std::string(kValidSpec), "job.yaml", dir);
  try {
    CheckRecordings(spec);  // rec_a's recording.json is an empty object
    FAIL() << "a recording without its keys was accepted";
  } catch (const JobSpecError& e) {
    EXPECT_CONTAINS(e.what(), "job.yaml: train[0] = '");
    EXPECT_CONTAINS(e.what(), "recording.json");
  }
}

TEST(JobSpec, CheckRecordingsAcceptsTheBundledExample) {
  const fs::path dir = testing::ScratchDir("job_spec_bundled");
  std::string text = kValidSpec;
  const std::string example = (fs::path(CALIB_SOURCE_DIR) / "examples/push_centre").string();
  text.replace(text.find("[rec_a]"), 7, "[" + example + "]");
  text.replace(text.find("[rec_b]"), 7, "[]");
  const JobSpec spec = ParseJobSpec(text, "job.yaml", dir);
  EXPECT_NO_THROW(CheckRecordings(spec));
}

TEST(JobSpec, ExampleSpecParses) {
  const fs::path path = fs::path(CALIB_SOURCE_DIR) / "examples/jobs/push_centre_cmaes.yaml";
  JobSpecParseOptions options;
  options.recordings = RecordingCheck::kNone;  // the example recordings may be regenerating
  const JobSpec spec = LoadJobSpec(path, options);
  EXPECT_EQ(spec.train[0], (fs::path(CALIB_SOURCE_DIR) / "examples/push_centre").lexically_normal());
  EXPECT_EQ(spec.optimizer.name, "cmaes");
  EXPECT_EQ(spec.holdout.size(), 1u);
}

}  // namespace
}  // namespace calib
