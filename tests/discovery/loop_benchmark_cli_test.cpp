// `calib loop-benchmark` end to end on one object (the bundled plastic push
// pair, at the smallest budgets that run the whole loop, ~20 s): the outputs
// are written, a second run reads the object back instead of running it, and
// a bad manifest or selection is named with exit status 2.

#include "support/csv_support.h"
#include "support/process_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kCalib = CALIB_EXE;
const fs::path kExamples = fs::path(CALIB_SOURCE_DIR) / "examples";

#define EXPECT_HAS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "output: " << (text)

// A family of one plasticity object whose recordings are the bundled pair.
fs::path PlasticFamily(const fs::path& dir) {
  const fs::path family = dir / "family";
  fs::create_directories(family);
  const json object = {{"id", "plasticity-clear-00"},
                       {"cell", "plasticity-clear"},
                       {"effect", "plasticity"},
                       {"loop_effect", "plasticity"},
                       {"magnitude", "clear"},
                       {"confusable_with", "table_friction"},
                       {"recordings",
                        {fs::relative(kExamples / "push_plastic", family).string(),
                         fs::relative(kExamples / "push_plastic_offset", family).string()}}};
  std::ofstream(family / "family.json") << json{
      {"format", "calib-family/1"},
      {"name", "plastic"},
      {"spec", "bundled"},
      {"seed", 1},
      {"count", 1},
      {"objects", {object}}}.dump(1);
  return family;
}

std::vector<std::string> Command(const fs::path& family, const fs::path& out) {
  return {kCalib,
          "loop-benchmark",
          family.string(),
          "--out",
          out.string(),
          "--budget",
          "8",
          "--restarts",
          "1",
          "--max-effects",
          "1",
          "--tries",
          "1",
          "--equally-good-fits",
          "0",
          "--overlays",
          "0",
          "--no-html",
          "--cache-dir",
          CALIB_TEST_CACHE_DIR};
}

TEST(LoopBenchmarkCli, RunsAFamilyAndReadsItBackOnTheSecondRun) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_cli");
  const fs::path family = PlasticFamily(dir);
  const auto first = testing::RunProcess(Command(family, dir / "out"), dir, {}, 300.0);
  ASSERT_EQ(first.exit_code, 0) << first.err;
  EXPECT_HAS(first.out, "objects: 1 (1 run, 0 read back, 0 failed)");
  const json doc = json::parse(testing::ReadText(dir / "out" / "benchmark.json"));
  ASSERT_EQ(doc["objects"].size(), 1u);
  const json& o = doc["objects"][0];
  EXPECT_EQ(o["status"], "ok") << o.dump(1);
  EXPECT_GT(o["holdout_xor_before"].get<double>(), 0.0);
  EXPECT_GT(o["train_xor_before"].get<double>(), 0.0);
  EXPECT_FALSE(o["first_round"].empty());
  EXPECT_EQ(doc["aggregate"]["detection"][0]["detected"]["trials"], 1);
  EXPECT_TRUE(fs::exists(dir / "out" / "objects" / "plasticity-clear-00" / "report.json"));
  EXPECT_TRUE(fs::exists(dir / "out" / "objects" / "plasticity-clear-00" / "summary.json"));
  EXPECT_EQ(testing::ParseCsvFile(dir / "out" / "benchmark.csv").size(), 2u);
  EXPECT_FALSE(fs::exists(dir / "out" / "benchmark.html"));  // --no-html

  const auto second = testing::RunProcess(Command(family, dir / "out"), dir, {}, 300.0);
  ASSERT_EQ(second.exit_code, 0) << second.err;
  EXPECT_HAS(second.out, "objects: 1 (0 run, 1 read back, 0 failed)");
  const json again = json::parse(testing::ReadText(dir / "out" / "benchmark.json"));
  EXPECT_EQ(again["objects"][0]["holdout_xor_after"], o["holdout_xor_after"]);
  EXPECT_EQ(again["objects"][0]["resumed"], true);
}

TEST(LoopBenchmarkCli, ABadManifestOrSelectionIsNamedWithStatus2) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_cli_bad");
  const fs::path family = PlasticFamily(dir);
  const auto unknown = testing::RunProcess({kCalib, "loop-benchmark", family.string(), "--out",
                                            (dir / "out").string(), "--only", "x-00"},
                                           dir);
  EXPECT_EQ(unknown.exit_code, 2) << unknown.err;
  EXPECT_HAS(unknown.err, "--only x-00: no such object");

  json doc = json::parse(testing::ReadText(family / "family.json"));
  doc["objects"][0]["loop_effect"] = "plastic";
  std::ofstream(family / "family.json") << doc.dump();
  const auto bad = testing::RunProcess(
      {kCalib, "loop-benchmark", family.string(), "--out", (dir / "out").string()}, dir);
  EXPECT_EQ(bad.exit_code, 2) << bad.err;
  EXPECT_HAS(bad.err, "family.json: objects[0] (id 'plasticity-clear-00').loop_effect");
}

}  // namespace
}  // namespace calib
