// Bad names, settings and bounds are rejected with messages that name the
// optimiser, the key, the value and the rule.
#include <string>

#include <gtest/gtest.h>

#include "calib/search/factory.h"
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

TEST(Factory, BudgetsAreFilledInUnderEachOptimisersOwnKey) {
  EXPECT_EQ(BudgetSetting("cmaes"), "max_evals");
  EXPECT_EQ(BudgetSetting("grid"), "max_evals");
  EXPECT_EQ(BudgetSetting("nlopt:BOBYQA"), "maxeval");
  EXPECT_EQ(BudgetSetting("genetic"), "");  // population x generations
  EXPECT_EQ(WithBudget("cmaes", nullptr, 40), (nlohmann::json{{"max_evals", 40}}));
  EXPECT_EQ(WithBudget("nlopt:SBPLX", {{"maxeval", 7}}, 40), (nlohmann::json{{"maxeval", 7}}))
      << "a budget the settings give is kept";
  EXPECT_EQ(WithBudget("genetic", nullptr, 40), nlohmann::json::object());
  // Every filled-in setting is one the optimiser accepts.
  for (const std::string& name : OptimizerNames()) {
    EXPECT_NO_THROW(MakeOptimizer(name, WithBudget(name, nullptr, 40), testing::Box(2, 0, 1), 1))
        << name;
  }
}

TEST(Factory, SeedIndependentOptimizersProposeTheSameCandidatesForAnySeed) {
  int independent = 0;
  for (const std::string& name : OptimizerNames()) {
    const nlohmann::json settings = WithBudget(name, nullptr, 40);
    CheckedOptimizer a = MakeOptimizer(name, settings, testing::Box(3, 0, 1), 1);
    CheckedOptimizer b = MakeOptimizer(name, settings, testing::Box(3, 0, 1), 987654321);
    const testing::History ha = testing::RunOptimizer(a, testing::Rastrigin, 4, testing::TellOrder::kInOrder, 40);
    const testing::History hb = testing::RunOptimizer(b, testing::Rastrigin, 4, testing::TellOrder::kInOrder, 40);
    std::string why;
    const bool same = testing::SameCandidates(ha.asked, hb.asked, &why);
    if (SeedIndependent(name)) {
      ++independent;
      EXPECT_TRUE(same) << name << " is said to ignore its seed, but: " << why;
    } else {
      EXPECT_FALSE(same) << name << " gives the same candidates for seeds 1 and 987654321; "
                         << "SeedIndependent should list it";
    }
  }
  EXPECT_EQ(independent, 8) << "grid and seven NLopt algorithms";
}

TEST(Factory, StartSettingsStartWhereAskedWithTheStepAsked) {
  const std::vector<double> x0 = {0.2, 0.7, 0.4};
  const nlohmann::json cmaes = StartSettings("cmaes", 3, &x0, 0.25, 100);
  EXPECT_EQ(cmaes["x0"], nlohmann::json(x0));
  EXPECT_EQ(cmaes["initial_sigma"], 0.25);
  EXPECT_EQ(cmaes["population"], 8) << "at least 8 candidates a generation";
  EXPECT_EQ(StartSettings("cmaes", 3, nullptr, 0.3, 5)["population"], 5) << "never over the budget";
  EXPECT_FALSE(StartSettings("cmaes", 3, nullptr, 0.3, 100).contains("x0"));
  EXPECT_EQ(StartSettings("nlopt:BOBYQA", 3, &x0, 0.3, 100), (nlohmann::json{{"x0", x0}}));
  EXPECT_EQ(StartSettings("random", 3, &x0, 0.3, 100), nlohmann::json::object());
  for (const std::string& name : OptimizerNames()) {
    const nlohmann::json settings = WithBudget(name, StartSettings(name, 3, &x0, 0.3, 50), 50);
    CheckedOptimizer opt = MakeOptimizer(name, settings, testing::Box(3, 0, 1), 1);
    EXPECT_FALSE(opt.Ask(1).empty()) << name;
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
