// The tracer's confidences as rates: counting first-round hypotheses by
// confidence bin, the bins' edges, confidence_rates.json's round trip and
// its errors, the table compiled in, the rate stated beside each
// hypothesis, and the rate the loop ranks hypotheses by.

#include "calib/discovery/confidence_rates.h"
#include "calib/discovery/hypotheses.h"

#include "support/process_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <stdexcept>

namespace calib {
namespace {

using nlohmann::json;

ObjectOutcome Traced(const std::string& loop_effect, std::vector<HypothesisConfidence> first_round) {
  ObjectOutcome o;
  o.loop_effect = loop_effect;
  o.effect = loop_effect;
  o.first_round = std::move(first_round);
  return o;
}

void ExpectCounts(const ConfidenceBin& bin, int64_t right, int64_t hypotheses) {
  EXPECT_EQ(bin.right.successes, right) << bin.from;
  EXPECT_EQ(bin.right.trials, hypotheses) << bin.from;
  const Proportion expected = WilsonInterval(right, hypotheses);
  EXPECT_DOUBLE_EQ(bin.right.lower, expected.lower) << bin.from;
  EXPECT_DOUBLE_EQ(bin.right.upper, expected.upper) << bin.from;
}

TEST(ConfidenceRates, CountsTheFirstRoundHypothesesThatNameTheObjectsEffect) {
  std::vector<ObjectOutcome> outcomes;
  outcomes.push_back(Traced("plasticity", {{"plasticity", 0.8}, {"table_friction", 0.3},
                                           {"viscoelastic", 0.0}}));
  // No effect: every hypothesis is wrong.
  outcomes.push_back(Traced("", {{"plasticity", 0.6}, {"table_friction", 0.02}}));
  outcomes.push_back(Traced("uneven_stiffness", {{"uneven_stiffness", 0.55}, {"plasticity", 1.0}}));
  // A loop that failed counts nowhere.
  ObjectOutcome failed = Traced("plasticity", {{"plasticity", 0.9}, {"inertia", 0.1}});
  failed.status = "error";
  outcomes.push_back(failed);

  const ConfidenceRates rates = CountConfidenceRates(outcomes);
  ASSERT_EQ(rates.bins.size(), ConfidenceBinEdges().size() - 1);
  ExpectCounts(rates.bins[0], 0, 2);  // 0.0, 0.02
  ExpectCounts(rates.bins[1], 0, 0);
  EXPECT_TRUE(std::isnan(rates.bins[1].right.rate));
  ExpectCounts(rates.bins[2], 0, 1);  // 0.3
  ExpectCounts(rates.bins[3], 1, 2);  // 0.6 wrong, 0.55 right
  ExpectCounts(rates.bins[4], 1, 2);  // 0.8 right, 1.0 wrong
  EXPECT_DOUBLE_EQ(rates.bins[4].right.rate, 0.5);

  // Per effect, by name.
  ASSERT_EQ(rates.effects.size(), 4u);
  EXPECT_EQ(rates.effects[0].effect, "plasticity");
  EXPECT_EQ(rates.effects[1].effect, "table_friction");
  EXPECT_EQ(rates.effects[2].effect, "uneven_stiffness");
  EXPECT_EQ(rates.effects[3].effect, "viscoelastic");
  const std::vector<ConfidenceBin>& plasticity = rates.effects[0].bins;
  ExpectCounts(plasticity[3], 0, 1);  // 0.6 on the object without an effect
  ExpectCounts(plasticity[4], 1, 2);  // 0.8 right, 1.0 on the uneven object
  ExpectCounts(plasticity[0], 0, 0);
  ExpectCounts(rates.effects[2].bins[3], 1, 1);
  EXPECT_EQ(rates.Find("plasticity", 0.9), &plasticity[4]);
  EXPECT_EQ(rates.Find("inertia", 0.9), nullptr);  // only the failed loop traced it
}

TEST(ConfidenceRates, AnEdgeOpensItsBinAndTheLastBinHoldsOne) {
  const ConfidenceRates rates = CountConfidenceRates({});
  const std::vector<double>& edges = ConfidenceBinEdges();
  ASSERT_EQ(edges.front(), 0.0);
  ASSERT_EQ(edges.back(), 1.0);
  for (size_t i = 0; i + 1 < edges.size(); ++i) {
    EXPECT_EQ(rates.Find(edges[i])->from, edges[i]);
    EXPECT_EQ(rates.Find(std::nextafter(edges[i + 1], 0.0))->from, edges[i]);
  }
  EXPECT_EQ(rates.Find(1.0), &rates.bins.back());
  EXPECT_EQ(rates.Find(1.5), &rates.bins.back());  // clamped
  EXPECT_EQ(rates.Find(-0.1), &rates.bins.front());
  EXPECT_EQ(rates.Find(NAN), nullptr);
  EXPECT_EQ(ConfidenceRates{}.Find(0.5), nullptr);
}

ConfidenceRates SomeRates() {
  ConfidenceRates rates =
      CountConfidenceRates({Traced("plasticity", {{"plasticity", 0.8}, {"viscoelastic", 0.1}}),
                            Traced("", {{"plasticity", 0.7}})});
  rates.family = "tune";
  rates.family_spec = "examples/families/tune.yaml";
  rates.family_seed = 101;
  rates.command = "calib loop-benchmark out/families/tune --out out/rates --min-confidence 1";
  return rates;
}

TEST(ConfidenceRates, JsonRoundTripsWithTheFamilyAndTheCommand) {
  const ConfidenceRates rates = SomeRates();
  const ConfidenceRates back = ConfidenceRatesFromJson(ToJson(rates), "confidence_rates.json");
  EXPECT_EQ(back.family, "tune");
  EXPECT_EQ(back.family_spec, rates.family_spec);
  EXPECT_EQ(back.family_seed, 101u);
  EXPECT_EQ(back.command, rates.command);
  ASSERT_EQ(back.bins.size(), rates.bins.size());
  for (size_t i = 0; i < rates.bins.size(); ++i) {
    EXPECT_EQ(back.bins[i].from, rates.bins[i].from);
    EXPECT_EQ(back.bins[i].to, rates.bins[i].to);
    ExpectCounts(back.bins[i], rates.bins[i].right.successes, rates.bins[i].right.trials);
  }
  ASSERT_EQ(back.effects.size(), 2u);
  EXPECT_EQ(back.effects[0].effect, "plasticity");
  ExpectCounts(back.effects[0].bins[3], 0, 1);
  ExpectCounts(back.effects[0].bins[4], 1, 1);
  EXPECT_EQ(ToJson(back), ToJson(rates));
}

void ExpectRejected(const json& doc, const std::string& culprit) {
  try {
    ConfidenceRatesFromJson(doc, "rates.json");
    ADD_FAILURE() << "accepted; expected an error naming " << culprit;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rates.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(culprit), std::string::npos) << e.what();
  }
}

TEST(ConfidenceRates, AMalformedTableNamesTheKey) {
  const json good = ToJson(SomeRates());
  json doc = good;
  doc["format"] = "calib-confidence-rates/0";
  ExpectRejected(doc, "format");
  doc = good;
  doc["bins"][1]["from"] = 0.1;  // a gap after the first bin
  ExpectRejected(doc, "bins[1].from");
  doc = good;
  doc["bins"][0]["right"] = 3;
  doc["bins"][0]["hypotheses"] = 2;
  ExpectRejected(doc, "bins[0].right");
  doc = good;
  doc["bins"].erase(doc["bins"].size() - 1);  // stops short of 1
  ExpectRejected(doc, "bins: the last bin ends at 0.75");
  doc = good;
  doc["bins"][2]["hypotheses"] = -4;
  ExpectRejected(doc, "bins[2].hypotheses");
  doc = good;
  doc.erase("command");
  ExpectRejected(doc, "command: missing");
  doc = good;
  doc["effects"][1]["bins"][2]["to"] = 0.2;  // ends before it starts
  ExpectRejected(doc, "effects[1].bins[2].to");
  doc = good;
  doc["effects"][0].erase("effect");
  ExpectRejected(doc, "effects[0].effect: missing");
}

TEST(ConfidenceRates, TheCompiledInTableIsTheTuningFamilysFile) {
  const ConfidenceRates& rates = TuningFamilyConfidenceRates();
  const std::string file = std::string(CALIB_SOURCE_DIR) + "/discovery/confidence_rates.json";
  EXPECT_EQ(ToJson(rates), ToJson(ConfidenceRatesFromJson(json::parse(testing::ReadText(file)), file)));
  EXPECT_EQ(rates.family, "tune");
  ASSERT_EQ(rates.bins.size(), ConfidenceBinEdges().size() - 1);
  int64_t hypotheses = 0;
  for (const ConfidenceBin& bin : rates.bins) hypotheses += bin.right.trials;
  EXPECT_GT(hypotheses, 0);
}

TEST(ConfidenceRates, EachHypothesisStatesTheRateOfItsConfidence) {
  Hypothesis h;
  h.effect = "plasticity";
  h.confidence = 0.6;
  h.summary = "the dent stays after the release";
  const ConfidenceRates& rates = TuningFamilyConfidenceRates();
  const std::string text = RateText(rates, "plasticity", 0.6);
  ASSERT_FALSE(text.empty());
  EXPECT_NE(HypothesesReport({h}).find(text), std::string::npos) << HypothesesReport({h});
  const json doc = ToJson(h);
  ASSERT_TRUE(doc.contains("tuning_family_rate"));
  const json& rate = doc["tuning_family_rate"];
  EXPECT_LE(rate["from"].get<double>(), 0.6);
  EXPECT_GT(rate["to"].get<double>(), 0.6);
  EXPECT_EQ(rate["all"]["hypotheses"].get<int64_t>(), rates.Find(0.6)->right.trials);
  ASSERT_NE(rates.Find("plasticity", 0.6), nullptr);  // traced on every tuning object
  EXPECT_EQ(rate["effect"]["right"].get<int64_t>(), rates.Find("plasticity", 0.6)->right.successes);
  EXPECT_EQ(HypothesisFromJson(doc).confidence, 0.6);  // derived, not read back
}

TEST(ConfidenceRates, RateTextGivesCountsIntervalAndBin) {
  ConfidenceBin bin{0.5, 0.75, WilsonInterval(5, 9)};
  EXPECT_EQ(RateText(bin), fmt::format("right on 5 of 9 ({:.2f} [{:.2f}, {:.2f}]) tuning-family "
                                       "hypotheses at confidence 0.50-0.75",
                                       5.0 / 9.0, bin.right.lower, bin.right.upper));
  bin.right = WilsonInterval(0, 0);
  EXPECT_EQ(RateText(bin), "no tuning-family hypothesis at confidence 0.50-0.75");

  const ConfidenceRates rates = SomeRates();  // plasticity right at 0.8, wrong at 0.7
  const Proportion one = WilsonInterval(1, 1);
  EXPECT_EQ(RateText(rates, "plasticity", 0.9),
            fmt::format("right on 1 of 1 (1.00 [{:.2f}, 1.00]) plasticity hypotheses and on 1 of 1 "
                        "(1.00 [{:.2f}, 1.00]) of every effect's at confidence 0.75-1.00 on the "
                        "tuning family",
                        one.lower, one.lower));
  EXPECT_EQ(RateText(rates, "inertia", 0.6),
            fmt::format("no inertia hypothesis and on 0 of 1 (0.00 [0.00, {:.2f}]) of every "
                        "effect's at confidence 0.50-0.75 on the tuning family",
                        WilsonInterval(0, 1).upper));
  EXPECT_EQ(RateText(ConfidenceRates{}, "plasticity", 0.9), "");
}

// A table where, at 0.5-0.75, every effect's hypotheses were right on 4 of 10:
// plasticity's on 3 of 3, push_relaxation's on 0 of 5, table_friction's on 1
// of 2; above 0.75 push_relaxation's on 0 of 2; below 0.05 none of 4.
ConfidenceRates RankingTable() {
  std::vector<ObjectOutcome> outcomes;
  for (int i = 0; i < 3; ++i) outcomes.push_back(Traced("plasticity", {{"plasticity", 0.6}}));
  for (int i = 0; i < 5; ++i) outcomes.push_back(Traced("", {{"push_relaxation", 0.6}}));
  outcomes.push_back(Traced("table_friction", {{"table_friction", 0.6}, {"push_relaxation", 0.9}}));
  outcomes.push_back(Traced("viscoelastic", {{"table_friction", 0.55}, {"push_relaxation", 0.8}}));
  for (int i = 0; i < 4; ++i) outcomes.push_back(Traced("", {{"inertia", 0.01}}));
  return CountConfidenceRates(outcomes);
}

TEST(ConfidenceRates, RankingRateShrinksTheEffectsCountTowardTheBins) {
  const ConfidenceRates rates = RankingTable();
  ASSERT_EQ(rates.Find(0.6)->right.successes, 4);
  ASSERT_EQ(rates.Find(0.6)->right.trials, 10);
  const double p = 0.4, m = kRankingPriorHypotheses;
  EXPECT_DOUBLE_EQ(RankingRate(rates, "plasticity", 0.6), (3 + m * p) / (3 + m));
  EXPECT_DOUBLE_EQ(RankingRate(rates, "push_relaxation", 0.6), (0 + m * p) / (5 + m));
  EXPECT_DOUBLE_EQ(RankingRate(rates, "table_friction", 0.7), (1 + m * p) / (2 + m));
  // An effect the bin never saw takes the bin's rate; no shrinkage, its own.
  EXPECT_DOUBLE_EQ(RankingRate(rates, "uneven_stiffness", 0.6), p);
  EXPECT_DOUBLE_EQ(RankingRate(rates, "plasticity", 0.6, 0.0), 1.0);
  EXPECT_NEAR(RankingRate(rates, "push_relaxation", 0.6, 1e12), p, 1e-9);
  // Above 0.75: right on 0 of 2, so every effect's rate there is 0.
  EXPECT_DOUBLE_EQ(RankingRate(rates, "push_relaxation", 0.9), 0.0);
  // No hypothesis in the bin, or no table: no rate.
  EXPECT_TRUE(std::isnan(RankingRate(rates, "plasticity", 0.3)));
  EXPECT_TRUE(std::isnan(RankingRate(ConfidenceRates{}, "plasticity", 0.6)));
}

Hypothesis HypothesisOf(const std::string& effect, double confidence) {
  Hypothesis h;
  h.effect = effect;
  h.confidence = confidence;
  h.summary = effect;
  return h;
}

std::vector<std::string> Effects(const std::vector<Hypothesis>& hypotheses) {
  std::vector<std::string> out;
  for (const Hypothesis& h : hypotheses) out.push_back(h.effect);
  return out;
}

TEST(ConfidenceRates, HypothesesAreRankedByTheirRateThenByConfidence) {
  const ConfidenceRates rates = RankingTable();
  // By confidence: push_relaxation, table_friction, plasticity, viscoelastic
  // (0.3: a bin without hypotheses), uneven_stiffness (a bin without rate
  // either), inertia.
  const std::vector<Hypothesis> hypotheses = {
      HypothesisOf("push_relaxation", 0.9), HypothesisOf("table_friction", 0.7), HypothesisOf("plasticity", 0.55),
      HypothesisOf("viscoelastic", 0.3),    HypothesisOf("uneven_stiffness", 0.26), HypothesisOf("inertia", 0.02)};
  // plasticity 0.63, table_friction 0.43, push_relaxation 0 (0 of 2 above
  // 0.75), inertia 0 (0 of 4 below 0.05) after it by confidence; then the two
  // without a rate, by confidence.
  EXPECT_EQ(Effects(RankedByRate(hypotheses, rates)),
            (std::vector<std::string>{"plasticity", "table_friction", "push_relaxation", "inertia",
                                      "viscoelastic", "uneven_stiffness"}));
  // Without a table: by confidence, ties in the catalogue's order.
  std::vector<Hypothesis> tied = hypotheses;
  tied[1].confidence = 0.9;  // table_friction comes before push_relaxation in TracedEffects()
  EXPECT_EQ(Effects(RankedByRate(tied, ConfidenceRates{})),
            (std::vector<std::string>{"table_friction", "push_relaxation", "plasticity",
                                      "viscoelastic", "uneven_stiffness", "inertia"}));
}

TEST(ConfidenceRates, EachHypothesisStatesItsRateEstimate) {
  const Hypothesis h = HypothesisOf("plasticity", 0.6);
  const double rate = RankingRate(TuningFamilyConfidenceRates(), "plasticity", 0.6);
  ASSERT_FALSE(std::isnan(rate));
  EXPECT_NE(HypothesesReport({h}).find(fmt::format("tuning-family rate {:.2f}", rate)),
            std::string::npos)
      << HypothesesReport({h});
  EXPECT_DOUBLE_EQ(ToJson(h)["tuning_family_rate"]["estimate"].get<double>(), rate);
}

}  // namespace
}  // namespace calib
