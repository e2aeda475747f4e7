// The CI subset of the loop benchmark: `calib synth --family` makes the
// small CI family (examples/families/ci.yaml: one object with no effect, one
// with clear plasticity, short pushes on coarse meshes) and `calib
// loop-benchmark` runs the loop on both at its default settings, on
// recordings made with randomised shapes, materials and cameras, not the
// bundled pairs. The plastic object keeps plasticity; the benchmark's false
// discoveries are the objects that kept an effect they lack, counted as the
// per-object outcomes say. The acceptance of issue 22 (no effect kept on an
// object without one) is NOT met on this family yet: at commit time the
// object without an effect kept plasticity and uneven stiffness (held-out
// -17 %, p = 0.004 and 0.0006), the plastic one plasticity and table
// friction (docs/loop.md, "The CI family"); this test does not assert it.

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
const fs::path kFamilies = fs::path(CALIB_SOURCE_DIR) / "examples" / "families";

TEST(FamilyBenchmark, TheCiFamilyKeepsWhatEachObjectHasAndNothingElse) {
  const fs::path dir = testing::ScratchDir("family_benchmark_ci");
  const fs::path family = dir / "family";
  const auto synth = testing::RunProcess({kCalib, "synth", "--family", (kFamilies / "ci.yaml").string(),
                                          "--count", "1", "--seed", "1", "--out", family.string()},
                                         dir, {}, 600.0);
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const auto bench = testing::RunProcess(
      {kCalib, "loop-benchmark", family.string(), "--out", (dir / "out").string(), "--overlays",
       "0", "--no-html", "--cache-dir", CALIB_TEST_CACHE_DIR},
      dir, {}, 1200.0);
  ASSERT_EQ(bench.exit_code, 0) << bench.err;
  std::ifstream in(dir / "out" / "benchmark.json");
  ASSERT_TRUE(in) << "no benchmark.json";
  const json doc = json::parse(in);
  ASSERT_TRUE(doc.contains("objects")) << doc.dump(1).substr(0, 2000);
  ASSERT_EQ(doc["objects"].size(), 2u);
  int false_discoveries = 0;
  bool plastic_seen = false;
  for (const json& o : doc["objects"]) {
    SCOPED_TRACE(o.dump(1).substr(0, 3000));
    ASSERT_EQ(o.value("status", ""), "ok");
    const std::vector<std::string> kept = o["effects_kept"].get<std::vector<std::string>>();
    const std::string present = o["loop_effect"].is_null() ? "" : o["loop_effect"].get<std::string>();
    bool lacks = false;
    for (const std::string& k : kept) lacks |= k != present;
    false_discoveries += lacks ? 1 : 0;
    EXPECT_EQ(o.value("false_discovery", !lacks), lacks);
    if (present == "plasticity") {
      plastic_seen = true;
      ASSERT_FALSE(kept.empty());
      EXPECT_EQ(kept.front(), "plasticity") << "the effect present is the first kept";
      EXPECT_LT(o["holdout_xor_after"].get<double>(), o["holdout_xor_before"].get<double>());
    }
  }
  EXPECT_TRUE(plastic_seen);
  const json& fd = doc["aggregate"]["false_discoveries"]["all"];
  EXPECT_EQ(fd["successes"].get<int>(), false_discoveries);
  EXPECT_EQ(fd["trials"].get<int>(), 2);
}

}  // namespace
}  // namespace calib
