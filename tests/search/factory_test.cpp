// Bad names, settings and bounds are rejected with messages that name the
// optimiser, the key, the value and the rule.
#include <string>

#include <gtest/gtest.h>

#include "harness.h"

namespace calib::search {
namespace {

// The message of the std::invalid_argument thrown by MakeOptimizer.
std::string MessageOf(const std::string& name, const nlohmann::json& settings,
                      const Bounds& bounds = testing::Box(2, 0, 1)) {
  try {
    MakeOptimizer(name, settings, bounds, 1);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(nothing thrown)";
}

void ExpectMentions(const std::string& message, std::initializer_list<std::string> parts) {
  for (const std::string& p : parts) {
    EXPECT_NE(message.find(p), std::string::npos) << "'" << p << "' missing from: " << message;
  }
}

TEST(Factory, EveryListedNameBuildsWithDefaults) {
  for (const std::string& name : OptimizerNames()) {
    EXPECT_NO_THROW({
      CheckedOptimizer opt = MakeOptimizer(name, nullptr, testing::Box(2, -1, 1), 3);
      EXPECT_EQ(opt.name(), name);
      EXPECT_FALSE(opt.Ask(1).empty()) << name;
    }) << name;
  }
}

TEST(Factory, UnknownNamesAreNamedWithTheChoices) {
  ExpectMentions(MessageOf("hillclimb", nullptr), {"'hillclimb'", "unknown", "cmaes", "nlopt:BOBYQA"});
  ExpectMentions(MessageOf("nlopt:LBFGS", nullptr), {"'nlopt:LBFGS'", "unknown", "SBPLX"});
}

TEST(Factory, BadSettingsNameOptimizerKeyValueAndRule) {
  ExpectMentions(MessageOf("genetic", {{"population", 1}}),
                 {"'genetic'", "'population'", "= 1", "population >= 2"});
  ExpectMentions(MessageOf("genetic", {{"population", "ten"}}),
                 {"'genetic'", "'population'", "\"ten\"", "is an integer"});
  ExpectMentions(MessageOf("genetic", {{"crossover", "uniform"}}),
                 {"'crossover'", "\"uniform\"", "blend, sbx"});
  ExpectMentions(MessageOf("genetic", {{"population", 4}, {"elitism", 4}}),
                 {"'elitism'", "= 4", "0 <= elitism <= 3"});
  ExpectMentions(MessageOf("genetic", {{"mutation_rate", 1.5}}),
                 {"'mutation_rate'", "1.5", "0 <= mutation_rate <= 1"});
  ExpectMentions(MessageOf("annealing", {{"cooling", 1.0}}),
                 {"'annealing'", "'cooling'", "0 < cooling < 1"});
  ExpectMentions(MessageOf("annealing", {{"max_evals", 10}, {"warmup", 10}}),
                 {"'warmup'", "= 10", "1 <= warmup <= 9"});
  ExpectMentions(MessageOf("cmaes", {{"initial_sigma", -0.1}}),
                 {"'cmaes'", "'initial_sigma'", "-0.1", "initial_sigma > 0"});
  ExpectMentions(MessageOf("cmaes", {{"x0", {0.5, 2.0}}}), {"'x0'", "0 <= x0[1] <= 1"});
  ExpectMentions(MessageOf("cmaes", {{"population", 10}, {"max_evals", 5}}),
                 {"'max_evals'", "= 5", "max_evals >= 10"});
  ExpectMentions(MessageOf("grid", {{"resolution", {3, 0}}}),
                 {"'grid'", "'resolution'", "[3,0]", "array of 2 integers >= 1"});
  ExpectMentions(MessageOf("random", {{"max_evals", 0}}), {"'random'", "'max_evals'", "max_evals >= 1"});
  ExpectMentions(MessageOf("nlopt:BOBYQA", {{"xtol_rel", -1}}),
                 {"'nlopt:BOBYQA'", "'xtol_rel'", "= -1", "xtol_rel >= 0"});
  ExpectMentions(MessageOf("nlopt:MLSL", {{"local_algorithm", "DIRECT"}}),
                 {"'nlopt:MLSL'", "'local_algorithm'", "\"DIRECT\"", "BOBYQA, COBYLA, NELDERMEAD, SBPLX"});
  ExpectMentions(MessageOf("random", nlohmann::json::array()), {"'random'", "JSON object"});
}

TEST(Factory, UnknownSettingKeysAreRejectedNotIgnored) {
  ExpectMentions(MessageOf("genetic", {{"popsize", 10}}),
                 {"'genetic'", "'popsize'", "unknown", "population"});
  // A setting that belongs to another algorithm is unknown here.
  ExpectMentions(MessageOf("nlopt:BOBYQA", {{"local_algorithm", "SBPLX"}}),
                 {"'nlopt:BOBYQA'", "'local_algorithm'", "unknown"});
}

TEST(Factory, BadBoundsAreNamed) {
  ExpectMentions(MessageOf("random", nullptr, {{0, 1}, {1, 1}}),
                 {"bounds", "parameter 1", "lower = 1", "upper = 1", "lower < upper"});
  ExpectMentions(MessageOf("random", nullptr, {{0}, {1, 2}}), {"bounds", "lower has 1", "upper has 2"});
  ExpectMentions(MessageOf("random", nullptr, {{}, {}}), {"bounds", "dimension >= 1"});
}

TEST(Factory, RestoringAnotherOptimizersStateIsRefusedByName) {
  CheckedOptimizer cmaes = MakeOptimizer("cmaes", nullptr, testing::Box(2, 0, 1), 1);
  CheckedOptimizer genetic = MakeOptimizer("genetic", nullptr, testing::Box(2, 0, 1), 1);
  try {
    genetic.RestoreState(cmaes.SaveState());
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    ExpectMentions(e.what(), {"'genetic'", "saved by 'cmaes'"});
  }
}

}  // namespace
}  // namespace calib::search
