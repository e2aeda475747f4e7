// Properties every optimiser must have, checked for each one through the
// factory: bounds, failed evaluations, determinism, order of results,
// independence of max_count, exact save/restore (also mid-batch).
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "harness.h"

namespace calib::search {
namespace {

using testing::Box;
using testing::History;
using testing::RunOptimizer;
using testing::TellOrder;

struct Config {
  std::string name;
  nlohmann::json settings;
};

// Budget about 120 evaluations in 3 dimensions.
std::vector<Config> AllConfigs() {
  std::vector<Config> c = {
      {"grid", {{"resolution", 7}, {"max_evals", 120}}},
      {"random", {{"max_evals", 120}}},
      {"genetic", {{"population", 12}, {"generations", 10}}},
      {"genetic", {{"population", 12}, {"generations", 10}, {"crossover", "sbx"}, {"elitism", 3}}},
      {"annealing", {{"max_evals", 120}}},
      {"annealing", {{"max_evals", 120}, {"batch_size", 4}}},
      {"cmaes", {{"max_evals", 120}, {"population", 8}}},
  };
  for (const char* algo : {"BOBYQA", "COBYLA", "NELDERMEAD", "SBPLX", "DIRECT", "DIRECT_L",
                                  "CRS2_LM", "ISRES", "ESCH", "MLSL"}) {
    c.push_back({std::string("nlopt:") + algo, {{"maxeval", 120}}});
  }
  c.push_back({"nlopt:MLSL", {{"maxeval", 120}, {"local_algorithm", "SBPLX"}}});
  return c;
}

std::string ConfigName(const ::testing::TestParamInfo<Config>& info) {
  std::string s = std::to_string(info.index) + "_" + info.param.name;
  for (char& ch : s) {
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  }
  return s;
}

class EveryOptimizer : public ::testing::TestWithParam<Config> {
 protected:
  CheckedOptimizer Make(uint64_t seed = 2024) const {
    return MakeOptimizer(GetParam().name, GetParam().settings, Box(3, -5, 5), seed);
  }
};

TEST_P(EveryOptimizer, FinishesAndNeverLeavesTheBox) {
  // Linear objective: the optimum is the corner (-5, -5, -5), so optimisers
  // press against the bounds.
  const testing::Objective corner = [](const std::vector<double>& x) {
    return x[0] + x[1] + x[2];
  };
  for (const testing::Objective& f : {testing::Objective(testing::Sphere), corner,
                                      testing::Objective(testing::Rastrigin)}) {
    CheckedOptimizer opt = Make();
    const History h = RunOptimizer(opt, f, 5);
    EXPECT_FALSE(h.stuck) << GetParam().name << ": Ask returned nothing before Done";
    EXPECT_TRUE(opt.Done()) << GetParam().name << " not done after " << h.asked.size();
    EXPECT_FALSE(opt.StopReason().empty()) << GetParam().name;
    EXPECT_LE(h.asked.size(), 120u) << GetParam().name << " exceeded its budget";
    EXPECT_GE(h.asked.size(), 10u) << GetParam().name << " stopped very early: " << opt.StopReason();
    for (const Candidate& c : h.asked) {
      for (int i = 0; i < 3; ++i) {
        ASSERT_GE(c.x[i], -5.0) << GetParam().name << " id " << c.id << " coordinate " << i;
        ASSERT_LE(c.x[i], 5.0) << GetParam().name << " id " << c.id << " coordinate " << i;
      }
    }
    EXPECT_TRUE(opt.Ask(4).empty()) << GetParam().name << ": asks after Done";
  }
}

TEST_P(EveryOptimizer, CopesWithNanAndFailedEvaluations) {
  // NaN on a third of the box, +inf (a failed simulation) on another slab.
  const testing::Objective f = [](const std::vector<double>& x) {
    if (x[0] > 1.5) return std::nan("");
    if (x[1] < -3.0) return std::numeric_limits<double>::infinity();
    return testing::Sphere(x);
  };
  CheckedOptimizer opt = Make();
  const History h = RunOptimizer(opt, f, 4);
  EXPECT_FALSE(h.stuck) << GetParam().name;
  EXPECT_TRUE(opt.Done()) << GetParam().name;
  ASSERT_TRUE(opt.Best().has_value()) << GetParam().name << " found no finite value";
  EXPECT_TRUE(std::isfinite(opt.Best()->value)) << GetParam().name;
  EXPECT_LE(opt.Best()->x[0], 1.5) << GetParam().name << ": best lies in the NaN region";
  EXPECT_LT(opt.Best()->value, testing::Sphere({0, 0, 0})) << GetParam().name
      << " did not improve on the box centre despite the failures";

  // Everything fails: still finishes, and there is no best.
  CheckedOptimizer all_fail = Make();
  const History g = RunOptimizer(all_fail, [](const std::vector<double>&) { return std::nan(""); }, 4);
  EXPECT_FALSE(g.stuck) << GetParam().name;
  EXPECT_TRUE(all_fail.Done()) << GetParam().name;
  EXPECT_FALSE(all_fail.Best().has_value()) << GetParam().name;
  EXPECT_EQ(g.failed, static_cast<int64_t>(g.asked.size())) << GetParam().name;
}

TEST_P(EveryOptimizer, SameSeedSameHistory) {
  CheckedOptimizer a = Make(7), b = Make(7);
  const History ha = RunOptimizer(a, testing::Rosenbrock, 4);
  const History hb = RunOptimizer(b, testing::Rosenbrock, 4);
  std::string why;
  EXPECT_TRUE(testing::SameCandidates(ha.asked, hb.asked, &why)) << GetParam().name << ": " << why;
}

TEST_P(EveryOptimizer, OrderOfResultsDoesNotChangeTheHistory) {
  CheckedOptimizer in_order = Make(), reversed = Make(), shuffled = Make();
  const History h0 = RunOptimizer(in_order, testing::Rastrigin, 7, TellOrder::kInOrder);
  const History h1 = RunOptimizer(reversed, testing::Rastrigin, 7, TellOrder::kReversed);
  const History h2 = RunOptimizer(shuffled, testing::Rastrigin, 7, TellOrder::kOneByOneShuffled);
  std::string why;
  EXPECT_TRUE(testing::SameCandidates(h0.asked, h1.asked, &why)) << GetParam().name << ": " << why;
  EXPECT_TRUE(testing::SameCandidates(h0.asked, h2.asked, &why)) << GetParam().name << ": " << why;
  EXPECT_EQ(in_order.Best()->id, shuffled.Best()->id) << GetParam().name;
}

TEST_P(EveryOptimizer, MaxCountDoesNotChangeTheHistory) {
  CheckedOptimizer one = Make(), some = Make(), many = Make();
  const History h1 = RunOptimizer(one, testing::Sphere, 1);
  const History h5 = RunOptimizer(some, testing::Sphere, 5);
  const History h64 = RunOptimizer(many, testing::Sphere, 64);
  std::string why;
  EXPECT_TRUE(testing::SameCandidates(h1.asked, h5.asked, &why)) << GetParam().name << ": " << why;
  EXPECT_TRUE(testing::SameCandidates(h1.asked, h64.asked, &why)) << GetParam().name << ": " << why;
}

TEST_P(EveryOptimizer, SaveRestoreContinuesExactlyAlsoMidBatch) {
  CheckedOptimizer reference = Make();
  const History ref = RunOptimizer(reference, testing::Rastrigin, 3);

  for (int64_t save_after : {1, 2, 7, 20, 41, 90}) {
    CheckedOptimizer opt = Make();
    std::vector<Candidate> asked;
    bool saved = false;
    while (!opt.Done()) {
      std::vector<Candidate> batch = opt.Ask(3);
      ASSERT_FALSE(batch.empty()) << GetParam().name << " stuck";
      asked.insert(asked.end(), batch.begin(), batch.end());
      size_t told_before_save = batch.size();
      if (!saved && opt.asked_count() >= save_after) told_before_save = batch.size() / 2;
      for (size_t i = 0; i < told_before_save; ++i) {
        opt.Tell(testing::Evaluate(testing::Rastrigin, batch[i]));
      }
      if (told_before_save < batch.size() || (!saved && opt.asked_count() >= save_after)) {
        saved = true;
        const std::string text = opt.SaveState().dump();
        CheckedOptimizer fresh = Make();
        fresh.RestoreState(nlohmann::json::parse(text));
        const std::vector<Candidate> outstanding = fresh.Outstanding();
        ASSERT_EQ(outstanding.size(), batch.size() - told_before_save) << GetParam().name;
        std::string why;
        EXPECT_TRUE(testing::SameCandidates(
            outstanding,
            std::vector<Candidate>(batch.begin() + told_before_save, batch.end()), &why))
            << GetParam().name << ": " << why;
        EXPECT_EQ(fresh.SaveState(), nlohmann::json::parse(text))
            << GetParam().name << ": restored state saves differently";
        opt = std::move(fresh);
        for (const Candidate& c : outstanding) opt.Tell(testing::Evaluate(testing::Rastrigin, c));
      }
    }
    std::string why;
    EXPECT_TRUE(testing::SameCandidates(asked, ref.asked, &why))
        << GetParam().name << " saved after " << save_after << ": " << why;
    ASSERT_TRUE(opt.Best().has_value());
    EXPECT_EQ(opt.Best()->value, reference.Best()->value) << GetParam().name;
  }
}

INSTANTIATE_TEST_SUITE_P(Search, EveryOptimizer, ::testing::ValuesIn(AllConfigs()), ConfigName);

}  // namespace
}  // namespace calib::search
