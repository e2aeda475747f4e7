// Loops and optimiser comparisons queued on the service (`calib serve`), end
// to end over HTTP at the smallest budgets that show it, on the bundled push
// pair:
//  - a loop submitted over HTTP, cancelled, resumed, then killed with
//    SIGKILL mid-way and continued by a restarted server, decides as an
//    uninterrupted `calib loop` with the same options (the report's
//    decisions and every calibration's history); `calib status` and `calib
//    jobs --server` show it; its report is served, it has no one best, and
//    it is deleted with its folder (one test, the reference loop running beside
//    the server);
//  - a comparison submitted through `calib submit --kind comparison` gives
//    the runs and the report files of `calib compare-optimizers` of the same
//    spec, on the server's threads and, with --mpi-hosts, over MPI ranks;
//  - a bad loop or comparison spec gets a 400 naming the field, one reading
//    outside the data roots or running an external optimiser a 403.

#include "calib/results/store.h"
#include "jobs/job_test_support.h"
#include "service/service_test_support.h"
#include "support/loop_decisions.h"
#include "support/process_support.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <signal.h>

#include <cstdlib>
#include <fstream>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using testing::Clock;
using testing::kCalib;
using testing::kExamples;
using testing::Server;

// The smallest loop that decides something: one search of 4 evaluations for
// the base model, the best ranked hypothesis tried (--min-confidence 0) with
// 4 more, no overlays.
const json kLoopSpec = {{"name", "tiny_loop"},   {"train", {"push_centre"}},
                        {"holdout", {"push_offset"}}, {"budget", 4},
                        {"effect_budget", 4},    {"restarts", 1},
                        {"max_effects", 1},      {"tries", 1},
                        {"min_confidence", 0},   {"seed", 1},
                        {"overlays", 0}};

// The same as `calib loop` options.
std::vector<std::string> LoopArguments(const fs::path& out) {
  return {kCalib,        "loop",     "--train",  (kExamples / "push_centre").string(),
          "--holdout",   (kExamples / "push_offset").string(),
          "--out",       out.string(), "--budget", "4", "--effect-budget", "4", "--restarts", "1",
          "--max-effects", "1", "--tries", "1", "--min-confidence", "0", "--seed", "1",
          "--overlays",  "0",        "--threads", "1", "--quiet"};
}

// Two optimisers, one seed, 4 evaluations each, on a coarse model.
std::string ComparisonYaml(const std::string& name, const std::string& train) {
  return fmt::format(R"(name: {}
train: [{}]
model: {{substeps: 4, mesh: {{edge_length_px: 40}}}}
{}budget: {{evaluations: 4}}
optimizers: [{{name: random}}, {{name: cmaes, settings: {{population: 4}}}}]
seeds: 1
)",
                     name, train, testing::kBaseParametersYaml);
}

json ReadJson(const fs::path& path) {
  std::ifstream in(path);
  return json::parse(in, nullptr, false);
}

// Every job of store `actual` has the history of the job of its name in
// `expected`, and the two hold the same jobs.
void ExpectSameStores(const fs::path& expected, const fs::path& actual) {
  StoreOptions read_only;
  read_only.read_only = true;
  const ResultStore want(expected, read_only);
  const ResultStore got(actual, read_only);
  std::vector<std::string> want_names, got_names;
  for (const JobInfo& job : want.Jobs()) want_names.push_back(job.name);
  for (const JobInfo& job : got.Jobs()) got_names.push_back(job.name);
  ASSERT_EQ(got_names, want_names) << actual;
  for (const JobInfo& job : want.Jobs()) {
    testing::ExpectSameHistory(want.Evaluations(job.id), got.Evaluations(got.FindJob(job.name)->id), job.name);
  }
}

// The loop `name` of the server decides as the uninterrupted `calib loop`
// whose folder is `reference`: the report's decisions, every calibration's
// history.
void ExpectTheReferenceLoop(const Server& server, const std::string& name, const fs::path& reference) {
  const json report = server.Get(fmt::format("/api/v1/jobs/{}/artefacts/report.json", name));
  const json decisions = testing::LoopDecisions(report);
  EXPECT_GE(decisions["stages"].size(), 2u) << "an effect tried: " << decisions.dump(1);
  EXPECT_EQ(decisions, testing::LoopDecisions(ReadJson(reference / "report.json")))
      << "the loop decides as calib loop";
  ExpectSameStores(reference / "store.sqlite", server.folder(name) / "store.sqlite");
}

