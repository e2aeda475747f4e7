// Golden regression test: what `calib` computes, bit for bit, at a small
// budget, against files made by the code at the time (tests/golden/):
//  - a CMA-ES job like examples/jobs/push_centre_cmaes.yaml on the bundled
//    centre push with 24 evaluations: every evaluation's id, status, score
//    and parameters as stored, the best parameter file and the report's
//    scores on the training and held-out recordings;
//  - `calib loop` on push_centre / push_offset at a tiny budget (the base
//    model fits it: --min-confidence 0 makes the loop try the best ranked
//    hypothesis all the same, so that a decision is taken): the stages with
//    their decisions, criterion values, parameters and errors, the
//    hypotheses, the kept effects, and every evaluation of every job of its
//    store.
// Doubles are compared exactly (JSON text that reads back to the same
// double). scripts/compare-outputs.sh makes the same comparison between two
// commits at the full budgets. This test guards a refactoring that must not
// change behaviour; after a deliberate change of behaviour regenerate the
// goldens with scripts/update-golden.sh (CALIB_UPDATE_GOLDEN=1 makes this
// test rewrite them instead of comparing) and commit them with the change.

#include "support/loop_decisions.h"
#include "support/process_support.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sqlite3.h>

#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::string kCalib = CALIB_EXE;
const fs::path kSource = CALIB_SOURCE_DIR;
const fs::path kGoldenDir = kSource / "tests" / "golden";
const std::string kCacheDir = CALIB_TEST_CACHE_DIR;
// Threads of every run (CALIB_GOLDEN_THREADS overrides: the goldens hold at
// any thread count).
int Threads() {
  const char* v = std::getenv("CALIB_GOLDEN_THREADS");
  return v != nullptr && *v != '\0' ? std::atoi(v) : 2;
}

bool UpdatingGoldens() {
  const char* v = std::getenv("CALIB_UPDATE_GOLDEN");
  return v != nullptr && *v != '\0' && std::string(v) != "0";
}

json ReadJson(const fs::path& path) {
  const std::string text = testing::ReadText(path);
  if (text.empty()) {
    ADD_FAILURE() << path << ": missing or empty";
    return nullptr;
  }
  return json::parse(text);
}

// Runs calib with `args`; a non-zero exit fails the test with its output.
void RunCalib(const std::vector<std::string>& args, const fs::path& dir) {
  std::vector<std::string> argv = {kCalib};
  argv.insert(argv.end(), args.begin(), args.end());
  const testing::ProcessResult r = testing::RunProcess(argv, dir, {}, 600.0);
  ASSERT_EQ(r.exit_code, 0) << fmt::format("{}", fmt::join(argv, " ")) << "\nstdout:\n"
                            << r.out << "\nstderr:\n"
                            << r.err;
}

// Every job of a results store by name, in creation order, with every
// evaluation's id, status, score and parameters exactly as stored.
json StoredHistories(const fs::path& db_path) {
  sqlite3* db = nullptr;
  json jobs = json::array();
  if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    ADD_FAILURE() << db_path << ": cannot open: " << sqlite3_errmsg(db);
    sqlite3_close(db);
    return jobs;
  }
  const char* sql =
      "SELECT j.name, e.id, e.status, e.score, e.parameters_json FROM jobs j "
      "JOIN evaluations e ON e.job_id = j.id ORDER BY j.id, e.id";
  sqlite3_stmt* s = nullptr;
  if (sqlite3_prepare_v2(db, sql, -1, &s, nullptr) != SQLITE_OK) {
    ADD_FAILURE() << db_path << ": " << sqlite3_errmsg(db);
  } else {
    while (sqlite3_step(s) == SQLITE_ROW) {
      const std::string job = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
      if (jobs.empty() || jobs.back()["job"] != job) {
        jobs.push_back({{"job", job}, {"evaluations", json::array()}});
      }
      json e = {{"id", sqlite3_column_int64(s, 1)},
                {"status", reinterpret_cast<const char*>(sqlite3_column_text(s, 2))},
                {"score", nullptr},
                {"parameters", json::parse(reinterpret_cast<const char*>(sqlite3_column_text(s, 4)))}};
      if (sqlite3_column_type(s, 3) != SQLITE_NULL) e["score"] = sqlite3_column_double(s, 3);
      jobs.back()["evaluations"].push_back(std::move(e));
    }
  }
  sqlite3_finalize(s);
  sqlite3_close(db);
  return jobs;
}

// How an array element is named in a difference's path: its id, its name
// or job, or its index.
std::string ElementLabel(const json& element, size_t index) {
  if (element.is_object()) {
    for (const char* key : {"id", "name", "job", "effect", "recording"}) {
      if (element.contains(key)) return fmt::format("[{}={}]", key, element[key].dump());
    }
  }
  return fmt::format("[{}]", index);
}

// Appends "path: golden X, now Y" for every difference (numbers exactly, by
// their round-trip text, so 0.1 + 0.2 != 0.3 and -0.0 != 0.0).
void Differences(const json& golden, const json& now, const std::string& path,
                 std::vector<std::string>& out) {
  if (golden.is_object() && now.is_object()) {
    for (const auto& [key, value] : golden.items()) {
      const std::string p = path.empty() ? key : path + "." + key;
      if (!now.contains(key)) {
        out.push_back(fmt::format("{}: golden {}, now missing", p, value.dump()));
      } else {
        Differences(value, now[key], p, out);
      }
    }
    for (const auto& [key, value] : now.items()) {
      if (!golden.contains(key)) {
        out.push_back(fmt::format("{}.{}: not in the golden, now {}", path, key, value.dump()));
      }
    }
  } else if (golden.is_array() && now.is_array()) {
    const size_t n = std::min(golden.size(), now.size());
    for (size_t i = 0; i < n; ++i) Differences(golden[i], now[i], path + ElementLabel(golden[i], i), out);
    if (golden.size() != now.size()) {
      out.push_back(fmt::format("{}: golden {} elements, now {}", path, golden.size(), now.size()));
    }
  } else if (golden.dump() != now.dump()) {
    out.push_back(fmt::format("{}: golden {}, now {}", path, golden.dump(), now.dump()));
  }
}

