// The loop at its default settings on pushed-sponge recordings made by
// another finite-element code (../shared/data/external: GetFEM, a Hencky
// elastic law, penalty contact with Coulomb friction, its own renderer),
// nothing declared: train on one push, hold out the other. truth.json is
// read here only to check the answer. The recordings are data the project
// did not make and never tunes on; the test fails (never skips) when they
// are missing.

#include "loop_test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;

fs::path ExternalDir() { return testing::SharedDir() / "data" / "external"; }

// The one effect the recording was made with ("effect" of its truth.json).
std::string TrueEffect(const fs::path& recording) {
  std::ifstream in(recording / "truth.json");
  return testing::CatalogueName(nlohmann::json::parse(in).at("effect").get<std::string>());
}

double HeldOutChange(const LoopReport& report) {
  const double before = static_cast<double>(testing::HeldOutXor(*report.BaseStage(), report));
  const double after = static_cast<double>(testing::HeldOutXor(*report.FinalStage(), report));
  return (after - before) / before;
}

LoopReport RunPair(const std::string& train, const std::string& holdout) {
  const fs::path train_dir = ExternalDir() / train, holdout_dir = ExternalDir() / holdout;
  for (const fs::path& dir : {train_dir, holdout_dir}) {
    if (!fs::exists(dir / "recording.json") || !fs::exists(dir / "truth.json")) {
      ADD_FAILURE() << "missing external recording " << dir
                    << " (the shared data folder must sit beside the repository)";
      return {};
    }
  }
  LoopOptions options;  // the defaults, as a user runs it
  options.train = {train_dir};
  options.holdout = {holdout_dir};
  options.out_dir = testing::ScratchDir("external_" + train + "_" + holdout);
  options.overlays_per_recording = 0;  // presentation only
  options.write_html = false;
  return RunLoop(options).report;
}

// x1 -> x2: elastoplastic (J2 with hardening), pushed right and left of
// centre. Plasticity is named and kept, nothing else, and the held-out
// error drops by at least 30 %.
TEST(ExternalPairs, X1ToX2KeepsPlasticityAlone) {
  const LoopReport report = RunPair("x1", "x2");
  ASSERT_FALSE(report.stages.empty());
  const std::string truth = TrueEffect(ExternalDir() / "x1");
  ASSERT_EQ(truth, "plasticity");
  EXPECT_EQ(report.effects_kept, std::vector<std::string>{truth});
  EXPECT_LE(HeldOutChange(report), -0.30);
}

// x3 -> x4: the left 30 % three times stiffer, pushed right of centre and
// over the stiff part's edge. Nothing the recording does not have is kept
// (today the loop keeps nothing here: uneven stiffness is not traced, see
// docs/loop.md); where uneven stiffness is kept, the held-out error drops
// by at least 10 %.
TEST(ExternalPairs, X3ToX4KeepsNoEffectItDoesNotHave) {
  const LoopReport report = RunPair("x3", "x4");
  ASSERT_FALSE(report.stages.empty());
  const std::string truth = TrueEffect(ExternalDir() / "x3");
  ASSERT_EQ(truth, "uneven_stiffness");
  for (const std::string& kept : report.effects_kept) EXPECT_EQ(kept, truth) << "a false discovery";
  if (!report.effects_kept.empty()) EXPECT_LE(HeldOutChange(report), -0.10);
}

}  // namespace
}  // namespace calib