// The comparison "tiny" of the server, done, has the runs and the report
// files of `calib compare-optimizers` in `cli` (the same spec).
void ExpectTheReferenceComparison(const Server& server, const fs::path& cli) {
  const json done = server.WaitDone("tiny", 120);
  ASSERT_FALSE(done.is_null());
  EXPECT_EQ(done["status"], "finished") << done.dump(1);
  EXPECT_EQ(done["budget"], 8);
  EXPECT_EQ(done["evaluations"], 8);
  EXPECT_EQ(done["progress"]["runs"], 2);
  EXPECT_EQ(done["progress"]["jobs_finished"], 2);
  EXPECT_EQ(done["report"], "report.html");
  ExpectSameStores(cli / "comparison.sqlite", server.folder("tiny") / "comparison.sqlite");
  for (const char* file : {"runs.csv", "convergence.csv", "fixed_budget.csv", "fixed_target.csv", "pairwise.csv"}) {
    EXPECT_EQ(testing::ReadText(server.folder("tiny") / file), testing::ReadText(cli / file)) << file;
    httplib::Client client = server.Client();
    const httplib::Result served = client.Get(fmt::format("/api/v1/jobs/tiny/artefacts/{}", file).c_str());
    ASSERT_TRUE(served);
    EXPECT_EQ(served->body, testing::ReadText(cli / file)) << file;
  }
  const json listed = server.Get("/api/v1/jobs");
  ASSERT_EQ(listed["jobs"].size(), 1u);
  EXPECT_EQ(listed["jobs"][0]["kind"], "comparison");
}

// `calib compare-optimizers` of the tiny comparison into `dir`/cli.
fs::path CliComparison(const fs::path& dir) {
  const fs::path spec = dir / "tiny.yaml";
  std::ofstream(spec) << ComparisonYaml("tiny", (kExamples / "push_centre").string());
  const testing::ProcessResult cli = testing::RunProcess(
      {kCalib, "compare-optimizers", spec.string(), "--out", (dir / "cli").string(), "--threads", "1",
       "--progress", "none"},
      dir);
  EXPECT_EQ(cli.exit_code, 0) << cli.err;
  return dir / "cli";
}

TEST(ServiceKinds, AComparisonSubmittedThroughCalibSubmitGivesTheRunsAndReportOfCalibCompareOptimizers) {
  const fs::path dir = testing::ScratchDir("service_comparison");
  const fs::path cli = CliComparison(dir);

  Server server(dir / "state", dir / "logs");
  ASSERT_GT(server.port(), 0);
  // Through `calib submit --kind comparison --wait`, the spec's path
  // relative to the server's data root.
  std::ofstream(dir / "submitted.yaml") << ComparisonYaml("tiny", "push_centre");
  const testing::ProcessResult submitted = server.RunClient(
      {"submit", "--kind", "comparison", (dir / "submitted.yaml").string(), "--wait"}, dir / "logs");
  EXPECT_EQ(submitted.exit_code, 0) << submitted.out << submitted.err;
  EXPECT_CONTAINS(submitted.out, "submitted: comparison tiny (priority 0)");
  EXPECT_CONTAINS(submitted.out, "comparison: tiny\nstate: done\nstatus: finished");
  EXPECT_CONTAINS(submitted.out, "evaluations: 8/8");
  EXPECT_CONTAINS(submitted.out, "report: report.html");
  ExpectTheReferenceComparison(server, cli);
}

// On a server with --mpi-hosts a comparison runs through the launcher
// (calib-mpirun.sh --compare, every run over the ranks): the same runs and
// report.
TEST(ServiceKinds, AComparisonOnMpiHostsGivesTheRunsAndReportOfCalibCompareOptimizers) {
  const std::string mpiexec = CALIB_MPIEXEC;
  if (mpiexec.empty()) GTEST_SKIP() << "no MPI launcher in this build";
  ::setenv("MPIRUN", mpiexec.c_str(), 1);
  const fs::path dir = testing::ScratchDir("service_comparison_mpi");
  const fs::path cli = CliComparison(dir);
  Server server(dir / "state", dir / "logs",
                {"--mpi-hosts", "localhost:3", "--mpi-launcher",
                 (fs::path(CALIB_SOURCE_DIR) / "scripts" / "calib-mpirun.sh").string(), "--mpirun-args",
                 "--allow-run-as-root --oversubscribe --bind-to none --mca btl self,vader "
                 "--mca btl_vader_single_copy_mechanism none"});
  ASSERT_GT(server.port(), 0);
  std::ofstream(dir / "submitted.yaml") << ComparisonYaml("tiny", "push_centre");
  const testing::ProcessResult submitted = server.RunClient(
      {"submit", "--kind", "comparison", (dir / "submitted.yaml").string()}, dir / "logs");
  EXPECT_EQ(submitted.exit_code, 0) << submitted.out << submitted.err;
  ExpectTheReferenceComparison(server, cli);
  const std::string log = testing::ReadText(dir / "state" / "mpi" / "tiny.log");
  EXPECT_CONTAINS(log, "calib compare-optimizers on localhost:3 (3 ranks)");
  EXPECT_CONTAINS(log, "MPI: manager and 2 worker ranks");
}

