// The service end to end: `calib serve` on an ephemeral loopback port, its
// REST API over HTTP and its command-line clients, on small jobs that
// calibrate the bundled centre push (40 px mesh edges, 4 substeps):
//  - jobs submitted over HTTP and through `calib submit` run to the end and
//    give the histories `calib run` gives; status, results, best and
//    artefacts answer; `calib jobs --server` and `calib status` list them;
//  - a running job cancelled (calib cancel) and resumed over HTTP ends with
//    the uninterrupted history;
//  - a report is deleted past --report-max-age, and the results stay;
//  - a server killed with SIGKILL in the middle of two running jobs and one
//    queued: restarted, every job ends with the uninterrupted history; a
//    SIGTERM stops it gracefully and the job it ran continues at the next
//    start, again to the uninterrupted history;
//  - unauthorised, oversized, malformed and path-escaping requests each get
//    their 4xx with a message naming the field, and the server answers on.

#include "calib/results/job_queue.h"
#include "calib/results/store.h"
#include "jobs/job_test_support.h"
#include "service/service_test_support.h"
#include "support/process_support.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <set>
#include <thread>

namespace calib {
namespace {

namespace fs = std::filesystem;
using testing::Clock;
using testing::History;
using testing::kCalib;
using testing::kExamples;
using testing::Prefix;
using testing::Server;

// A job on examples/push_centre (an absolute path inside the data root, so
// that the same text runs under `calib run` and the server alike).
std::string JobYaml(const std::string& name, int seed, int budget) {
  return testing::SmallPushJobYaml(name, (kExamples / "push_centre").string(), seed, budget,
                                   "results: {store: ignored.sqlite}");
}

// The reference histories, from `calib run` of the same specs: 16
// evaluations at seeds 3 and 5, run when first asked for. CMA-ES proposes
// the same candidates whatever its budget, so a job of fewer evaluations at
// the same seed gives a prefix of them.
class Service : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dir_ = new fs::path(testing::ScratchDir("service")); }
  static void TearDownTestSuite() { delete dir_; }

  // The first `evaluations` of an uninterrupted `calib run` of the job with
  // `seed` and `budget`.
  static std::vector<EvaluationRecord> Reference(int seed, size_t evaluations, int budget = 16) {
    const fs::path store = *dir_ / fmt::format("reference_{}_{}.sqlite", seed, budget);
    if (!fs::exists(store)) {
      const fs::path spec = *dir_ / fmt::format("reference_{}_{}.yaml", seed, budget);
      std::ofstream(spec) << JobYaml("reference", seed, budget);
      const testing::ProcessResult run = testing::RunProcess(
          {kCalib, "run", spec.string(), "--store", store.string(), "--no-report", "--progress", "none"},
          *dir_);
      EXPECT_EQ(run.exit_code, 0) << run.err;
    }
    return Prefix(History(store, "reference"), evaluations);
  }

  static fs::path* dir_;
};

fs::path* Service::dir_ = nullptr;

