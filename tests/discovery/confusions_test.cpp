// Effects that look alike: a pair is reported only when the round met both
// sides; the keep rule's tests separate them when exactly one passes, or
// both pass with drops whose intervals do not overlap; otherwise the report
// says these recordings cannot and proposes the recording that would; the
// base model's turn is a confusion only under an off-centre push.

#include "calib/discovery/confusions.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace calib {
namespace {

Hypothesis Traced(const std::string& effect, double confidence) {
  Hypothesis h;
  h.effect = effect;
  h.confidence = confidence;
  return h;
}

ReportStage Tested(const std::string& effect, double drop, double low, double high, double p,
                   bool significant) {
  ReportStage s;
  s.effect_tried = effect;
  s.test = {330, 33, drop, low, high, p, 2, significant};
  return s;
}

const ReportConfusion* Find(const std::vector<ReportConfusion>& all, const std::string& a,
                            const std::string& b) {
  for (const ReportConfusion& c : all) {
    if (c.effect == a && c.confused_with == b) return &c;
  }
  return nullptr;
}

TEST(Confusions, ExactlyOneSignificantSeparatesThePair) {
  const std::vector<Hypothesis> ranked = {Traced("plasticity", 0.7), Traced("table_friction", 0.6)};
  const ReportStage plastic = Tested("plasticity", 5000, 3000, 7000, 0.0002, true);
  const ReportStage friction = Tested("table_friction", 800, -500, 2100, 0.21, false);
  const auto all = JudgeConfusions(1, ranked, {&plastic, &friction}, 0.0, 0.05);
  const ReportConfusion* c = Find(all, "plasticity", "table_friction");
  ASSERT_NE(c, nullptr);
  EXPECT_TRUE(c->separated);
  EXPECT_TRUE(c->proposal.empty());
  EXPECT_NE(c->evidence.find("p = 0.0002"), std::string::npos) << c->evidence;
  EXPECT_NE(c->evidence.find("p = 0.2100"), std::string::npos) << c->evidence;
  EXPECT_EQ(c->round, 1);
  // Viscoelastic was neither tried nor traced: no such pair.
  EXPECT_EQ(Find(all, "plasticity", "viscoelastic"), nullptr);
}

// Of two calibrations of one effect (--effect-restarts), the evidence reads
// the one the round would keep: a significant one, then the larger drop.
TEST(Confusions, OfAnEffectsCalibrationsTheOneTheRoundWouldKeepIsRead) {
  const std::vector<Hypothesis> ranked = {Traced("plasticity", 0.7), Traced("table_friction", 0.6)};
  const ReportStage first = Tested("plasticity", 9000, -1000, 19000, 0.09, false);
  ReportStage second = Tested("plasticity", 5000, 3000, 7000, 0.0002, true);
  second.restart = 1;
  const ReportStage friction = Tested("table_friction", 800, -500, 2100, 0.21, false);
  const auto all = JudgeConfusions(1, ranked, {&first, &second, &friction}, 0.0, 0.05);
  const ReportConfusion* c = Find(all, "plasticity", "table_friction");
  ASSERT_NE(c, nullptr);
  EXPECT_TRUE(c->separated);
  EXPECT_NE(c->evidence.find("p = 0.0002"), std::string::npos) << c->evidence;
  EXPECT_EQ(c->evidence.find("p = 0.0900"), std::string::npos) << c->evidence;
}

TEST(Confusions, OverlappingDropsCannotBeToldApart) {
  const std::vector<Hypothesis> ranked = {Traced("plasticity", 0.7), Traced("table_friction", 0.6)};
  const ReportStage plastic = Tested("plasticity", 5000, 3000, 7000, 0.0002, true);
  const ReportStage friction = Tested("table_friction", 4500, 2500, 6500, 0.0004, true);
  const auto all = JudgeConfusions(2, ranked, {&plastic, &friction}, 0.0, 0.05);
  const ReportConfusion* c = Find(all, "plasticity", "table_friction");
  ASSERT_NE(c, nullptr);
  EXPECT_FALSE(c->separated);
  EXPECT_NE(c->evidence.find("cannot tell apart"), std::string::npos) << c->evidence;
  EXPECT_NE(c->proposal.find("push the object again"), std::string::npos) << c->proposal;
  // Disjoint intervals: separated.
  const ReportStage weak = Tested("table_friction", 1000, 400, 1600, 0.001, true);
  const auto apart = JudgeConfusions(2, ranked, {&plastic, &weak}, 0.0, 0.05);
  EXPECT_TRUE(Find(apart, "plasticity", "table_friction")->separated);
}

TEST(Confusions, OneSideOnlyTracedIsNotSeparated) {
  const std::vector<Hypothesis> ranked = {Traced("viscoelastic", 0.5), Traced("plasticity", 0.3)};
  const ReportStage visco = Tested("viscoelastic", 900, -100, 1900, 0.08, false);
  const auto all = JudgeConfusions(1, ranked, {&visco}, 0.0, 0.05);
  const ReportConfusion* c = Find(all, "plasticity", "viscoelastic");
  ASSERT_NE(c, nullptr);
  EXPECT_FALSE(c->separated);
  EXPECT_NE(c->evidence.find("plasticity was traced at 0.30 but not tried"), std::string::npos)
      << c->evidence;
  EXPECT_NE(c->proposal.find("after the release"), std::string::npos);
  // Below the confidence the loop tries: not met, not reported.
  EXPECT_EQ(Find(JudgeConfusions(1, ranked, {&visco}, 0.0, 0.4), "plasticity", "viscoelastic"),
            nullptr);
}

TEST(Confusions, TheBaseModelsTurnOnlyUnderAnOffCentrePush) {
  const std::vector<Hypothesis> ranked = {Traced("uneven_stiffness", 0.6)};
  const ReportStage uneven = Tested("uneven_stiffness", 700, -300, 1700, 0.12, false);
  EXPECT_EQ(Find(JudgeConfusions(1, ranked, {&uneven}, 0.1, 0.05), "uneven_stiffness", ""), nullptr)
      << "a centred push does not turn an even object";
  const auto all = JudgeConfusions(1, ranked, {&uneven}, 0.5, 0.05);
  const ReportConfusion* c = Find(all, "uneven_stiffness", "");
  ASSERT_NE(c, nullptr);
  EXPECT_FALSE(c->separated);
  EXPECT_NE(c->evidence.find("eccentricity 0.50"), std::string::npos) << c->evidence;
  EXPECT_NE(c->proposal.find("mirrored"), std::string::npos);
  const ReportStage confirmed = Tested("uneven_stiffness", 9000, 6000, 12000, 0.0001, true);
  EXPECT_TRUE(Find(JudgeConfusions(1, ranked, {&confirmed}, 0.5, 0.05), "uneven_stiffness", "")
                  ->separated);
}

TEST(Confusions, EveryPairNamesItsEvidenceAndProposal) {
  ASSERT_EQ(ConfusablePairs().size(), 3u);
  for (const ConfusablePair& p : ConfusablePairs()) {
    EXPECT_FALSE(std::string(p.separating_evidence).empty()) << p.effect;
    EXPECT_FALSE(std::string(p.proposal).empty()) << p.effect;
  }
}

}  // namespace
}  // namespace calib
