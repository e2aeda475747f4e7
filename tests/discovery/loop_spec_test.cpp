// Loop specs (discovery/loop_spec.h): `calib loop`'s options as keys, read
// with the command's defaults and ranges; ToJson reads back to the same
// spec; every malformed key is an error naming it.

#include "calib/discovery/loop_spec.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace calib {
namespace {

namespace fs = std::filesystem;

const fs::path kBase = "/data";

TEST(LoopSpec, KeysLeftOutTakeTheLoopsDefaults) {
  const LoopSpec spec = ParseLoopSpec("name: a\ntrain: [x, y/z]\n", "spec", kBase);
  const LoopOptions defaults;
  const LoopOptions& o = spec.options;
  EXPECT_EQ(spec.name, "a");
  EXPECT_EQ(o.train, (std::vector<fs::path>{"/data/x", "/data/y/z"}));
  EXPECT_TRUE(o.holdout.empty());
  EXPECT_EQ(o.seed, defaults.seed);
  EXPECT_EQ(o.budget, defaults.budget);
  EXPECT_EQ(o.effect_budget, defaults.effect_budget);
  EXPECT_EQ(o.optimizer, defaults.optimizer);
  EXPECT_EQ(o.max_effects, defaults.max_effects);
  EXPECT_EQ(o.tries_per_round, defaults.tries_per_round);
  EXPECT_EQ(o.min_confidence, defaults.min_confidence);
  EXPECT_EQ(o.false_discovery_rate, defaults.false_discovery_rate);
  EXPECT_EQ(o.min_relative_drop, defaults.min_relative_drop);
  EXPECT_EQ(o.held_out_stretch, defaults.held_out_stretch);
  EXPECT_EQ(o.equally_good_fits, defaults.equally_good_fits);
  EXPECT_EQ(o.refit_candidates, defaults.refit_candidates);
  EXPECT_EQ(o.restarts, defaults.restarts);
  EXPECT_EQ(o.effect_restarts, defaults.effect_restarts);
  EXPECT_EQ(o.overlays_per_recording, defaults.overlays_per_recording);
  EXPECT_EQ(o.simulation.outline_contact, defaults.simulation.outline_contact);
  EXPECT_EQ(o.simulation.contact_friction, defaults.simulation.contact_friction);
  EXPECT_EQ(o.simulation.integrator, defaults.simulation.integrator);
  EXPECT_EQ(o.rank_by_rate, defaults.rank_by_rate);
  EXPECT_EQ(o.write_html, defaults.write_html);
  EXPECT_TRUE(o.out_dir.empty()) << "the runner's to set";
}

TEST(LoopSpec, EveryKeyIsReadAndToJsonReadsBackToTheSameSpec) {
  const std::string text = R"(
name: every_key
train: [a]
holdout: [/elsewhere/b]
seed: 7
budget: 12
effect_budget: 6
optimizer: random
max_effects: 1
tries: 2
min_confidence: 0.5
rank_by: rate
fdr: 0.1
min_drop: 0.03
held_out_stretch: 0.25
equally_good_fits: 4
refit_candidates: 5
restarts: 2
effect_restarts: 3
overlays: 0
outline_contact: false
contact_friction: 0.25
integrator: first_order
html: false
)";
  const LoopSpec spec = ParseLoopSpec(text, "spec", kBase);
  const LoopOptions& o = spec.options;
  EXPECT_EQ(o.train, (std::vector<fs::path>{"/data/a"}));
  EXPECT_EQ(o.holdout, (std::vector<fs::path>{"/elsewhere/b"})) << "an absolute path stays";
  EXPECT_EQ(o.seed, 7u);
  EXPECT_EQ(o.budget, 12);
  EXPECT_EQ(o.effect_budget, 6);
  EXPECT_EQ(o.optimizer, "random");
  EXPECT_EQ(o.max_effects, 1);
  EXPECT_EQ(o.tries_per_round, 2);
  EXPECT_EQ(o.min_confidence, 0.5);
  EXPECT_TRUE(o.rank_by_rate);
  EXPECT_EQ(o.false_discovery_rate, 0.1);
  EXPECT_EQ(o.min_relative_drop, 0.03);
  EXPECT_EQ(o.held_out_stretch, 0.25);
  EXPECT_EQ(o.equally_good_fits, 4);
  EXPECT_EQ(o.refit_candidates, 5);
  EXPECT_EQ(o.restarts, 2);
  EXPECT_EQ(o.effect_restarts, 3);
  EXPECT_EQ(o.overlays_per_recording, 0);
  EXPECT_FALSE(o.simulation.outline_contact);
  EXPECT_EQ(o.simulation.contact_friction, 0.25);
  EXPECT_EQ(o.simulation.integrator, IntegratorKind::kFirstOrder);
  EXPECT_FALSE(o.write_html);
  const nlohmann::json canonical = ToJson(spec);
  EXPECT_EQ(ToJson(ParseLoopSpec(canonical.dump(), "canonical", "/other")), canonical);
}

