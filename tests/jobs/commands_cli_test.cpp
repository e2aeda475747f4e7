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
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;

const std::string kCalib = CALIB_EXE;
const fs::path kExamples = fs::path(CALIB_SOURCE_DIR) / "examples";

#define EXPECT_HAS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "output: " << (text)

// Bad command lines are bad input: exit status 2 with CLI11's message,
// not CLI11's own codes (100 and up); --help and --version exit 0.
TEST(Cli, ParseErrorsExitWithStatus2) {
  const fs::path dir = testing::ScratchDir("cli_parse_errors");
  const auto unknown = testing::RunProcess(
      {kCalib, "score", (kExamples / "push_centre").string(), "--params", "p.json", "--no-such-option"},
      dir);
  EXPECT_EQ(unknown.exit_code, 2) << unknown.err;
  EXPECT_HAS(unknown.err, "--no-such-option");
  const auto missing = testing::RunProcess({kCalib, "score"}, dir);
  EXPECT_EQ(missing.exit_code, 2) << missing.err;
  EXPECT_HAS(missing.err, "recording");
  const auto bad_value = testing::RunProcess({kCalib, "run", "job.yaml", "--threads", "many"}, dir);
  EXPECT_EQ(bad_value.exit_code, 2) << bad_value.err;
  EXPECT_HAS(bad_value.err, "--threads");
  const auto none = testing::RunProcess({kCalib}, dir);
  EXPECT_EQ(none.exit_code, 2) << none.err;
  EXPECT_EQ(testing::RunProcess({kCalib, "--help"}, dir).exit_code, 0);
  const auto version = testing::RunProcess({kCalib, "--version"}, dir);
  EXPECT_EQ(version.exit_code, 0) << version.err;
  EXPECT_HAS(version.out, "calib ");
}

// `calib simulate` says a failed simulation as `calib score` does: exit 3.
TEST(SimulateCli, AFailedSimulationExitsWithStatus3) {
  const fs::path dir = testing::ScratchDir("simulate_cli_failed");
  // Far too stiff for the explicit first-order step: it blows up.
  const fs::path params = dir / "stiff.json";
  std::ofstream(params) << R"({"k_D": 1e9, "k_d": 2.0, "k_A": 200.0, "k_phi": 50.0, "mass": 0.2, "tau": 0.3})";
  const auto r = testing::RunProcess(
      {kCalib, "simulate", (kExamples / "push_centre").string(), "--params", params.string(), "--out",
       (dir / "out").string(), "--no-video", "--cache-dir", (dir / "cache").string()},
      dir);
  EXPECT_EQ(r.exit_code, 3) << r.out << r.err;
  EXPECT_HAS(r.out, "status: failed at frame");
  EXPECT_HAS(r.out, "not simulated counting 0");  // its IoU does not look good
}

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

// The score's first line, "score (XOR pixel area summed over frames): N",
// N exactly.
double PrintedScore(const std::string& out) {
  const std::string key = "score (XOR pixel area summed over frames): ";
  const size_t at = out.find(key);
  EXPECT_NE(at, std::string::npos) << out;
  return at == std::string::npos ? -1.0 : std::stod(out.substr(at + key.size()));
}

// A simulation option of `calib score` reaches the simulation: the printed
// score is that of RunScore with the option set, and differs from the
// default's on push_centre at params_push.json.
void ExpectOptionReachesTheSimulation(const std::string& name,
                                      const std::vector<std::string>& flags,
                                      const std::function<void(CommandSettings&)>& set) {
  const fs::path dir = testing::ScratchDir("score_cli_" + name);
  const fs::path recording = kExamples / "push_centre";
  const fs::path params = kExamples / "params_push.json";
  const std::vector<std::string> command = {kCalib,       "score",         recording.string(),
                                            "--params",   params.string(), "--cache-dir",
                                            (dir / "cache").string()};
  std::vector<std::string> with_option = command;
  with_option.insert(with_option.end(), flags.begin(), flags.end());
  const auto plain = testing::RunProcess(command, dir);
  const auto option = testing::RunProcess(with_option, dir);
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  ASSERT_EQ(option.exit_code, 0) << option.err;
  CommandSettings settings;
  settings.preparation.cache_dir = dir / "cache";
  set(settings);
  const EvaluationResult expected = RunScore(recording, params, settings);
  EXPECT_EQ(PrintedScore(option.out), expected.xor_sum) << name;
  EXPECT_NE(PrintedScore(plain.out), PrintedScore(option.out)) << name;
}

TEST(ScoreCli, OutlineContactReachesTheSimulation) {
  // The 7 px finger and the pencil slip between the 20 px mesh's nodes:
  // keeping them out of the edges changes the score.
  ExpectOptionReachesTheSimulation("contact", {"--outline-contact"}, [](CommandSettings& s) {
    s.simulation.outline_contact = true;
  });
}

TEST(ScoreCli, ImplicitIntegratorReachesTheSimulation) {
  ExpectOptionReachesTheSimulation(
      "implicit", {"--integrator", "implicit_first_order"},
      [](CommandSettings& s) { s.simulation.integrator = IntegratorKind::kImplicitFirstOrder; });
}

TEST(ScoreCli, ContactFrictionReachesTheSimulation) {
  ExpectOptionReachesTheSimulation("friction", {"--contact-friction", "0.5"},
                                   [](CommandSettings& s) { s.simulation.contact_friction = 0.5; });
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

// The loop's default simulation is the implicit step with outline contact
// and contact friction; the flags give back the paper's, and the report
// says which one ran.
TEST(LoopCli, ThePapersSimulationCanBeAskedFor) {
  const fs::path dir = testing::ScratchDir("loop_cli_paper");
  const std::vector<std::string> common = {
      kCalib,      "loop",      "--train", (kExamples / "push_centre").string(), "--budget", "12",
      "--restarts", "1",        "--max-effects", "0", "--overlays", "0", "--no-html",
      "--cache-dir", (dir / "cache").string()};
  auto notes = [&](const std::string& out, std::vector<std::string> flags) {
    std::vector<std::string> command = common;
    command.push_back("--out");
    command.push_back((dir / out).string());
    command.insert(command.end(), flags.begin(), flags.end());
    const auto r = testing::RunProcess(command, dir);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    std::ifstream in(dir / out / "report.json");
    return nlohmann::json::parse(in).at("notes").dump();
  };
  const std::string fallback = notes("default", {});
  EXPECT_HAS(fallback, "implicit_first_order integrator");
  EXPECT_HAS(fallback, "outline contact");
  EXPECT_HAS(fallback, "contact friction 0.5");
  const std::string paper = notes(
      "paper", {"--integrator", "first_order", "--node-contact", "--contact-friction", "0"});
  EXPECT_HAS(paper, "first_order integrator");
  EXPECT_HAS(paper, "node contact");
  EXPECT_HAS(paper, "frictionless contact");
}

}  // namespace
}  // namespace calib
