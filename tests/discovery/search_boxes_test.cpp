// The loop's search boxes where a fit ends on one (loop_stages.h,
// WidenPinnedBoxes, IncludeBoxes): a log-scaled box is widened past the
// bound the fit lies on, within the parameter's range; nothing else moves;
// a stage that continues a widened fit searches boxes at least as wide.
// And a swing's lengthening horizons (FollowHorizons): each searched from
// the previous one's best, the fit the best of them over the whole
// recordings.

#include "loop_stages.h"

#include "calib/core/parameters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace calib::loop_detail {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

ParameterSetting LogBox(const std::string& name, double lower, double upper) {
  ParameterSetting s;
  s.name = name;
  s.lower = lower;
  s.upper = upper;
  s.scale = ParameterScale::kLog;
  return s;
}

ParameterSpec Range(const std::string& name, double lower, double upper) {
  ParameterSpec spec;
  spec.name = name;
  spec.lower = lower;
  spec.upper = upper;
  return spec;
}

TEST(WidenPinnedBoxes, WidensTheBoundAFitLiesOnAndNothingElse) {
  std::vector<ParameterSetting> settings = {LogBox("k_d", 1e-3, 1e4), LogBox("k_D", 10, 1e5),
                                            LogBox("k_A", 0.1, 1e5)};
  ParameterSetting linear;
  linear.name = "tau";
  linear.lower = 0.0;
  linear.upper = 0.5;  // on its upper bound, but linear: not widened
  settings.push_back(linear);
  ParameterSetting fixed;
  fixed.name = "mass";
  fixed.fixed = 0.2;
  settings.push_back(fixed);
  const std::vector<ParameterSpec> specs = {Range("k_d", 0, kInf), Range("k_D", 0, kInf),
                                            Range("k_A", 0, kInf), Range("tau", 0, 1),
                                            Range("mass", 0, kInf)};
  const ParameterValues fit = {{"k_d", 1e4}, {"k_D", 10}, {"k_A", 300}, {"tau", 0.5}, {"mass", 0.2}};

  const std::vector<std::string> widened = WidenPinnedBoxes(settings, fit, specs, 10.0);

  ASSERT_EQ(widened.size(), 2u);
  EXPECT_EQ(widened[0], "k_d: upper 10000 -> 100000");
  EXPECT_EQ(widened[1], "k_D: lower 10 -> 1");
  EXPECT_DOUBLE_EQ(settings[0].lower, 1e-3);
  EXPECT_DOUBLE_EQ(settings[0].upper, 1e5);
  EXPECT_DOUBLE_EQ(settings[1].lower, 1.0);
  EXPECT_DOUBLE_EQ(settings[1].upper, 1e5);
  EXPECT_DOUBLE_EQ(settings[2].lower, 0.1);  // inside its box
  EXPECT_DOUBLE_EQ(settings[2].upper, 1e5);
  EXPECT_DOUBLE_EQ(settings[3].upper, 0.5);
  EXPECT_EQ(*settings[4].fixed, 0.2);

  // The widened boxes hold the fit inside: nothing more to widen.
  EXPECT_TRUE(WidenPinnedBoxes(settings, fit, specs, 10.0).empty());
}

TEST(WidenPinnedBoxes, StaysWithinTheParametersRange) {
  std::vector<ParameterSetting> settings = {LogBox("plastic_yield_strain", 0.01, 0.5)};
  const std::vector<ParameterSpec> specs = {Range("plastic_yield_strain", 0.0, 0.9)};
  const std::vector<std::string> widened =
      WidenPinnedBoxes(settings, {{"plastic_yield_strain", 0.5}}, specs, 10.0);
  ASSERT_EQ(widened.size(), 1u);
  EXPECT_DOUBLE_EQ(settings[0].upper, 0.9);
  // At the range's end there is nowhere to widen to.
  EXPECT_TRUE(WidenPinnedBoxes(settings, {{"plastic_yield_strain", 0.9}}, specs, 10.0).empty());
  EXPECT_DOUBLE_EQ(settings[0].upper, 0.9);
}

TEST(WidenPinnedBoxes, AFactorThatDoesNotWidenIsRefusedByValue) {
  std::vector<ParameterSetting> settings = {LogBox("k_d", 1e-3, 1e4)};
  try {
    WidenPinnedBoxes(settings, {{"k_d", 1e4}}, {Range("k_d", 0, kInf)}, 1.0);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("factor 1"), std::string::npos) << e.what();
  }
}

TEST(IncludeBoxes, AStageContinuingAWidenedFitSearchesBoxesAtLeastAsWide) {
  std::vector<ParameterSetting> settings = {LogBox("k_d", 1e-3, 1e4), LogBox("k_A", 0.1, 1e5),
                                            LogBox("uneven_gradient", 0.01, 1)};
  const std::vector<ParameterSetting> wider = {LogBox("k_d", 1e-3, 3e5), LogBox("k_A", 1, 1e4)};
  IncludeBoxes(settings, wider);
  EXPECT_DOUBLE_EQ(settings[0].lower, 1e-3);
  EXPECT_DOUBLE_EQ(settings[0].upper, 3e5);
  EXPECT_DOUBLE_EQ(settings[1].lower, 0.1);  // already wider than the other
  EXPECT_DOUBLE_EQ(settings[1].upper, 1e5);
  EXPECT_DOUBLE_EQ(settings[2].upper, 1.0);  // not in `wider`
}

