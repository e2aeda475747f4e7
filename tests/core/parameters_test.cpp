#include "calib/core/parameters.h"

#include "support/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

namespace calib {
namespace {

std::filesystem::path WriteFile(const std::filesystem::path& dir, const std::string& text) {
  const auto path = dir / "params.json";
  std::ofstream(path) << text;
  return path;
}

std::string ErrorOf(const std::filesystem::path& path) {
  try {
    LoadParameterFile(path, BaseModelParameterSpecs());
  } catch (const ParameterError& e) {
    return e.what();
  }
  return "";
}

const char* kValid = R"({"k_D": 10, "k_d": 0.5, "k_A": 3, "k_phi": 1, "mass": 0.01, "tau": 0.2})";

TEST(Parameters, LoadsAValidFile) {
  const auto dir = calib::testing::ScratchDir("params");
  const auto values = LoadParameterFile(WriteFile(dir, kValid), BaseModelParameterSpecs());
  const auto p = ModelParameters::FromValues(values);
  EXPECT_EQ(p.k_distance, 10.0);
  EXPECT_EQ(p.k_damping, 0.5);
  EXPECT_EQ(p.k_area, 3.0);
  EXPECT_EQ(p.k_angle, 1.0);
  EXPECT_EQ(p.mass, 0.01);
  EXPECT_EQ(p.translation, 0.2);
}

TEST(Parameters, SaveLoadRoundTripIsExact) {
  const auto dir = calib::testing::ScratchDir("params");
  ModelParameters p;
  p.k_distance = 1.0 / 3.0;
  p.k_damping = 1e-17;
  p.k_area = 123456.789012345678;
  p.k_angle = 0.1 + 0.2;
  p.mass = 2.5e-7;
  p.translation = 0.7071067811865476;
  SaveParameterFile(dir / "p.json", p.ToValues());
  const auto back = LoadParameterFile(dir / "p.json", BaseModelParameterSpecs());
  EXPECT_EQ(back, p.ToValues());
}

TEST(Parameters, MissingNameIsNamed) {
  const auto dir = calib::testing::ScratchDir("params");
  const auto msg = ErrorOf(WriteFile(dir, R"({"k_D": 1, "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 1})"));
  EXPECT_NE(msg.find("missing parameter 'tau'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("params.json"), std::string::npos) << msg;
}

TEST(Parameters, UnknownNameIsNamed) {
  const auto dir = calib::testing::ScratchDir("params");
  const auto msg = ErrorOf(WriteFile(
      dir, R"({"k_D": 1, "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 1, "tau": 0, "k_X": 2})"));
  EXPECT_NE(msg.find("unknown parameter 'k_X'"), std::string::npos) << msg;
}

TEST(Parameters, ARepeatedNameIsNamed) {
  const auto dir = calib::testing::ScratchDir("params");
  const auto msg = ErrorOf(WriteFile(
      dir, R"({"k_D": 1, "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 1, "tau": 0, "k_D": 2})"));
  EXPECT_NE(msg.find("parameter 'k_D' appears more than once"), std::string::npos) << msg;
  EXPECT_NE(msg.find("params.json"), std::string::npos) << msg;
}

TEST(Parameters, NonNumberIsNamed) {
  const auto dir = calib::testing::ScratchDir("params");
  const auto msg = ErrorOf(WriteFile(
      dir, R"({"k_D": "stiff", "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 1, "tau": 0})"));
  EXPECT_NE(msg.find("'k_D' must be a number"), std::string::npos) << msg;
  EXPECT_NE(msg.find("stiff"), std::string::npos) << msg;
}

TEST(Parameters, OutOfRangeIsNamedWithRule) {
  const auto dir = calib::testing::ScratchDir("params");
  auto msg = ErrorOf(
      WriteFile(dir, R"({"k_D": 1, "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 0, "tau": 0})"));
  EXPECT_NE(msg.find("'mass' = 0 is out of range; must be in (0"), std::string::npos) << msg;
  msg = ErrorOf(
      WriteFile(dir, R"({"k_D": 1, "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 1, "tau": 1.5})"));
  EXPECT_NE(msg.find("'tau' = 1.5"), std::string::npos) << msg;
  msg = ErrorOf(
      WriteFile(dir, R"({"k_D": -1, "k_d": 0, "k_A": 1, "k_phi": 1, "mass": 1, "tau": 0})"));
  EXPECT_NE(msg.find("'k_D' = -1"), std::string::npos) << msg;
}

TEST(Parameters, NonFiniteValueIsNamed) {
  ParameterValues values = ModelParameters{}.ToValues();
  values["k_A"] = std::numeric_limits<double>::quiet_NaN();
  try {
    ValidateParameters(values, BaseModelParameterSpecs(), "candidate 7");
    FAIL() << "NaN accepted";
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find("candidate 7: parameter 'k_A'"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("not finite"), std::string::npos) << e.what();
  }
}

TEST(Parameters, InvalidJsonAndMissingFileNameTheFile) {
  const auto dir = calib::testing::ScratchDir("params");
  auto msg = ErrorOf(WriteFile(dir, R"({"k_D": 1,,})"));
  EXPECT_NE(msg.find("params.json: invalid JSON"), std::string::npos) << msg;
  msg = ErrorOf(WriteFile(dir, R"([1, 2, 3])"));
  EXPECT_NE(msg.find("expected a JSON object"), std::string::npos) << msg;
  msg = ErrorOf(dir / "absent.json");
  EXPECT_NE(msg.find("absent.json: cannot open"), std::string::npos) << msg;
}

}  // namespace
}  // namespace calib