TEST(LoopSpec, EveryMalformedKeyIsNamedWithItsRule) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"train: [a]", "spec: name: missing"},
      {"name: a b\ntrain: [a]", "spec: name = 'a b': must be non-empty letters"},
      {"name: a", "spec: train: missing"},
      {"name: a\ntrain: []", "spec: train = []: expected a non-empty list of recording folders"},
      {"name: a\ntrain: a", "spec: train = 'a': expected a non-empty list of recording folders"},
      {"name: a\ntrain: [a]\nholdout: [{x: 1}]", "spec: holdout[0] = {x: 1}"},
      {"name: a\ntrain: [a]\nbudget: 1", "spec: budget = '1': must be in [2, 100000000]"},
      {"name: a\ntrain: [a]\nbudget: many", "spec: budget = 'many'"},
      {"name: a\ntrain: [a]\neffect_budget: -1", "spec: effect_budget = '-1': must be >= 0"},
      {"name: a\ntrain: [a]\noptimizer: hillclimb", "spec: optimizer = 'hillclimb': unknown optimiser"},
      {"name: a\ntrain: [a]\ntries: 0", "spec: tries = '0': must be >= 1"},
      {"name: a\ntrain: [a]\nmin_confidence: 2", "spec: min_confidence = '2': must be in [0, 1]"},
      {"name: a\ntrain: [a]\nrank_by: often", "spec: rank_by = 'often': must be confidence or rate"},
      {"name: a\ntrain: [a]\nfdr: 0.9", "spec: fdr = '0.9': must be in [0.001, 0.5]"},
      {"name: a\ntrain: [a]\nmin_drop: 0.6", "spec: min_drop = '0.6': must be in [0, 0.5]"},
      {"name: a\ntrain: [a]\nheld_out_stretch: 0.99", "spec: held_out_stretch = '0.99': must be in [0.05, 0.95]"},
      {"name: a\ntrain: [a]\nrestarts: 0", "spec: restarts = '0': must be >= 1"},
      {"name: a\ntrain: [a]\neffect_restarts: 0", "spec: effect_restarts = '0': must be >= 1"},
      {"name: a\ntrain: [a]\noverlays: -2", "spec: overlays = '-2': must be >= 0"},
      {"name: a\ntrain: [a]\ncontact_friction: -1", "spec: contact_friction = '-1': must be >= 0"},
      {"name: a\ntrain: [a]\nintegrator: verlet", "spec: integrator = 'verlet': must be first_order or"},
      {"name: a\ntrain: [a]\nhtml: maybe", "spec: html = 'maybe': expected true or false"},
      {"name: a\ntrain: [a]\nbugdet: 4", "spec: bugdet = '4': unknown key"},
      {"[1, 2]", "spec: (top level)"},
      {"name: [", "spec: not valid YAML or JSON"},
  };
  for (const auto& [text, message] : cases) {
    try {
      (void)ParseLoopSpec(text, "spec", kBase);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const LoopSpecError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos)
          << "spec: " << text << "\nmessage: " << e.what() << "\nmissing: " << message;
    }
  }
}

}  // namespace
}  // namespace calib