TEST(ServiceKinds, ALoopOverHttpCancelledResumedAndKilledMidwayDecidesAsCalibLoop) {
  const fs::path dir = testing::ScratchDir("service_loop_kill");
  // The reference, `calib loop` uninterrupted, runs beside the server.
  fs::create_directories(dir / "reference_logs");
  testing::ChildProcess reference(LoopArguments(dir / "reference"), dir / "reference_logs");
  json spec = kLoopSpec;
  spec["name"] = "killed_loop";
  auto wait_evaluations = [](const Server& server, int n) {
    const auto deadline = Clock::now() + std::chrono::seconds(120);
    while (Clock::now() < deadline) {
      if (server.Get("/api/v1/jobs/killed_loop")["evaluations"].get<int>() >= n) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ADD_FAILURE() << "fewer than " << n << " evaluations after 120 s";
  };
  {
    Server server(dir / "state", dir / "logs");
    ASSERT_GT(server.port(), 0);
    EXPECT_EQ(server.Submit("loop", spec)["kind"], "loop");
    wait_evaluations(server, 1);
    httplib::Client client = server.Client();
    const httplib::Result cancel = client.Post("/api/v1/jobs/killed_loop/cancel", "", "application/json");
    ASSERT_TRUE(cancel);
    EXPECT_EQ(cancel->status, 200) << cancel->body;
    const json cancelled = server.WaitDone("killed_loop");
    EXPECT_EQ(cancelled["state"], "cancelled") << cancelled.dump(1);
    EXPECT_EQ(cancelled["status"], "stopped") << cancelled.dump(1);
    const int before = cancelled["evaluations"].get<int>();
    const httplib::Result resumed = client.Post("/api/v1/jobs/killed_loop/resume", "", "application/json");
    ASSERT_TRUE(resumed);
    EXPECT_EQ(resumed->status, 200) << resumed->body;
    wait_evaluations(server, before + 2);
    server.process().Kill(SIGKILL);
    server.process().Wait(30);
    EXPECT_FALSE(fs::exists(server.folder("killed_loop") / "report.json")) << "killed before its end";
  }
  Server server(dir / "state", dir / "logs2");
  ASSERT_GT(server.port(), 0);
  const json done = server.WaitDone("killed_loop", 300);
  ASSERT_FALSE(done.is_null());
  EXPECT_EQ(done["kind"], "loop");
  EXPECT_EQ(done["status"], "finished") << done.dump(1);
  EXPECT_EQ(done["report"], "report.json");
  EXPECT_GE(done["progress"]["jobs"].get<int>(), 2) << done.dump(1);
  EXPECT_EQ(done["progress"]["jobs_finished"], done["progress"]["jobs"]);
  const testing::ProcessResult referenced = reference.Wait(300);
  ASSERT_EQ(referenced.exit_code, 0) << referenced.err;
  ExpectTheReferenceLoop(server, "killed_loop", dir / "reference");

  std::vector<std::string> files;
  const json artefacts = server.Get("/api/v1/jobs/killed_loop/artefacts");
  for (const json& f : artefacts["files"]) files.push_back(f["path"]);
  EXPECT_NE(std::find(files.begin(), files.end(), "report.html"), files.end());
  EXPECT_EQ(std::find(files.begin(), files.end(), "store.sqlite"), files.end()) << "its store is not a file served";
  httplib::Client client = server.Client();
  const httplib::Result page = client.Get("/api/v1/jobs/killed_loop/artefacts/report.html");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_CONTAINS(page->get_header_value("Content-Type"), "text/html");
  EXPECT_CONTAINS(page->get_header_value("Content-Security-Policy"), "default-src 'none'");
  const testing::ProcessResult shown = server.RunClient({"status", "killed_loop"}, dir / "logs");
  EXPECT_EQ(shown.exit_code, 0) << shown.err;
  EXPECT_CONTAINS(shown.out, "loop: killed_loop\nstate: done\nstatus: finished");
  EXPECT_CONTAINS(shown.out, fmt::format("evaluations: {} (", done["evaluations"].get<int>()));
  EXPECT_CONTAINS(shown.out, "calibrations: ");
  EXPECT_CONTAINS(shown.out, "report: report.json");
  const testing::ProcessResult listed = server.RunClient({"jobs"}, dir / "logs");
  EXPECT_EQ(listed.exit_code, 0) << listed.err;
  EXPECT_CONTAINS(listed.out, "killed_loop");
  EXPECT_CONTAINS(listed.out, " loop ");
  const json results = server.Get("/api/v1/jobs/killed_loop/results");
  EXPECT_EQ(results["jobs"].size(), done["progress"]["jobs"].get<size_t>());
  EXPECT_EQ(results["report"]["effects_kept"], ReadJson(dir / "reference" / "report.json")["effects_kept"]);
  const httplib::Result best = client.Get("/api/v1/jobs/killed_loop/best");
  ASSERT_TRUE(best);
  EXPECT_EQ(best->status, 409) << best->body;
  const httplib::Result budget = client.Post("/api/v1/jobs/killed_loop/budget", R"({"evaluations": 9})", "application/json");
  ASSERT_TRUE(budget);
  EXPECT_EQ(budget->status, 409) << budget->body;
  const httplib::Result deleted = client.Delete("/api/v1/jobs/killed_loop");
  ASSERT_TRUE(deleted);
  EXPECT_EQ(deleted->status, 200) << deleted->body;
  EXPECT_FALSE(fs::exists(server.folder("killed_loop"))) << "its folder, store and report went with it";
}

TEST(ServiceKinds, BadLoopAndComparisonSpecsGetTheir4xxNamingTheField) {
  const fs::path dir = testing::ScratchDir("service_kinds_bad");
  Server server(dir / "state", dir / "logs", {"--no-report"});
  ASSERT_GT(server.port(), 0);
  auto expect = [&](const std::string& kind, const json& spec, int status, const std::string& message) {
    httplib::Client client = server.Client();
    const httplib::Result r = client.Post("/api/v1/jobs", json{{"kind", kind}, {"spec", spec}}.dump(),
                                          "application/json");
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, status) << r->body;
    const json body = json::parse(r->body, nullptr, false);
    EXPECT_EQ(body.value("field", ""), kind == "batch" ? "kind" : "spec") << r->body;
    EXPECT_CONTAINS(body.value("error", ""), message);
  };
  auto loop = [](const std::string& key, const json& value) {
    json spec = kLoopSpec;
    if (value.is_null()) {
      spec.erase(key);
    } else {
      spec[key] = value;
    }
    return spec;
  };
  expect("batch", kLoopSpec, 400, "kind = \"batch\": must be \"job\", \"loop\" or \"comparison\"");
  expect("loop", loop("budget", 1), 400, "submitted loop spec: budget = '1': must be in [2, 100000000]");
  expect("loop", loop("fdr", 0.9), 400, "submitted loop spec: fdr = '0.9': must be in [0.001, 0.5]");
  expect("loop", loop("integrator", "verlet"), 400, "integrator = 'verlet': must be first_order or");
  expect("loop", loop("budgt", 4), 400, "budgt = '4': unknown key");
  expect("loop", loop("train", nullptr), 400, "submitted loop spec: train: missing");
  expect("loop", loop("name", "a b"), 400, "name = 'a b': must be non-empty letters");
  expect("loop", loop("holdout", {"no_such_recording"}), 400, "holdout[0] = '");
  expect("loop", loop("train", {"../README.md"}), 403, "train[0] = '");
  expect("loop", loop("holdout", {"/etc"}), 403, "holdout[0] = '/etc': outside the server's data roots");
  expect("loop", loop("optimizer", "external"), 403, "submitted loop spec: optimizer = 'external': runs a program");
  expect("comparison", "name: c\ntrain: [push_centre]\n", 400, "submitted comparison spec: ");
  std::string zero = ComparisonYaml("c", "push_centre");
  zero.replace(zero.find("evaluations: 4"), 14, "evaluations: 0");
  expect("comparison", zero, 400, "submitted comparison spec: budget.evaluations = '0'");
  expect("comparison", ComparisonYaml("c", "../README.md"), 403, "train[0] = '");
  std::string external = ComparisonYaml("c", "push_centre");
  external.replace(external.find("{name: random}"), 14, "{name: external, command: [/bin/true]}");
  expect("comparison", external, 403,
         "submitted comparison spec: optimizers[0].name = 'external': runs a program on the server");
  EXPECT_TRUE(server.Get("/api/v1/jobs")["jobs"].empty()) << "nothing queued";
}

}  // namespace
}  // namespace calib
