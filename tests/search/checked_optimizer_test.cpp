// The wrapper catches plug-ins that break the ask contract and runners that
// tell what was never asked.
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "calib/search/factory.h"
#include "harness.h"

namespace calib::search {
namespace {

// A plug-in whose Ask output a test scripts.
class ScriptedPlugin final : public Optimizer {
 public:
  explicit ScriptedPlugin(std::function<std::vector<Candidate>(int)> ask) : ask_(std::move(ask)) {}
  std::string name() const override { return "scripted"; }
  std::vector<Candidate> Ask(int max_count) override { return ask_(max_count); }
  void Tell(std::span<const Evaluation> r) override {
    for (const auto& e : r) seen.push_back(e);
  }
  bool Done() const override { return false; }
  std::string StopReason() const override { return ""; }
  nlohmann::json SaveState() const override { return nlohmann::json::object(); }
  void RestoreState(const nlohmann::json&) override {}
  std::vector<Evaluation> seen;

 private:
  std::function<std::vector<Candidate>(int)> ask_;
};

std::string LogicErrorOf(std::function<std::vector<Candidate>(int)> ask, int max_count = 2) {
  CheckedOptimizer opt(std::make_unique<ScriptedPlugin>(std::move(ask)), testing::Box(2, 0, 1));
  try {
    opt.Ask(max_count);
  } catch (const std::logic_error& e) {
    return e.what();
  }
  return "(nothing thrown)";
}

TEST(CheckedOptimizer, CatchesPluginsThatBreakTheAskContract) {
  EXPECT_NE(LogicErrorOf([](int) { return std::vector<Candidate>{{0, {0.5, 1.5}}}; })
                .find("candidate 0 has x[1] = 1.5, outside [0, 1]"),
            std::string::npos);
  EXPECT_NE(LogicErrorOf([](int) { return std::vector<Candidate>{{0, {0.5, std::nan("")}}}; })
                .find("x[1] = nan"),
            std::string::npos);
  EXPECT_NE(LogicErrorOf([](int) { return std::vector<Candidate>{{0, {0.5}}}; })
                .find("candidate 0 has 1 coordinates, expected 2"),
            std::string::npos);
  EXPECT_NE(LogicErrorOf([](int) { return std::vector<Candidate>{{3, {0.5, 0.5}}}; })
                .find("candidate id 3 where 0 was expected"),
            std::string::npos);
  EXPECT_NE(LogicErrorOf([](int) {
              return std::vector<Candidate>{{0, {0, 0}}, {1, {0, 0}}, {2, {0, 0}}};
            }).find("returned 3 candidates for max_count = 2"),
            std::string::npos);
  EXPECT_NE(LogicErrorOf([](int) { return std::vector<Candidate>{}; }, 0), "(nothing thrown)")
      << "max_count = 0 is refused";
}

TEST(CheckedOptimizer, RefusesUnaskedDuplicateAndAlteredResultsAndKeepsItsState) {
  int64_t next = 0;
  auto plugin = std::make_unique<ScriptedPlugin>([&](int k) {
    std::vector<Candidate> out;
    for (int i = 0; i < k; ++i) out.push_back({next++, {0.25, 0.75}});
    return out;
  });
  ScriptedPlugin* raw = plugin.get();
  CheckedOptimizer opt(std::move(plugin), testing::Box(2, 0, 1));
  const std::vector<Candidate> c = opt.Ask(3);
  const auto expect_refused = [&](std::vector<Evaluation> r, const std::string& part) {
    try {
      opt.Tell(r);
      ADD_FAILURE() << "expected std::invalid_argument containing " << part;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  expect_refused({{7, {0.25, 0.75}, 1.0, false}}, "id 7, which is not an asked id");
  expect_refused({{1, {0.25, 0.75}, 1.0, false}, {1, {0.25, 0.75}, 2.0, false}}, "id 1 told twice");
  expect_refused({{0, {0.25, 0.5}, 1.0, false}}, "differs from the asked x");
  EXPECT_TRUE(raw->seen.empty()) << "a refused Tell must not reach the plug-in";
  EXPECT_EQ(opt.Outstanding().size(), 3u);

  // NaN and infinities reach the plug-in as failed; results arrive sorted.
  opt.Tell(std::vector<Evaluation>{{2, c[2].x, std::nan(""), false},
                                   {0, c[0].x, 4.0, false},
                                   {1, c[1].x, -std::numeric_limits<double>::infinity(), false}});
  ASSERT_EQ(raw->seen.size(), 3u);
  EXPECT_EQ(raw->seen[0].id, 0);
  EXPECT_FALSE(raw->seen[0].failed);
  EXPECT_TRUE(raw->seen[1].failed);
  EXPECT_TRUE(raw->seen[2].failed);
  EXPECT_EQ(opt.failed_count(), 2);
  ASSERT_TRUE(opt.Best().has_value());
  EXPECT_EQ(opt.Best()->id, 0);
  expect_refused({{0, c[0].x, 1.0, false}}, "id 0, which is already told");
}

TEST(CheckedOptimizer, BestTiesGoToTheLowestIdWhateverTheArrivalOrder) {
  int64_t next = 0;
  CheckedOptimizer opt(std::make_unique<ScriptedPlugin>([&](int k) {
                         std::vector<Candidate> out;
                         for (int i = 0; i < k; ++i) out.push_back({next++, {0.5, 0.5}});
                         return out;
                       }),
                       testing::Box(2, 0, 1));
  const auto c = opt.Ask(3);
  opt.Tell(Evaluation{2, c[2].x, 1.0, false});
  opt.Tell(Evaluation{1, c[1].x, 1.0, false});
  EXPECT_EQ(opt.Best()->id, 1);
}

// What RestoreState of `state` into `fresh` throws as std::invalid_argument,
// or "(restored)".
std::string RestoreError(CheckedOptimizer fresh, const nlohmann::json& state) {
  try {
    fresh.RestoreState(state);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(restored)";
}

// Found by fuzz/fuzz_checkpoint: an NLopt checkpoint whose outstanding id
// was one already told (3 -> 1) was restored, and the resumed run's first
// Tell threw std::logic_error (a plug-in bug) instead of the restore
// refusing the state with std::invalid_argument.
TEST(CheckedOptimizer, RestoreRefusesAStateWhosePartsDisagree) {
  const auto saved = [] {
    CheckedOptimizer opt = MakeOptimizer("nlopt:SBPLX", nlohmann::json{{"maxeval", 48}},
                                         testing::Box(2, 0, 1), 7);
    for (int i = 0; i < 3; ++i) {
      const std::vector<Candidate> c = opt.Ask(1);
      opt.Tell(testing::Evaluate(testing::Sphere, c.at(0)));
    }
    (void)opt.Ask(1);
    return opt.SaveState();
  }();
  ASSERT_EQ(saved.at("outstanding").at(0).at("id"), 3);
  const auto error_of = [](const nlohmann::json& state) {
    return RestoreError(
        MakeOptimizer("nlopt:SBPLX", nlohmann::json{{"maxeval", 48}}, testing::Box(2, 0, 1), 7),
        state);
  };
  EXPECT_EQ(error_of(saved), "(restored)");
  nlohmann::json told_id = saved;
  told_id["outstanding"][0]["id"] = 1;
  EXPECT_NE(error_of(told_id).find(
                "outstanding ids [1] are not the ones the optimiser's own state waits for ([3])"),
            std::string::npos)
      << error_of(told_id);
  nlohmann::json none = saved;  // NLopt waits for id 3, the wrapper for nothing
  none["outstanding"] = nlohmann::json::array();
  none["next_id"] = 3;
  EXPECT_NE(error_of(none).find("outstanding ids [] are not the ones"), std::string::npos)
      << error_of(none);
  nlohmann::json counts = saved;
  counts["told"] = 2;
  EXPECT_NE(error_of(counts).find("do not add up"), std::string::npos) << error_of(counts);
  nlohmann::json outside = saved;
  outside["outstanding"][0]["x"][1] = 1.5;
  EXPECT_NE(error_of(outside).find("coordinate 1 = 1.5 is outside the bounds"), std::string::npos)
      << error_of(outside);
}

// Every optimiser's own state says how many candidates it handed out and how
// many results it was told; a checkpoint whose wrapper part adds up but
// disagrees with it is refused at the restore (fuzz_checkpoint found a grid
// state counting 16 told of 14 asked that was taken, and the resumed search
// never ended).
TEST(CheckedOptimizer, RestoreRefusesAPlugInStateThatCountsOtherwise) {
  const std::vector<std::pair<std::string, nlohmann::json>> optimizers = {
      {"grid", nlohmann::json::object({{"resolution", 4}})},
      {"random", nlohmann::json::object({{"max_evals", 40}})},
      {"genetic", nlohmann::json::object({{"population", 6}, {"generations", 6}})},
      {"annealing", nlohmann::json::object({{"max_evals", 40}})},
      {"cmaes", nlohmann::json::object({{"max_evals", 40}})},
      {"nlopt:SBPLX", nlohmann::json::object({{"maxeval", 40}})}};
  for (const auto& [name, settings] : optimizers) {
    SCOPED_TRACE(name);
    const auto make = [&] { return MakeOptimizer(name, settings, testing::Box(2, 0, 1), 3); };
    // Some results told, one candidate still outstanding.
    CheckedOptimizer opt = make();
    for (int i = 0; i < 3; ++i) {
      const std::vector<Candidate> c = opt.Ask(1);
      ASSERT_EQ(c.size(), 1u);
      opt.Tell(testing::Evaluate(testing::Sphere, c[0]));
    }
    ASSERT_EQ(opt.Ask(1).size(), 1u);
    const nlohmann::json saved = opt.SaveState();
    const auto error_of = [&](const nlohmann::json& state) { return RestoreError(make(), state); };
    EXPECT_EQ(error_of(saved), "(restored)");
    // Two more told in the wrapper's part (which still adds up), none in
    // the optimiser's own.
    nlohmann::json more_told = saved;
    more_told["told"] = more_told["told"].get<int64_t>() + 2;
    more_told["next_id"] = more_told["next_id"].get<int64_t>() + 2;
    for (auto& o : more_told["outstanding"]) o["id"] = o["id"].get<int64_t>() + 2;
    const std::string error = error_of(more_told);
    EXPECT_TRUE(error.find("the optimiser's own state counts 4 asked and 3 told, the checkpoint "
                           "6 asked and 5 told") != std::string::npos ||
                error.find("are not the ones the optimiser's own state waits for") !=
                    std::string::npos)
        << error;
  }
}

// A point of the optimiser's own state with another number of coordinates
// than the search has is refused at the restore, naming what is wrong,
// before anything reads past it (fuzz_checkpoint found NLopt's replay
// reading past a two-coordinate point of a three-dimensional search).
TEST(CheckedOptimizer, RestoreRefusesAPlugInPointOfAnotherDimension) {
  struct Case {
    std::string optimizer;
    nlohmann::json settings;
    std::vector<std::string> path;  // to the point shortened to one coordinate
    std::string error;
  };
  const std::vector<Case> cases = {
      {"genetic", {{"population", 6}, {"generations", 6}}, {"batch", "x", "0"},
       "a point of the batch has 1 values; the search has 2 dimensions"},
      {"annealing", {{"max_evals", 40}}, {"step"}, "step has 1 values; the search has 2 dimensions"},
      {"cmaes", {{"max_evals", 40}}, {"batch", "x", "1"},
       "a point of the batch has 1 values; the search has 2 dimensions"},
      {"nlopt:SBPLX", {{"maxeval", 40}}, {"evaluations", "2", "raw_x"},
       "evaluation 2 has a point of 1 coordinates; the search has 2"}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.optimizer);
    const auto make = [&] { return MakeOptimizer(c.optimizer, c.settings, testing::Box(2, 0, 1), 3); };
    CheckedOptimizer opt = make();
    for (int i = 0; i < 3; ++i) {
      const std::vector<Candidate> candidates = opt.Ask(1);
      ASSERT_EQ(candidates.size(), 1u);
      opt.Tell(testing::Evaluate(testing::Sphere, candidates[0]));
    }
    nlohmann::json state = opt.SaveState();
    nlohmann::json* point = &state["plugin"];
    for (const std::string& key : c.path) {
      point = point->is_array() ? &(*point)[std::stoul(key)] : &(*point)[key];
    }
    ASSERT_TRUE(point->is_array() && point->size() == 2) << point->dump();
    point->erase(1);
    const std::string error = RestoreError(make(), state);
    EXPECT_NE(error.find(c.error), std::string::npos) << error;
  }
}

// A fresh optimiser `name` over the unit square, and the state of one that
// was told one result.
struct StateAfterOneResult {
  std::function<CheckedOptimizer()> make;
  nlohmann::json state;
};
StateAfterOneResult SaveAfterOneResult(const std::string& name, const nlohmann::json& settings) {
  StateAfterOneResult saved;
  saved.make = [=] { return MakeOptimizer(name, settings, testing::Box(2, 0, 1), 3); };
  CheckedOptimizer opt = saved.make();
  opt.Tell(testing::Evaluate(testing::Sphere, opt.Ask(1).at(0)));
  saved.state = opt.SaveState();
  return saved;
}

// `state` is refused with a message holding `fragment`.
void ExpectRefused(const StateAfterOneResult& saved, const nlohmann::json& state,
                   const std::string& fragment) {
  const std::string error = RestoreError(saved.make(), state);
  EXPECT_NE(error.find(fragment), std::string::npos) << error;
}

// An integer of a state written as a number that is not one (1.2e20 is read
// as a double, which converts to an integer with undefined behaviour) is
// refused naming the field (fuzz_checkpoint found it in the random
// search's generator state).
TEST(CheckedOptimizer, RestoreRefusesANonIntegerWhereItsStateHasAnInteger) {
  const StateAfterOneResult saved = SaveAfterOneResult("random", {{"max_evals", 20}});
  nlohmann::json huge = saved.state;
  huge["plugin"]["rng"]["xoshiro256"][0] = 1.2e20;
  ExpectRefused(saved, huge, "xoshiro256 = 1.2e+20: not an integer");
  nlohmann::json fraction = saved.state;
  fraction["next_id"] = 1.5;
  ExpectRefused(saved, fraction, "next_id = 1.5: not an integer");
  nlohmann::json negative = saved.state;
  negative["plugin"]["rng"]["spare_bits"] = -1;
  ExpectRefused(saved, negative, "spare_bits = -1: not an integer in [0, ");
}

// A point of an optimiser's state outside the search's box is refused at
// the restore, asked or not (fuzz_checkpoint found a genetic batch point
// not yet handed out at 4.1 in [0, 1]: handed out later, it broke the ask
// contract).
TEST(CheckedOptimizer, RestoreRefusesAPlugInPointOutsideTheBox) {
  const StateAfterOneResult saved =
      SaveAfterOneResult("genetic", {{"population", 6}, {"generations", 6}});
  nlohmann::json unasked = saved.state;
  unasked["plugin"]["batch"]["x"][5][1] = 4.1;
  ExpectRefused(saved, unasked, "point 5 of the batch has x[1] = 4.1, outside [0, 1]");
  nlohmann::json not_a_number = saved.state;
  not_a_number["plugin"]["batch"]["x"][4][0] = "nan";
  ExpectRefused(saved, not_a_number, "point 4 of the batch has x[0] = nan, outside [0, 1]");
}

// The cmaes state's vectors and matrices must be those of its dimension.
TEST(CheckedOptimizer, RestoreRefusesACmaesStateOfAnotherShape) {
  const StateAfterOneResult saved = SaveAfterOneResult("cmaes", {{"max_evals", 40}});
  nlohmann::json wrong_c = saved.state;
  wrong_c["plugin"]["C"] = {{"rows", 3}, {"cols", 3}, {"data", std::vector<double>(9, 0.0)}};
  ExpectRefused(saved, wrong_c, "not those of 2 dimensions");
  nlohmann::json negative = saved.state;
  negative["plugin"]["mean"] = {{"rows", -2}, {"cols", -1}, {"data", {0.5, 0.5}}};
  ExpectRefused(saved, negative, "a -2 x -1 matrix with 2 values");
}

// The state fuzz_checkpoint found: the grid's own part counts more told
// than asked.
TEST(CheckedOptimizer, AGridStateWithMoreToldThanAskedIsRefused) {
  const auto make = [] {
    return MakeOptimizer("grid", {{"resolution", 4}}, testing::Box(2, 0, 1), 0);
  };
  CheckedOptimizer opt = make();
  for (int i = 0; i < 2; ++i) opt.Tell(testing::Evaluate(testing::Sphere, opt.Ask(1).at(0)));
  nlohmann::json state = opt.SaveState();
  state["plugin"]["told"] = 5;
  const std::string error = RestoreError(make(), state);
  EXPECT_NE(error.find("told 5 and asked 2 are not 0 <= told <= asked"), std::string::npos)
      << error;
}

}  // namespace
}  // namespace calib::search
