// What a calibration's history says about its fit (fit_diagnostics.h): a
// parameter left on its box's bound is named with the bound; a score that
// no candidate moved is uninformative; failed candidates do not count.

#include "calib/jobs/fit_diagnostics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace calib {
namespace {

std::vector<ParameterSetting> Settings() {
  std::vector<ParameterSetting> s(3);
  s[0].name = "k_D";
  s[0].lower = 10.0;
  s[0].upper = 1e5;
  s[0].scale = ParameterScale::kLog;
  s[1].name = "tau";
  s[1].lower = 0.0;
  s[1].upper = 0.5;
  s[2].name = "mass";
  s[2].fixed = 0.2;
  return s;
}

EvaluationRecord Evaluation(double score, bool ok = true) {
  EvaluationRecord e;
  e.ok = ok;
  e.score = ok ? score : NAN;
  return e;
}

TEST(FitDiagnostics, NamesTheParametersOnTheirBoxsBounds) {
  const FitDiagnostics upper = DiagnoseFit(Settings(), {{"k_D", 1e5}, {"tau", 0.2}, {"mass", 0.2}}, {});
  ASSERT_EQ(upper.at_bounds.size(), 1u);
  EXPECT_EQ(upper.at_bounds[0], "k_D = 100000 (upper bound)");
  const FitDiagnostics lower = DiagnoseFit(Settings(), {{"k_D", 300.0}, {"tau", 0.0}, {"mass", 0.2}}, {});
  ASSERT_EQ(lower.at_bounds.size(), 1u);
  EXPECT_EQ(lower.at_bounds[0], "tau = 0 (lower bound)");
  // Inside (on the log scale too), and a fixed value, say nothing.
  const FitDiagnostics inside = DiagnoseFit(Settings(), {{"k_D", 10.001}, {"tau", 0.4999}, {"mass", 0.2}}, {});
  EXPECT_TRUE(inside.at_bounds.empty());
  EXPECT_EQ(inside.Summary(), "");
  EXPECT_NE(upper.Summary().find("on the search box's bound: k_D = 100000 (upper bound)"), std::string::npos);
}

TEST(FitDiagnostics, AnAngleSearchedOverAWholeTurnHasNoBound) {
  std::vector<ParameterSetting> settings = Settings();
  ParameterSetting angle;
  angle.name = "gravity_angle_deg";
  angle.lower = -180.0;
  angle.upper = 180.0;
  settings.push_back(angle);
  const ParameterValues best{{"k_D", 300.0}, {"tau", 0.2}, {"mass", 0.2}, {"gravity_angle_deg", -180.0}};
  EXPECT_TRUE(DiagnoseFit(settings, best, {}).at_bounds.empty());
  settings.back().upper = 90.0;  // part of a turn: its ends are bounds
  ASSERT_EQ(DiagnoseFit(settings, best, {}).at_bounds.size(), 1u);
  EXPECT_EQ(DiagnoseFit(settings, best, {}).at_bounds[0], "gravity_angle_deg = -180 (lower bound)");
}

TEST(FitDiagnostics, AScoreThatNoCandidateMovedIsUninformative) {
  const std::vector<EvaluationRecord> flat{Evaluation(7088623.0), Evaluation(7088623.0),
                                           Evaluation(0.0, false), Evaluation(7088623.0)};
  const FitDiagnostics d = DiagnoseFit(Settings(), {}, flat);
  EXPECT_TRUE(d.uninformative);
  EXPECT_EQ(d.scored, 3) << "failed candidates do not count";
  EXPECT_NE(d.Summary().find("uninformative: all 3 successful evaluations scored the same"),
            std::string::npos);
  const std::vector<EvaluationRecord> moved{Evaluation(7088623.0), Evaluation(7088622.0)};
  EXPECT_FALSE(DiagnoseFit(Settings(), {}, moved).uninformative);
  EXPECT_EQ(DiagnoseFit(Settings(), {}, moved).score_spread, 1.0);
  // One candidate, or none that simulated, is no evidence either way.
  EXPECT_FALSE(DiagnoseFit(Settings(), {}, std::vector<EvaluationRecord>{Evaluation(5.0)}).uninformative);
  EXPECT_FALSE(DiagnoseFit(Settings(), {}, std::vector<EvaluationRecord>{Evaluation(0.0, false)}).uninformative);
}

}  // namespace
}  // namespace calib