TEST_F(Service, JobsSubmittedOverHttpAndThroughTheCliGiveTheHistoriesOfCalibRun) {
  const fs::path dir = testing::ScratchDir("service_end_to_end");
  Server server(dir / "state", dir / "logs");
  ASSERT_GT(server.port(), 0);

  const nlohmann::json submitted = server.Submit(JobYaml("over_http", 3, 8));
  ASSERT_FALSE(submitted.is_discarded());
  EXPECT_EQ(submitted["name"], "over_http");
  EXPECT_EQ(submitted["state"], "queued");
  ASSERT_EQ(submitted["notices"].size(), 1u);
  EXPECT_CONTAINS(submitted["notices"][0].get<std::string>(), "results.store and results.out_dir of a submitted spec are ignored");

  const fs::path spec = dir / "over_cli.yaml";
  std::ofstream(spec) << JobYaml("over_cli", 5, 8);
  const testing::ProcessResult cli =
      server.RunClient({"submit", spec.string(), "--priority", "3", "--wait"}, dir / "logs");
  EXPECT_EQ(cli.exit_code, 0) << cli.out << cli.err;
  EXPECT_CONTAINS(cli.out, "submitted: job over_cli (priority 3)");
  EXPECT_CONTAINS(cli.out, "status: finished");
  EXPECT_CONTAINS(cli.out, "evaluations: 8/8");

  const nlohmann::json done = server.WaitDone("over_http");
  ASSERT_FALSE(done.is_null());
  EXPECT_EQ(done["status"], "finished") << done.dump();
  EXPECT_EQ(done["evaluations"], 8);
  EXPECT_EQ(done["budget"], 8);
  ASSERT_EQ(done["runs"].size(), 1u);
  EXPECT_EQ(done["runs"][0]["command"], "serve");
  EXPECT_CONTAINS(done["runs"][0]["program_version"].get<std::string>(), "calib ");

  testing::ExpectSameHistory(Reference(3, 8), History(server.store(), "over_http"), "over HTTP");
  testing::ExpectSameHistory(Reference(5, 8), History(server.store(), "over_cli"), "through calib submit");

  const nlohmann::json results = server.Get("/api/v1/jobs/over_http/results");
  ASSERT_EQ(results["evaluations"].size(), 8u);
  EXPECT_EQ(results["summary"]["evaluations"], 8);
  const nlohmann::json best = server.Get("/api/v1/jobs/over_http/best");
  const EvaluationRecord expected = *ResultStore(server.store()).Best(ResultStore(server.store()).FindJob("over_http")->id);
  EXPECT_EQ(best["evaluation"], expected.id);
  EXPECT_EQ(best["score"].get<double>(), expected.score);
  EXPECT_EQ(best["parameters"].size(), 6u) << best.dump();
  const nlohmann::json artefacts = server.Get("/api/v1/jobs/over_http/artefacts");
  std::vector<std::string> files;
  for (const auto& f : artefacts["files"]) files.push_back(f["path"]);
  EXPECT_NE(std::find(files.begin(), files.end(), "best_params.json"), files.end()) << artefacts.dump();
  EXPECT_NE(std::find(files.begin(), files.end(), "summary.txt"), files.end()) << artefacts.dump();
  const nlohmann::json params = server.Get("/api/v1/jobs/over_http/artefacts/best_params.json");
  EXPECT_EQ(params, best["parameters"]) << "the report's parameter file is the best's";
  {
    httplib::Client client = server.Client();
    const httplib::Result openapi = client.Get("/api/v1/openapi.yaml");
    ASSERT_TRUE(openapi);
    EXPECT_EQ(openapi->status, 200);
    EXPECT_CONTAINS(openapi->body, "/api/v1/jobs/{name}/budget:");
  }

  const testing::ProcessResult listed = server.RunClient({"jobs"}, dir / "logs");
  EXPECT_EQ(listed.exit_code, 0) << listed.err;
  EXPECT_CONTAINS(listed.out, "over_http");
  EXPECT_CONTAINS(listed.out, "over_cli");
  EXPECT_CONTAINS(listed.out, "8/8");
  const testing::ProcessResult from_store = testing::RunProcess(
      {kCalib, "jobs", "--store", server.store().string()}, dir / "logs");
  EXPECT_EQ(from_store.exit_code, 0) << from_store.err;
  EXPECT_CONTAINS(from_store.out, "over_cli");
  const testing::ProcessResult shown = server.RunClient({"status", "over_cli"}, dir / "logs");
  EXPECT_EQ(shown.exit_code, 0) << shown.err;
  EXPECT_CONTAINS(shown.out, "status: finished");

  // Extend the finished job over HTTP: the history of 16 evaluations.
  {
    httplib::Client client = server.Client();
    const httplib::Result r = client.Post("/api/v1/jobs/over_http/budget",
                                          R"({"evaluations": 16})", "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << r->body;
  }
  EXPECT_EQ(server.WaitDone("over_http")["evaluations"], 16);
  testing::ExpectSameHistory(Reference(3, 16), History(server.store(), "over_http"), "extended over HTTP");

  server.process().Kill(SIGTERM);
  const testing::ProcessResult stopped = server.process().Wait(60);
  EXPECT_EQ(stopped.exit_code, 0) << stopped.err;
  EXPECT_CONTAINS(stopped.out, "token: ") << "a token made on the first start is printed";
}

TEST_F(Service, KilledMidJobsAndRestartedEveryJobEndsWithTheUninterruptedHistory) {
  const fs::path dir = testing::ScratchDir("service_sigkill");
  {
    Server server(dir / "state", dir / "logs", {"--no-report"});
    ASSERT_GT(server.port(), 0);
    server.Submit(JobYaml("kill_a", 3, 16), 2);
    server.Submit(JobYaml("kill_b", 5, 16), 1);
    server.Submit(JobYaml("kill_c", 5, 8), 0);  // queued behind the two
    server.WaitEvaluations("kill_a", 5);
    server.WaitEvaluations("kill_b", 5);
    server.process().Kill(SIGKILL);
    server.process().Wait(30);
    EXPECT_LT(History(server.store(), "kill_a").size(), 16u) << "killed mid-job";
  }
  {
    Server server(dir / "state", dir / "logs2", {"--no-report"});
    ASSERT_GT(server.port(), 0);
    for (const char* name : {"kill_a", "kill_b", "kill_c"}) {
      EXPECT_EQ(server.WaitDone(name)["status"], "finished") << name;
    }
    testing::ExpectSameHistory(Reference(3, 16), History(server.store(), "kill_a"), "kill_a");
    testing::ExpectSameHistory(Reference(5, 16), History(server.store(), "kill_b"), "kill_b");
    testing::ExpectSameHistory(Reference(5, 8), History(server.store(), "kill_c"), "kill_c");

    // SIGTERM while a job runs: a graceful stop, the job left queued.
    server.Submit(JobYaml("term", 3, 16));
    server.WaitEvaluations("term", 5);
    server.process().Kill(SIGTERM);
    const testing::ProcessResult stopped = server.process().Wait(60);
    EXPECT_EQ(stopped.exit_code, 0) << stopped.err;
    EXPECT_EQ(stopped.out.find("token: "), std::string::npos) << "the token is printed once";
  }
  EXPECT_EQ(JobQueue(dir / "state" / "service.sqlite").Find("term")->state, QueueState::kQueued);
  Server server(dir / "state", dir / "logs3", {"--no-report"});
  EXPECT_EQ(server.WaitDone("term")["status"], "finished");
  testing::ExpectSameHistory(Reference(3, 16), History(server.store(), "term"), "term");
}

TEST_F(Service, ARunningJobCancelledThroughCalibCancelAndResumedEndsWithTheUninterruptedHistory) {
  const fs::path dir = testing::ScratchDir("service_cancel");
  Server server(dir / "state", dir / "logs", {"--no-report"});
  ASSERT_GT(server.port(), 0);
  // A budget far beyond the 5 evaluations after which the job is cancelled,
  // so that the cancel lands while it runs however slow `calib cancel` is
  // to start.
  constexpr int kBudget = 96;
  server.Submit(JobYaml("cancelled", 3, kBudget));
  server.WaitEvaluations("cancelled", 5);
  const testing::ProcessResult cancel = server.RunClient({"cancel", "cancelled"}, dir / "logs");
  EXPECT_EQ(cancel.exit_code, 0) << cancel.err;
  EXPECT_CONTAINS(cancel.out, "state: cancelling");
  const nlohmann::json stopped = server.WaitDone("cancelled");
  EXPECT_EQ(stopped["state"], "cancelled") << stopped.dump();
  EXPECT_EQ(stopped["status"], "stopped");
  EXPECT_LT(stopped["evaluations"].get<int>(), kBudget) << "stopped before its end";

  httplib::Client client = server.Client();
  const httplib::Result resumed = client.Post("/api/v1/jobs/cancelled/resume", "", "application/json");
  ASSERT_TRUE(resumed);
  EXPECT_EQ(resumed->status, 200) << resumed->body;
  const nlohmann::json done = server.WaitDone("cancelled");
  EXPECT_EQ(done["status"], "finished") << done.dump();
  EXPECT_EQ(done["runs"].size(), 2u) << "the run and the resume";
  testing::ExpectSameHistory(Reference(3, kBudget, kBudget), History(server.store(), "cancelled"),
                             "cancelled and resumed");
  const httplib::Result again = client.Post("/api/v1/jobs/cancelled/resume", "", "application/json");
  ASSERT_TRUE(again);
  EXPECT_EQ(again->status, 200) << "a finished job may be queued again: nothing to do";
  EXPECT_EQ(server.WaitDone("cancelled")["evaluations"], kBudget);
}

// --mpi-hosts: a job run by scripts/calib-mpirun.sh on three MPI ranks of
// this machine (the manager and two workers), cancelled and resumed, then
// its server killed with SIGKILL and restarted, ends with the history of
// `calib run` on threads.
TEST_F(Service, AJobOnMpiHostsCancelledResumedAndKilledEndsWithTheHistoryOfCalibRun) {
  const std::string mpiexec = CALIB_MPIEXEC;
  if (mpiexec.empty()) GTEST_SKIP() << "no MPI launcher in this build";
  ::setenv("MPIRUN", mpiexec.c_str(), 1);
  const fs::path dir = testing::ScratchDir("service_mpi");
  const std::vector<std::string> mpi = {
      "--no-report", "--mpi-hosts", "localhost:3", "--mpi-launcher",
      (fs::path(CALIB_SOURCE_DIR) / "scripts" / "calib-mpirun.sh").string(), "--mpirun-args",
      "--allow-run-as-root --oversubscribe --bind-to none --mca btl self,vader "
      "--mca btl_vader_single_copy_mechanism none"};
  const fs::path log = dir / "state" / "mpi" / "on_mpi.log";
  fs::create_directories(dir / "logs");
  for (const char* bad : {"localhost:1", "localhost:0,b:2", "a:2,,b", ":3"}) {
    const testing::ProcessResult refused = testing::RunProcess(
        {kCalib, "serve", "--data-root", kExamples.string(), "--state-dir", (dir / "bad").string(),
         "--port", "0", "--mpi-hosts", bad, "--mpi-launcher", "/bin/true"},
        dir / "logs");
    EXPECT_EQ(refused.exit_code, 2) << bad << ": " << refused.err;
    EXPECT_CONTAINS(refused.err, fmt::format("ServiceOptions::mpi_hosts = '{}'", bad));
  }
  // A budget the ranks need seconds for (they evaluate about 50 a second
  // here), so that the cancel and the kill land while it runs.
  constexpr int kBudget = 160;
  {
    Server server(dir / "state", dir / "logs", mpi);
    ASSERT_GT(server.port(), 0);
    server.Submit(JobYaml("on_mpi", 3, kBudget));
    // Cancelled: SIGTERM to the launcher, the manager stops at a checkpoint.
    server.WaitEvaluations("on_mpi", 5);
    EXPECT_CONTAINS(server.RunClient({"cancel", "on_mpi"}, dir / "logs").out, "state: cancelling");
    const nlohmann::json cancelled = server.WaitDone("on_mpi");
    EXPECT_EQ(cancelled["state"], "cancelled") << cancelled.dump(1);
    EXPECT_EQ(cancelled["status"], "stopped") << testing::ReadText(log);
    const int before = cancelled["evaluations"].get<int>();
    EXPECT_LT(before, kBudget) << "stopped before its end";
    // Resumed (the launcher's calib resume), then the server killed: the
    // kernel sends the launcher SIGTERM.
    httplib::Client client = server.Client();
    const httplib::Result resumed = client.Post("/api/v1/jobs/on_mpi/resume", "", "application/json");
    ASSERT_TRUE(resumed);
    EXPECT_EQ(resumed->status, 200) << resumed->body;
    server.WaitEvaluations("on_mpi", before + 5);
    server.process().Kill(SIGKILL);
    server.process().Wait(30);
  }
  // The launcher heard of its server's death (it may still have let the
  // manager finish the job meanwhile).
  auto interruptions = [&log] {
    const std::string text = testing::ReadText(log);
    size_t n = 0;
    for (size_t at = text.find("calib-mpirun: interrupted"); at != std::string::npos;
         at = text.find("calib-mpirun: interrupted", at + 1)) {
      ++n;
    }
    return n;
  };
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  while (interruptions() < 2 && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(interruptions(), 2u) << "the cancel and the server's death: " << testing::ReadText(log);
  Server server(dir / "state", dir / "logs2", mpi);
  ASSERT_GT(server.port(), 0);
  const nlohmann::json done = server.WaitDone("on_mpi");
  EXPECT_EQ(done["status"], "finished") << done.dump(1) << testing::ReadText(log);
  const std::vector<EvaluationRecord> history = History(server.store(), "on_mpi");
  testing::ExpectSameHistory(Reference(3, kBudget, kBudget), history,
                             "on three MPI ranks, cancelled, resumed and killed");
  std::set<std::string> workers;
  for (const EvaluationRecord& e : history) workers.insert(e.worker);
  EXPECT_EQ(workers, (std::set<std::string>{"rank 1", "rank 2"})) << "evaluated by the worker ranks";
}

TEST_F(Service, AReportIsDeletedPastItsAgeLimitAndTheResultsStay) {
  const fs::path dir = testing::ScratchDir("service_report_age");
  Server server(dir / "state", dir / "logs", {"--report-max-age", "4"});
  ASSERT_GT(server.port(), 0);
  server.Submit(JobYaml("aged", 3, 4));
  EXPECT_EQ(server.WaitDone("aged")["status"], "finished");
  EXPECT_FALSE(server.Get("/api/v1/jobs/aged/artefacts")["files"].empty()) << "the report, at first";
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  while (!server.Get("/api/v1/jobs/aged/artefacts")["files"].empty() && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  EXPECT_TRUE(server.Get("/api/v1/jobs/aged/artefacts")["files"].empty()) << "deleted past 4 s";
  EXPECT_FALSE(fs::exists(dir / "state" / "jobs" / "aged"));
  EXPECT_EQ(server.Get("/api/v1/jobs/aged/results")["evaluations"].size(), 4u) << "the results stay";
  EXPECT_EQ(server.Get("/api/v1/jobs/aged/best")["parameters"].size(), 6u);
}

TEST_F(Service, BadRequestsGetTheir4xxNamingTheFieldAndTheServerAnswersOn) {
  const fs::path dir = testing::ScratchDir("service_bad");
  fs::create_directories(dir / "root");
  fs::create_directories(dir / "outside");
  fs::copy(kExamples / "push_centre", dir / "outside" / "push_centre", fs::copy_options::recursive);
  fs::create_directory_symlink(dir / "outside", dir / "root" / "out_link");  // a link out of the roots
  Server server(dir / "state", dir / "logs", {"--data-root", (dir / "root").string(), "--max-body", "4096", "--no-report"});
  ASSERT_GT(server.port(), 0);
  struct stat st {};
  ASSERT_EQ(::stat((dir / "state" / "token").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u) << "the token file is its owner's only";

  auto expect = [&](const httplib::Result& r, int status, const std::string& field,
                    const std::string& message) {
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, status) << r->body;
    const nlohmann::json body = nlohmann::json::parse(r->body, nullptr, false);
    ASSERT_FALSE(body.is_discarded()) << "a JSON body: " << r->body;
    if (!field.empty()) {
      EXPECT_EQ(body.value("field", ""), field) << r->body;
    }
    EXPECT_CONTAINS(body.value("error", ""), message);
  };
  auto post = [&](const std::string& body) {
    return server.Client().Post("/api/v1/jobs", body, "application/json");
  };

  expect(server.Client("").Get("/api/v1/jobs"), 401, "Authorization", "no token");
  expect(server.Client("not-the-token").Get("/api/v1/jobs"), 401, "Authorization", "wrong token");
  expect(server.Client("").Post("/api/v1/jobs", "{}", "application/json"), 401, "", "token");
  // The dashboard: its page without the token; the sign-in sets the token
  // as an HttpOnly, SameSite=Strict cookie that then stands for it.
  {
    httplib::Client anonymous = server.Client("");
    const httplib::Result page = anonymous.Get("/");
    ASSERT_TRUE(page);
    EXPECT_EQ(page->status, 200);
    EXPECT_CONTAINS(page->body, "<script src=\"/dashboard/chart.umd.js\">");
    const httplib::Result chart = anonymous.Get("/dashboard/chart.umd.js");
    ASSERT_TRUE(chart);
    EXPECT_CONTAINS(chart->body, "Chart.js");
    expect(anonymous.Post("/api/v1/session", R"({"token": "nope"})", "application/json"), 401, "token",
           "wrong token");
    const httplib::Result session = anonymous.Post(
        "/api/v1/session", nlohmann::json{{"token", server.token()}}.dump(), "application/json");
    ASSERT_TRUE(session);
    EXPECT_EQ(session->status, 200) << session->body;
    EXPECT_EQ(session->get_header_value("Set-Cookie"),
              "calib_token=" + server.token() + "; HttpOnly; SameSite=Strict; Path=/");
    const httplib::Headers with_cookie = {{"Cookie", "other=1; calib_token=" + server.token()}};
    const httplib::Result listed = anonymous.Get("/api/v1/jobs", with_cookie);
    ASSERT_TRUE(listed);
    EXPECT_EQ(listed->status, 200) << "the cookie stands for the token";
    expect(anonymous.Get("/api/v1/jobs", {{"Cookie", "calib_token=wrong"}}), 401, "Authorization", "no token");
  }
  expect(post(std::string(10000, ' ')), 413, "body", "larger than the server accepts");
  expect(post("{\"spec\": "), 400, "body", "the body is not JSON");
  expect(post("[1, 2]"), 400, "", "must be a JSON object");
  expect(post(R"({"spec": {}, "colour": 1})"), 400, "colour", "unknown field");
  expect(post(R"({"spec": 12})"), 400, "spec", "spec: must be a job spec");
  expect(post(nlohmann::json{{"spec", JobYaml("j", 3, 8)}, {"priority", "high"}}.dump()), 400, "priority",
         "priority = \"high\": must be an integer");
  std::string bad_budget = JobYaml("j", 3, 8);
  bad_budget.replace(bad_budget.find("evaluations: 8"), 14, "evaluations: 0");
  expect(post(nlohmann::json{{"spec", bad_budget}}.dump()), 400, "spec",
         "submitted spec: budget.evaluations = '0': must be >= 1");
  auto with_train = [&](const std::string& path) {
    std::string yaml = JobYaml("j", 3, 8);
    const std::string train = (kExamples / "push_centre").string();
    yaml.replace(yaml.find(train), train.size(), path);
    return nlohmann::json{{"spec", yaml}}.dump();
  };
  expect(post(with_train("../README.md")), 403, "spec", "train[0] = '");
  expect(post(with_train("push_centre/../../../etc")), 403, "spec", "outside the server's data roots");
  expect(post(with_train("/etc")), 403, "spec", "train[0] = '/etc': outside the server's data roots");
  expect(post(with_train((dir / "root" / "out_link" / "push_centre").string())), 403, "spec",
         "outside the server's data roots");
  expect(post(with_train("no_such_recording")), 400, "spec", "train[0]");  // inside, but absent
  // An external optimiser would run any program on the server.
  std::string external = JobYaml("j", 3, 8);
  const std::string cmaes = "{name: cmaes, settings: {population: 4, initial_sigma: 0.3}}";
  ASSERT_NE(external.find(cmaes), std::string::npos);
  external.replace(external.find(cmaes), cmaes.size(), "{name: external, command: [/bin/true]}");
  expect(post(nlohmann::json{{"spec", external}}.dump()), 403, "spec",
         "submitted spec: optimizer.name = 'external': runs a program on the server");
  expect(server.Client().Get("/api/v1/jobs/nosuchjob"), 404, "name", "no job 'nosuchjob'");
  expect(server.Client().Get("/api/v1/nothing"), 404, "", "no such resource");
  expect(server.Client().Post("/api/v1/jobs/nosuchjob/budget", "{}", "application/json"), 404, "name",
         "no job 'nosuchjob'");

  // A job on a recording in the second root; its artefact paths may not
  // leave its folder.
  fs::create_directories(dir / "root" / "recs");
  fs::copy(kExamples / "push_centre", dir / "root" / "recs" / "push_centre", fs::copy_options::recursive);
  std::string held_yaml = JobYaml("held", 3, 8);
  const std::string train = (kExamples / "push_centre").string();
  held_yaml.replace(held_yaml.find(train), train.size(), (dir / "root" / "recs" / "push_centre").string());
  const nlohmann::json held = server.Submit(held_yaml);
  ASSERT_EQ(held["name"], "held");
  expect(post(nlohmann::json{{"spec", JobYaml("held", 3, 8)}}.dump()), 409, "spec",
         "name = 'held': a job of that name is on this server");
  expect(server.Client().Get("/api/v1/jobs/held/artefacts/..%2F..%2Fservice.sqlite"), 400, "path",
         "'..' is not allowed");
  expect(server.Client().Get("/api/v1/jobs/held/artefacts/absent.txt"), 404, "path", "no such file");
  EXPECT_EQ(server.Get("/api/v1/health")["status"], "ok") << "still answering";
  server.WaitDone("held");
  expect(server.Client().Post("/api/v1/jobs/held/cancel", "", "application/json"), 409, "name",
         "nothing to cancel");
  {
    httplib::Client client = server.Client();
    const httplib::Result deleted = client.Delete("/api/v1/jobs/held");
    ASSERT_TRUE(deleted);
    EXPECT_EQ(deleted->status, 200) << deleted->body;
  }
  expect(server.Client().Get("/api/v1/jobs/held"), 404, "name", "no job 'held'");
  EXPECT_TRUE(History(server.store(), "held").empty()) << "its evaluations went with it";
}

}  // namespace
}  // namespace calib
