// External optimisers (external_optimizer.h): the protocol with a tiny
// fake program (fake_external_optimizer.py beside this file), the same
// candidates for any batch size and across save / restore, each way a
// program can misbehave as a named error, and the Optuna bridge
// (search/optuna_bridge.py) restored exactly from its saved state.

#include <cstdlib>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "calib/search/external_optimizer.h"
#include "calib/search/factory.h"
#include "harness.h"

namespace calib::search {
namespace {

const std::string kFake = std::string(CALIB_SOURCE_DIR) + "/tests/search/fake_external_optimizer.py";
const std::string kBridge = std::string(CALIB_SOURCE_DIR) + "/search/optuna_bridge.py";

nlohmann::json FakeSettings(const std::vector<std::string>& args, int batch = 3, int max_evals = 20) {
  std::vector<std::string> command{"/usr/bin/python3", kFake};
  command.insert(command.end(), args.begin(), args.end());
  return {{"command", command}, {"batch", batch}, {"max_evals", max_evals}, {"timeout_s", 5.0}};
}

CheckedOptimizer Make(const nlohmann::json& settings, uint64_t seed = 4) {
  return MakeOptimizer("external", settings, testing::Box(3, 0, 1), seed);
}

TEST(ExternalOptimizer, FollowsTheProtocolWhateverTheBatchAskedOfIt) {
  CheckedOptimizer one = Make(FakeSettings({"good"}));
  CheckedOptimizer eight = Make(FakeSettings({"good"}));
  const testing::History a = testing::RunOptimizer(one, testing::Sphere, 1);
  const testing::History b = testing::RunOptimizer(eight, testing::Sphere, 8, testing::TellOrder::kReversed);
  EXPECT_EQ(a.asked.size(), 20u) << "max_evals";
  EXPECT_TRUE(one.Done());
  EXPECT_FALSE(a.stuck);
  std::string why;
  EXPECT_TRUE(testing::SameCandidates(a.asked, b.asked, &why)) << why;
  CheckedOptimizer other_seed = Make(FakeSettings({"good"}), 5);
  const testing::History c = testing::RunOptimizer(other_seed, testing::Sphere, 4);
  EXPECT_FALSE(testing::SameCandidates(a.asked, c.asked, &why)) << "the seed reaches the program";
}

TEST(ExternalOptimizer, RestoredMidBatchItContinuesAsIfUninterrupted) {
  CheckedOptimizer whole = Make(FakeSettings({"good"}));
  const testing::History reference = testing::RunOptimizer(whole, testing::Sphere, 2);

  CheckedOptimizer first = Make(FakeSettings({"good"}));
  std::vector<Candidate> asked;
  for (int round = 0; round < 2; ++round) {  // a batch and a half
    for (const Candidate& c : first.Ask(2)) {
      asked.push_back(c);
      first.Tell(testing::Evaluate(testing::Sphere, c));
    }
  }
  const std::vector<Candidate> untold = first.Ask(1);  // asked, not told: what a kill leaves
  ASSERT_EQ(untold.size(), 1u);
  asked.push_back(untold.front());
  const nlohmann::json state = first.SaveState();

  CheckedOptimizer second = Make(FakeSettings({"good"}));
  second.RestoreState(state);
  ASSERT_EQ(second.Outstanding().size(), 1u);
  second.Tell(testing::Evaluate(testing::Sphere, second.Outstanding().front()));
  const testing::History rest = testing::RunOptimizer(second, testing::Sphere, 2);
  asked.insert(asked.end(), rest.asked.begin(), rest.asked.end());
  std::string why;
  EXPECT_TRUE(testing::SameCandidates(reference.asked, asked, &why)) << why;
}

// The external optimiser's own state says what it asked and was told
// (Optimizer::Counts, AwaitedIds), so a checkpoint whose wrapper part adds
// up but disagrees with it is refused at the restore, as for the others
// (CheckedOptimizer.RestoreRefusesAPlugInStateThatCountsOtherwise).
TEST(ExternalOptimizer, RestoreRefusesAStateThatCountsOtherwise) {
  const auto error_of = [](const nlohmann::json& state) -> std::string {
    CheckedOptimizer opt = Make(FakeSettings({"good"}));
    try {
      opt.RestoreState(state);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "(restored)";
  };
  CheckedOptimizer opt = Make(FakeSettings({"good"}));
  for (int i = 0; i < 3; ++i) opt.Tell(testing::Evaluate(testing::Sphere, opt.Ask(1).at(0)));
  const nlohmann::json between = opt.SaveState();  // a whole batch told, none pending
  ASSERT_EQ(opt.Ask(1).size(), 1u);
  const nlohmann::json mid = opt.SaveState();  // the next batch asked, one handed out
  EXPECT_EQ(error_of(between), "(restored)");
  EXPECT_EQ(error_of(mid), "(restored)");

  nlohmann::json more_told = between;  // two more told in the wrapper's part only
  more_told["next_id"] = 5;
  more_told["told"] = 5;
  std::string error = error_of(more_told);
  EXPECT_NE(error.find("the optimiser's own state counts 3 asked and 3 told, the checkpoint 5 "
                       "asked and 5 told"),
            std::string::npos)
      << error;

  nlohmann::json other_id = mid;  // the wrapper awaits id 5, the external optimiser id 3
  other_id["next_id"] = 6;
  other_id["told"] = 5;
  other_id["outstanding"][0]["id"] = 5;
  error = error_of(other_id);
  EXPECT_NE(error.find("outstanding ids [5] are not the ones the optimiser's own state waits for "
                       "([3])"),
            std::string::npos)
      << error;

  nlohmann::json shifted = mid;  // its pending batch's ids are not the last asked
  shifted["plugin"]["pending"][0]["id"] = 7;
  error = error_of(shifted);
  EXPECT_NE(error.find("pending id 7 is not the asked id 3"), std::string::npos) << error;
}

// The error a misbehaving fake gives while a run asks and tells.
ExternalOptimizerError ErrorOf(const std::vector<std::string>& args, double timeout_s = 5.0) {
  nlohmann::json settings = FakeSettings(args);
  settings["timeout_s"] = timeout_s;
  CheckedOptimizer opt = Make(settings);
  try {
    testing::RunOptimizer(opt, testing::Sphere, 3);
  } catch (const ExternalOptimizerError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for " << args.front();
  return ExternalOptimizerError(ExternalOptimizerError::Kind::kRefused, "");
}

TEST(ExternalOptimizer, AProgramThatExitsHangsPrintsGarbageOrLeavesTheBoxIsANamedError) {
  using Kind = ExternalOptimizerError::Kind;
  const ExternalOptimizerError exited = ErrorOf({"exit", "2"});
  EXPECT_EQ(exited.kind(), Kind::kExited);
  EXPECT_NE(std::string(exited.what()).find("exited with status 3 without replying to 'ask'"), std::string::npos)
      << exited.what();
  EXPECT_NE(std::string(exited.what()).find("fake_external_optimizer.py exit 2"), std::string::npos)
      << "names the command: " << exited.what();

  const ExternalOptimizerError hung = ErrorOf({"hang", "2"}, 0.5);
  EXPECT_EQ(hung.kind(), Kind::kTimedOut);
  EXPECT_NE(std::string(hung.what()).find("did not reply to 'ask' within 0.5 s (timeout_s)"), std::string::npos)
      << hung.what();

  const ExternalOptimizerError garbage = ErrorOf({"garbage", "1"});
  EXPECT_EQ(garbage.kind(), Kind::kGarbage);
  EXPECT_NE(std::string(garbage.what()).find("printed garbage: 'hello, this is not JSON'"), std::string::npos)
      << garbage.what();

  const ExternalOptimizerError outside = ErrorOf({"outside", "2"});
  EXPECT_EQ(outside.kind(), Kind::kOutOfBox);
  EXPECT_NE(std::string(outside.what()).find("proposed a point outside the box: x[2] = "), std::string::npos)
      << outside.what();

  CheckedOptimizer missing = MakeOptimizer("external", {{"command", {"/nonexistent/optimiser"}}},
                                           testing::Box(2, 0, 1), 1);
  try {
    (void)missing.Ask(1);
    ADD_FAILURE() << "a missing program ran";
  } catch (const ExternalOptimizerError& e) {
    EXPECT_EQ(e.kind(), Kind::kCannotStart);
    EXPECT_NE(std::string(e.what()).find("cannot run '/nonexistent/optimiser'"), std::string::npos) << e.what();
  }
}

TEST(ExternalOptimizer, BadSettingsAreNamed) {
  const auto message = [](const nlohmann::json& settings) {
    try {
      MakeOptimizer("external", settings, testing::Box(2, 0, 1), 1);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("(nothing thrown)");
  };
  EXPECT_NE(message(nlohmann::json::object()).find("command"), std::string::npos);
  EXPECT_NE(message({{"command", "optimiser"}}).find("non-empty list of strings"), std::string::npos);
  EXPECT_NE(message({{"command", {"x"}}, {"batch", 0}}).find("batch"), std::string::npos);
  EXPECT_NE(message({{"command", {"x"}}, {"timeout_s", -1}}).find("timeout_s"), std::string::npos);
  EXPECT_NE(message({{"command", {"x"}}, {"comand", 1}}).find("comand"), std::string::npos);
}

// Whether the bridge can run (found, not imported: importing Optuna takes a second or two).
bool HaveOptuna() {
  return std::system("/usr/bin/python3 -c \"import importlib.util as u, sys; "
                     "sys.exit(not (u.find_spec('optuna') and u.find_spec('cmaes')))\" 2>/dev/null") == 0;
}

// The sampler run to 8 evaluations and saved; then on to 16, and a new
// bridge restored from the saved state and run to 16 too: the same
// candidates. (Two bridges, not three: each starts Optuna, about 2 s.)
void ExpectBridgeResumesExactly(const std::string& sampler) {
  if (!HaveOptuna()) GTEST_SKIP() << "/usr/bin/python3 has no optuna (Debian: python3-optuna)";
  const nlohmann::json settings = {{"command", {"/usr/bin/python3", kBridge}},
                                   {"options", {{"sampler", sampler}}},
                                   {"batch", 4},
                                   {"max_evals", 16},
                                   {"timeout_s", 30.0}};
  CheckedOptimizer first = MakeOptimizer("external", settings, testing::Box(3, 0, 1), 9);
  (void)testing::RunOptimizer(first, testing::Rosenbrock, 4, testing::TellOrder::kInOrder, 8);
  const nlohmann::json state = first.SaveState();
  const testing::History reference = testing::RunOptimizer(first, testing::Rosenbrock, 4);
  ASSERT_EQ(reference.asked.size(), 8u) << "the second half";

  CheckedOptimizer second = MakeOptimizer("external", settings, testing::Box(3, 0, 1), 9);
  second.RestoreState(state);
  const testing::History rest = testing::RunOptimizer(second, testing::Rosenbrock, 4);
  std::string why;
  EXPECT_TRUE(testing::SameCandidates(reference.asked, rest.asked, &why)) << why;
  EXPECT_LT(reference.best, testing::Rosenbrock({0.5, 0.5, 0.5})) << "it minimises";
}

TEST(OptunaBridge, TpeResumesFromItsSavedStateExactly) { ExpectBridgeResumesExactly("tpe"); }

// A sphere whose simulation "fails" over a third of the box (x0 > 2/3):
// how many of TPE's last 24 of 48 proposals land there, failures told as
// `failed` (the bridge's option).
int LateProposalsWhereItFails(const std::string& failed) {
  const nlohmann::json settings = {{"command", {"/usr/bin/python3", kBridge}},
                                   {"options", {{"sampler", "tpe"}, {"failed", failed}}},
                                   {"batch", 4},
                                   {"max_evals", 48},
                                   {"timeout_s", 30.0}};
  CheckedOptimizer opt = MakeOptimizer("external", settings, testing::Box(3, 0, 1), 9);
  const auto f = [](const std::vector<double>& x) {
    if (x[0] > 2.0 / 3.0) return std::numeric_limits<double>::quiet_NaN();
    return testing::Sphere(x);
  };
  const testing::History h = testing::RunOptimizer(opt, f, 4);
  EXPECT_EQ(h.asked.size(), 48u);
  int there = 0;
  for (size_t i = 24; i < h.asked.size(); ++i) there += h.asked[i].x[0] > 2.0 / 3.0 ? 1 : 0;
  return there;
}

// Told the worst finished value (the default), TPE learns to leave the
// region where simulations fail, as calib's own optimisers rank a failure
// worse than any finished evaluation; told Optuna's FAIL, which its
// samplers leave out, it keeps proposing there.
TEST(OptunaBridge, FailuresToldAsTheWorstValueSteerTpeAwayFromWhereTheyHappen) {
  if (!HaveOptuna()) GTEST_SKIP() << "/usr/bin/python3 has no optuna (Debian: python3-optuna)";
  const int worst = LateProposalsWhereItFails("worst");
  const int fail = LateProposalsWhereItFails("fail");
  // Seeded: 4 and 24 with Debian 12's Optuna 3.1.
  EXPECT_LE(worst, 6) << "of 24";
  EXPECT_GE(fail, 12) << "of 24";
}

TEST(OptunaBridge, CmaEsResumesFromItsSavedStateExactly) { ExpectBridgeResumesExactly("cmaes"); }

}  // namespace
}  // namespace calib::search