// Compares `now` with tests/golden/<name>, or rewrites that file when
// CALIB_UPDATE_GOLDEN is set.
void ExpectGolden(const json& now, const std::string& name) {
  const fs::path path = kGoldenDir / name;
  if (UpdatingGoldens()) {
    std::ofstream out(path);
    out << now.dump(1) << "\n";
    ASSERT_TRUE(out.good()) << path << ": cannot write";
    std::cout << "CALIB_UPDATE_GOLDEN: rewrote " << path.string() << "\n";
    return;
  }
  ASSERT_TRUE(fs::exists(path)) << path << ": no golden file; make it with scripts/update-golden.sh";
  const json golden = ReadJson(path);
  std::vector<std::string> diffs;
  Differences(golden, now, "", diffs);
  std::string listed;
  for (size_t i = 0; i < diffs.size() && i < 25; ++i) listed += "  " + diffs[i] + "\n";
  EXPECT_TRUE(diffs.empty())
      << name << ": " << diffs.size() << " values differ from the golden (first 25):\n"
      << listed
      << "A refactoring must not change these. If the change of behaviour is deliberate, "
         "regenerate the goldens (scripts/update-golden.sh) and commit them with it.";
}

// ---------------------------------------------------------------------------

// examples/jobs/push_centre_cmaes.yaml at 24 evaluations (4 generations of 6).
std::string JobYaml(const fs::path& dir) {
  return fmt::format(R"yaml(
name: golden_push_centre_cmaes
train: [{}]
holdout: [{}]
model:
  effects: []
  substeps: 10
  integrator: first_order
  constraint_iterations: 8
  mesh: {{edge_length_px: 20}}
parameters:
  - {{name: k_D,   lower: 10,   upper: 5000, scale: log}}
  - {{name: k_d,   lower: 0.01, upper: 50,   scale: log}}
  - {{name: k_A,   lower: 1,    upper: 5000, scale: log}}
  - {{name: k_phi, lower: 0.1,  upper: 1000, scale: log}}
  - {{name: mass,  fixed: 0.2}}
  - {{name: tau,   lower: 0,    upper: 0.5}}
optimizer: {{name: cmaes, settings: {{population: 6, initial_sigma: 0.3}}}}
budget: {{evaluations: 24}}
seed: 1
threads: {}
checkpoint: {{every_evaluations: 12, every_seconds: 0}}
failure_policy: {{mode: penalty}}
results: {{store: {}, out_dir: {}}}
)yaml",
                     (kSource / "examples" / "push_centre").string(),
                     (kSource / "examples" / "push_offset").string(), Threads(),
                     (dir / "store.sqlite").string(), (dir / "report").string());
}

TEST(GoldenTest, ExampleJobAtASmallBudget) {
  const fs::path dir = testing::ScratchDir("golden_job");
  const fs::path spec = dir / "job.yaml";
  std::ofstream(spec) << JobYaml(dir);
  RunCalib({"run", spec.string(), "--progress", "none", "--no-video", "--cache-dir", kCacheDir}, dir);
  RunCalib({"best", spec.string(), "--out", (dir / "best.json").string()}, dir);
  RunCalib({"results", spec.string(), "--json", (dir / "results.json").string()}, dir);

  const json results = ReadJson(dir / "results.json");
  json recordings = json::array();  // the report: the best simulated on train and held out
  for (const json& r : results["job"]["result"]["recordings"]) {
    recordings.push_back({{"role", r["role"]},
                          {"recording", r["recording"]},
                          {"score", r["score"]},
                          {"mean_iou", r["mean_iou"]},
                          {"status", r["status"]}});
  }
  const json now = {{"job", StoredHistories(dir / "store.sqlite")},
                    {"status", results["job"]["status"]},
                    {"stop_reason", results["job"]["stop_reason"]},
                    {"best_id", results["summary"]["best"]["id"]},
                    {"best_parameters", ReadJson(dir / "best.json")},
                    {"report", recordings}};
  EXPECT_EQ(now["job"].size(), 1u);
  EXPECT_EQ(now["job"][0]["evaluations"].size(), 24u);
  ExpectGolden(now, "job_push_centre_cmaes_24.json");
  if (!HasFailure()) fs::remove_all(dir);
}

TEST(GoldenTest, LoopOnPushCentreAtATinyBudget) {
  const fs::path dir = testing::ScratchDir("golden_loop");
  RunCalib({"loop", "--train", (kSource / "examples" / "push_centre").string(), "--holdout",
            (kSource / "examples" / "push_offset").string(), "--out", (dir / "loop").string(),
            "--budget", "16", "--effect-budget", "16", "--restarts", "1", "--equally-good-fits",
            "4", "--max-effects", "1", "--tries", "1", "--min-confidence", "0", "--seed", "1",
            "--overlays", "0", "--no-html", "--quiet", "--threads", std::to_string(Threads()), "--cache-dir",
            kCacheDir},
           dir);
  const json decisions = testing::LoopDecisions(ReadJson(dir / "loop" / "report.json"));
  // At least one effect tried, so that a decision is exercised.
  ASSERT_GE(decisions["stages"].size(), 2u) << decisions.dump(1);
  const json now = {{"loop", decisions}, {"store", StoredHistories(dir / "loop" / "store.sqlite")}};
  ExpectGolden(now, "loop_push_centre_push_offset.json");
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace calib
