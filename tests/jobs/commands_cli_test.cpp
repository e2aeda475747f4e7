// The recording commands on the bundled recordings. `calib compare`: a
// recording against itself differs nowhere; against another take the
// printed sum is the per-frame CSV's; recordings that cannot be compared are
// named, exit status 2. `calib score --outline-contact` and `--integrator
// implicit_first_order` score as a job with those settings does; `calib
// loop --integrator` names a value it cannot use.

#include "calib/jobs/commands.h"
#include "support/csv_support.h"
#include "support/process_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;

const std::string kCalib = CALIB_EXE;
const fs::path kExamples = fs::path(CALIB_SOURCE_DIR) / "examples";

#define EXPECT_HAS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "output: " << (text)

TEST(CompareCli, ARecordingAgainstItselfDiffersNowhere) {
  const fs::path dir = testing::ScratchDir("compare_cli_self");
  const auto r = testing::RunProcess(
      {kCalib, "compare", (kExamples / "push_centre").string(), (kExamples / "push_centre").string(),
       "--cache-dir", (dir / "cache").string()},
      dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_HAS(r.out, "difference (XOR pixels summed over frames): 0\n");
  EXPECT_HAS(r.out, "mean IoU: 1.0000 over 330 frames");
}

TEST(CompareCli, ThePrintedSumIsThePerFrameCsvs) {
  const fs::path dir = testing::ScratchDir("compare_cli_takes");
  const fs::path csv = dir / "difference.csv";
  const auto r = testing::RunProcess(
      {kCalib, "compare", (kExamples / "push_centre").string(), (kExamples / "push_offset").string(),
       "--csv", csv.string(), "--no-cache"},
      dir);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const testing::CsvRows rows = testing::ParseCsvFile(csv);
  ASSERT_EQ(rows.size(), 331u);
  int64_t sum = 0;
  for (size_t i = 1; i < rows.size(); ++i) {
    EXPECT_EQ(std::stoll(rows[i][1]), std::stoll(rows[i][2]) + std::stoll(rows[i][3])) << "row " << i;
    sum += std::stoll(rows[i][1]);
  }
  EXPECT_GT(sum, 0);
  EXPECT_HAS(r.out, "difference (XOR pixels summed over frames): " + std::to_string(sum) + "\n");
}

TEST(CompareCli, RecordingsOfDifferentLengthsAreNamed) {
  const fs::path dir = testing::ScratchDir("compare_cli_lengths");
  const fs::path real = testing::RealRecordingsDir() / "concave_1";
  if (!fs::exists(real / "recording.json")) GTEST_FAIL() << "missing real recording " << real;
  const auto r = testing::RunProcess(
      {kCalib, "compare", (kExamples / "push_centre").string(), real.string(), "--no-cache"}, dir);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_HAS(r.err, "push_centre (330 frames)");
  EXPECT_HAS(r.err, "concave_1 (1074 frames)");
}

// The score's first line, "score (XOR pixels summed over frames): N".
int64_t PrintedScore(const std::string& out) {
  const std::string key = "score (XOR pixels summed over frames): ";
  const size_t at = out.find(key);
  EXPECT_NE(at, std::string::npos) << out;
  return at == std::string::npos ? -1 : std::stoll(out.substr(at + key.size()));
}

TEST(ScoreCli, OutlineContactReachesTheSimulation) {
  const fs::path dir = testing::ScratchDir("score_cli_contact");
  const fs::path recording = kExamples / "push_centre";
  const fs::path params = kExamples / "params_push.json";
  const std::string cache = (dir / "cache").string();
  const auto node = testing::RunProcess(
      {kCalib, "score", recording.string(), "--params", params.string(), "--cache-dir", cache}, dir);
  const auto outline = testing::RunProcess({kCalib, "score", recording.string(), "--params",
                                            params.string(), "--cache-dir", cache,
                                            "--outline-contact"},
                                           dir);
  ASSERT_EQ(node.exit_code, 0) << node.err;
  ASSERT_EQ(outline.exit_code, 0) << outline.err;
  CommandSettings settings;
  settings.preparation.cache_dir = dir / "cache";
  settings.simulation.outline_contact = true;
  const EvaluationResult expected = RunScore(recording, params, settings);
  EXPECT_EQ(PrintedScore(outline.out), expected.xor_sum);
  // The 7 px finger and the pencil slip between the 20 px mesh's nodes:
  // keeping them out of the edges changes the score.
  EXPECT_NE(PrintedScore(node.out), PrintedScore(outline.out));
}

TEST(ScoreCli, ImplicitIntegratorReachesTheSimulation) {
  const fs::path dir = testing::ScratchDir("score_cli_implicit");
  const fs::path recording = kExamples / "push_centre";
  const fs::path params = kExamples / "params_push.json";
  const std::string cache = (dir / "cache").string();
  const auto explicit_run = testing::RunProcess(
      {kCalib, "score", recording.string(), "--params", params.string(), "--cache-dir", cache}, dir);
  const auto implicit_run =
      testing::RunProcess({kCalib, "score", recording.string(), "--params", params.string(),
                           "--cache-dir", cache, "--integrator", "implicit_first_order"},
                          dir);
  ASSERT_EQ(explicit_run.exit_code, 0) << explicit_run.err;
  ASSERT_EQ(implicit_run.exit_code, 0) << implicit_run.err;
  CommandSettings settings;
  settings.preparation.cache_dir = dir / "cache";
  settings.simulation.integrator = IntegratorKind::kImplicitFirstOrder;
  const EvaluationResult expected = RunScore(recording, params, settings);
  EXPECT_EQ(PrintedScore(implicit_run.out), expected.xor_sum);
  EXPECT_NE(PrintedScore(explicit_run.out), PrintedScore(implicit_run.out));
}

TEST(LoopCli, AnIntegratorItCannotUseIsNamed) {
  // verlet is second order: the loop's first-order calibrations (and
  // inertia, which brings its own step) have no use for it.
  const fs::path dir = testing::ScratchDir("loop_cli_integrator");
  const auto r = testing::RunProcess({kCalib, "loop", "--train", (kExamples / "push_centre").string(),
                                      "--out", (dir / "out").string(), "--integrator", "verlet"},
                                     dir);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_HAS(r.err + r.out, "--integrator");
  EXPECT_HAS(r.err + r.out, "verlet");
  EXPECT_FALSE(fs::exists(dir / "out" / "report.json"));
}

}  // namespace
}  // namespace calib