// Every horizon prefers k = 1: score (k - 1)^2 times the horizon's frames
// (1000 for the whole recordings).
double HorizonScoreOf(const ParameterValues& v, int frames) {
  return std::pow(v.at("k") - 1.0, 2) * (frames == 0 ? 1000.0 : frames);
}

// Searches that end at the scripted k, or simulate nothing (NaN).
HorizonSearch Scripted(const std::vector<int>& horizons, const std::vector<double>& ends,
                       std::vector<double>* started_from) {
  return [=](size_t k, const ParameterValues& from) {
    started_from->push_back(from.at("k"));
    const ParameterValues values{{"k", ends.at(k - 1)}};
    return std::make_pair(values, std::isnan(ends.at(k - 1)) ? kInf : HorizonScoreOf(values, horizons[k]));
  };
}

TEST(FollowHorizons, TheFitIsTheBestOverTheWholeRecordingsOfEveryHorizonsBest) {
  // Each search starts from the previous one's best; the last ends far
  // from k = 1 (out of phase, as a swing can), so the 504-frame search's
  // best, nearer, is the fit.
  const std::vector<int> horizons = {126, 252, 504, 0};
  std::vector<double> started_from;
  std::vector<std::tuple<int, double, double>> chosen;
  const HorizonFit fit = FollowHorizons(
      horizons, ParameterValues{{"k", 2.0}}, Scripted(horizons, {1.5, 1.2, 3.0}, &started_from),
      HorizonScoreOf, [&](int frames, double score, double last) { chosen.emplace_back(frames, score, last); });
  EXPECT_EQ(started_from, (std::vector<double>{2.0, 1.5, 1.2}));
  EXPECT_DOUBLE_EQ(fit.values.at("k"), 1.2);
  EXPECT_NEAR(fit.score, 0.04 * 1000.0, 1e-9) << "its score over the whole recordings";
  ASSERT_EQ(chosen.size(), 1u);
  EXPECT_EQ(std::get<0>(chosen[0]), 504);
  EXPECT_DOUBLE_EQ(std::get<2>(chosen[0]), 4.0 * 1000.0);

  // Where the last search is the best over the whole recordings, it is the
  // fit, and a tie goes to it.
  started_from.clear();
  const HorizonFit last = FollowHorizons(horizons, ParameterValues{{"k", 2.0}},
                                         Scripted(horizons, {1.5, 1.2, 1.0}, &started_from), HorizonScoreOf);
  EXPECT_DOUBLE_EQ(last.values.at("k"), 1.0);
  EXPECT_DOUBLE_EQ(last.score, 0.0);
  const HorizonScore flat = [](const ParameterValues&, int) { return 5.0; };
  const HorizonSearch flat_search = [](size_t, const ParameterValues&) {
    return std::make_pair(ParameterValues{{"k", 7.0}}, 5.0);
  };
  EXPECT_DOUBLE_EQ(FollowHorizons({10, 0}, ParameterValues{{"k", 2.0}}, flat_search, flat).values.at("k"), 7.0);
}

TEST(FollowHorizons, ASearchThatSimulatesNothingPassesTheFitOn) {
  const std::vector<int> horizons = {10, 20, 0};
  std::vector<double> started_from;
  int scored = 0;
  const HorizonFit fit = FollowHorizons(horizons, ParameterValues{{"k", 2.0}},
                                        Scripted(horizons, {std::nan(""), 1.0}, &started_from),
                                        [&](const ParameterValues& v, int frames) {
                                          ++scored;
                                          return HorizonScoreOf(v, frames);
                                        });
  EXPECT_EQ(started_from, (std::vector<double>{2.0, 2.0}));
  EXPECT_DOUBLE_EQ(fit.values.at("k"), 1.0);
  EXPECT_EQ(scored, 1) << "the fit passed on is scored once";
  // Nothing simulates the whole recordings: no fit (the caller says so).
  started_from.clear();
  EXPECT_EQ(FollowHorizons({10, 0}, ParameterValues{{"k", 2.0}}, Scripted({10, 0}, {std::nan("")}, &started_from),
                           [](const ParameterValues&, int) { return kInf; })
                .score,
            kInf);
  // One horizon: nothing to follow.
  EXPECT_DOUBLE_EQ(FollowHorizons({0}, ParameterValues{{"k", 2.0}}, Scripted({0}, {}, &started_from), HorizonScoreOf)
                       .values.at("k"),
                   2.0);
}

}  // namespace
}  // namespace calib::loop_detail
