// The loop's search boxes where a fit ends on one (loop_stages.h,
// WidenPinnedBoxes, IncludeBoxes): a log-scaled box is widened past the
// bound the fit lies on, within the parameter's range; nothing else moves;
// a stage that continues a widened fit searches boxes at least as wide.

#include "loop_stages.h"

#include "calib/core/parameters.h"

#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>
#include <string>
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

}  // namespace
}  // namespace calib::loop_detail
