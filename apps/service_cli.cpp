#include "service_cli.h"

#include "calib/results/store.h"
#include "calib/service/client.h"
#include "calib/service/http_api.h"
#include "calib/service/job_service.h"
#include "calib/service/token.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <csignal>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <thread>

#include <pthread.h>

namespace calib::cli {

namespace fs = std::filesystem;

struct ServiceCli {
  CLI::App* serve = nullptr;
  CLI::App* submit = nullptr;
  CLI::App* status = nullptr;
  CLI::App* cancel = nullptr;
  CLI::App* jobs = nullptr;

  service::ServiceOptions service;
  service::HttpOptions http;
  fs::path port_file;
  bool no_report = false;
  bool no_video = false;

  std::string server = "http://127.0.0.1:8080";
  fs::path token_file;
  fs::path spec;
  std::string kind = "job";
  std::string name;
  int64_t priority = 0;
  bool wait = false;
  fs::path store;
};

namespace {

constexpr const char* kDefaultStateDir = "out/service";

void AddClientOptions(CLI::App* cmd, ServiceCli* cli) {
  cmd->add_option("--server", cli->server, "the server's address")->capture_default_str();
  cmd->add_option("--token-file", cli->token_file,
                  "file holding the server's token (default: $CALIB_TOKEN, else "
                  "out/service/token)");
}

service::ServiceClient Client(const ServiceCli& cli) {
  std::string token;
  if (!cli.token_file.empty()) {
    token = service::ReadToken(cli.token_file);
  } else if (const char* env = std::getenv("CALIB_TOKEN"); env != nullptr && *env != '\0') {
    token = env;
  } else {
    token = service::ReadToken(fs::path(kDefaultStateDir) / "token");
  }
  return service::ServiceClient(cli.server, token);
}

std::string Best(const nlohmann::json& best) {
  if (best.is_null()) return "-";
  return fmt::format("{} (#{})", best["score"].dump(), best["id"].dump());
}

// "E/BUDGET"; a loop's evaluations alone (its calibrations are decided as
// it goes: no budget).
std::string Evaluations(const nlohmann::json& job) {
  if (job.value("kind", "job") == "loop") return job["evaluations"].dump();
  return fmt::format("{}/{}", job["evaluations"].dump(), job["budget"].dump());
}

void PrintStatus(const nlohmann::json& job) {
  fmt::print("{}: {}\nstate: {}\nstatus: {}{}\nevaluations: {} ({} failed)\nbest: {}\n",
             job.value("kind", "job"), job["name"].get<std::string>(), job["state"].get<std::string>(),
             job["status"].get<std::string>(),
             job["stop_reason"].get<std::string>().empty()
                 ? ""
                 : " (" + job["stop_reason"].get<std::string>() + ")",
             Evaluations(job), job["failed"].dump(), Best(job["best"]));
  if (job.contains("progress")) {
    fmt::print("calibrations: {} finished of {}\n", job["progress"]["jobs_finished"].dump(),
               job["progress"]["jobs"].dump());
  }
  if (job.contains("report") && !job["report"].is_null()) {
    fmt::print("report: {}\n", job["report"].get<std::string>());
  }
  if (!job["message"].get<std::string>().empty()) {
    fmt::print("message: {}\n", job["message"].get<std::string>());
  }
}

// Blocks the stop signals in this thread (and every thread it starts); a
// thread of its own waits for one and stops the server.
// The launcher of --mpi-hosts when none is named: beside calib (an
// installation), else in the source tree calib was built from
// (build/apps/calib).
fs::path DefaultMpiLauncher(const fs::path& calib) {
  for (const fs::path& candidate : {calib.parent_path() / "calib-mpirun.sh",
                                    calib.parent_path() / ".." / ".." / "scripts" / "calib-mpirun.sh"}) {
    if (fs::is_regular_file(candidate)) return candidate.lexically_normal();
  }
  throw std::invalid_argument(fmt::format(
      "--mpi-hosts: no calib-mpirun.sh beside {} or in its source tree; name it with --mpi-launcher",
      calib.string()));
}

int Serve(ServiceCli& cli) {
  cli.service.calib_executable = fs::read_symlink("/proc/self/exe");
  if (!cli.service.mpi_hosts.empty() && cli.service.mpi_launcher.empty()) {
    cli.service.mpi_launcher = DefaultMpiLauncher(cli.service.calib_executable);
  }
  cli.service.write_report = !cli.no_report;
  cli.service.report_video = !cli.no_video;
  cli.service.program_version = std::string("calib ") + CALIB_VERSION;
  const service::Token token = service::LoadOrCreateToken(cli.service.state_dir / "token");
  cli.http.token = token.value;

  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  service::JobService jobs(cli.service);
  service::HttpApi api(jobs, cli.http);
  const int port = api.Bind();
  if (token.created) {
    fmt::print("token: {}\n  (made now and kept in {}, mode 0600; clients read it from there; "
               "it is not shown again)\n",
               token.value, (cli.service.state_dir / "token").string());
  }
  fmt::print("calib serve: listening on http://{}:{}\nstore: {}\nreports: {}\n", cli.http.listen,
             port, cli.service.store().string(), cli.service.reports().string());
  std::fflush(stdout);
  if (!cli.port_file.empty()) {
    const fs::path temp = cli.port_file.string() + ".tmp";
    std::ofstream(temp) << port << "\n";
    fs::rename(temp, cli.port_file);
  }
  std::thread waiter([&] {
    int signal = 0;
    sigwait(&stop_signals, &signal);
    spdlog::info("signal {}: stopping; running jobs stop at a checkpoint and continue at the "
                 "next start",
                 signal);
    api.Stop();
  });
  api.Serve();
  jobs.Stop();
  waiter.join();
  return 0;
}

int Submit(ServiceCli& cli) {
  std::ifstream in(cli.spec);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open {} spec", cli.spec.string(), cli.kind));
  std::stringstream text;
  text << in.rdbuf();
  service::ServiceClient client = Client(cli);
  const nlohmann::json answer =
      client.Post("/api/v1/jobs", {{"kind", cli.kind}, {"spec", text.str()}, {"priority", cli.priority}});
  for (const auto& notice : answer["notices"]) spdlog::warn("{}", notice.get<std::string>());
  const std::string name = answer["name"].get<std::string>();
  fmt::print("submitted: {} {} (priority {})\n", cli.kind, name, cli.priority);
  if (!cli.wait) return 0;
  while (true) {
    const nlohmann::json job = client.Get("/api/v1/jobs/" + name);
    const std::string state = job["state"].get<std::string>();
    if (state != "queued" && state != "running") {
      PrintStatus(job);
      return job["status"] == "finished" ? 0 : 1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

int Jobs(ServiceCli& cli) {
  if (!cli.store.empty() || cli.jobs->count("--server") == 0) {
    const fs::path path = cli.store.empty() ? fs::path(kDefaultStateDir) / "service.sqlite" : cli.store;
    StoreOptions read_only;
    read_only.read_only = true;
    if (!fs::is_regular_file(path)) {
      throw StoreError(fmt::format("{}: no results store there", path.string()));
    }
    ResultStore store(path, read_only);
    fmt::print("{:<24} {:<10} {:>11}  {}\n", "name", "status", "evaluations", "best");
    for (const JobInfo& job : store.Jobs()) {
      const JobSummary summary = store.Summary(job.id);
      fmt::print("{:<24} {:<10} {:>11}  {}\n", job.name, ToString(job.status), summary.evaluations,
                 summary.best ? fmt::format("{} (#{})", summary.best->score, summary.best->id) : "-");
    }
    return 0;
  }
  const nlohmann::json answer = Client(cli).Get("/api/v1/jobs");
  fmt::print("{:<24} {:<10} {:<10} {:<10} {:>11}  {}\n", "name", "kind", "state", "status",
             "evaluations", "best");
  for (const auto& job : answer["jobs"]) {
    fmt::print("{:<24} {:<10} {:<10} {:<10} {:>11}  {}\n", job["name"].get<std::string>(),
               job.value("kind", "job"), job["state"].get<std::string>(), job["status"].get<std::string>(),
               Evaluations(job), Best(job["best"]));
  }
  return 0;
}

}  // namespace

std::shared_ptr<ServiceCli> AddServiceSubcommands(CLI::App& app) {
  auto cli = std::make_shared<ServiceCli>();
  cli->service.state_dir = kDefaultStateDir;

  cli->serve = app.add_subcommand(
      "serve", "run the calibration service: a job queue in a results store behind a REST API "
               "(docs/service.md)");
  auto* serve = cli->serve;
  serve->add_option("--data-root", cli->service.data_roots,
                    "folder recordings may be read from (repeatable); submitted specs' paths "
                    "are relative to the first")
      ->required();
  serve->add_option("--state-dir", cli->service.state_dir,
                    "the store (service.sqlite), the reports (jobs/NAME/) and the token")
      ->capture_default_str();
  serve->add_option("--listen", cli->http.listen,
                    "address to listen on (the loopback address unless told otherwise)")
      ->capture_default_str();
  serve->add_option("--port", cli->http.port, "port, 0: any free one")
      ->check(CLI::Range(0, 65535))
      ->capture_default_str();
  serve->add_option("--port-file", cli->port_file, "write the port listened on to this file");
  serve->add_option("--jobs", cli->service.concurrent_jobs, "jobs run at a time")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  serve->add_option("--threads-per-job", cli->service.threads_per_job,
                    "OpenMP threads of each job, 0: all cores")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  serve->add_option("--max-body", cli->http.max_body_bytes, "largest request body, bytes")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  serve->add_option("--report-max-age", cli->service.report_max_age_s,
                    "seconds a finished or cancelled job's report is kept after the job last "
                    "changed (its results stay in the store); 0: until the job is deleted")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  serve->add_flag("--no-report", cli->no_report,
                  "write no report (best parameters, overlays, summary) when a job stops");
  serve->add_flag("--no-video", cli->no_video, "write job reports without overlay videos");
  serve->add_option("--mpi-hosts", cli->service.mpi_hosts,
                    "run calibration jobs as MPI ranks on these hosts, H1:SLOTS,H2:SLOTS (rank 0 "
                    "on the first; scripts/calib-mpirun.sh); the state folder, the data roots and "
                    "calib at the same paths on every host");
  serve->add_option("--mpi-launcher", cli->service.mpi_launcher,
                    "the launcher of --mpi-hosts (default: calib-mpirun.sh beside calib, else "
                    "scripts/calib-mpirun.sh of its source tree)");
  serve->add_option("--mpirun-args", cli->service.mpirun_args,
                    "extra mpirun arguments for --mpi-hosts (the launcher's --mpirun-args)");

  cli->submit = app.add_subcommand("submit", "submit a job, loop or comparison spec to a server");
  cli->submit->add_option("spec", cli->spec,
                          "spec file; its paths are relative to the server's data root")
      ->required();
  cli->submit->add_option("--kind", cli->kind,
                          "job (a job spec, docs/job_spec.md), loop (calib loop's options, "
                          "docs/service.md) or comparison (docs/compare.md)")
      ->check(CLI::IsMember({"job", "loop", "comparison"}))
      ->capture_default_str();
  cli->submit->add_option("--priority", cli->priority, "higher runs first")->capture_default_str();
  cli->submit->add_flag("--wait", cli->wait, "follow the job to its end (exit 0: finished)");
  AddClientOptions(cli->submit, cli.get());

  cli->status = app.add_subcommand("status", "a server's job: state, progress, best");
  cli->status->add_option("name", cli->name, "job name")->required();
  AddClientOptions(cli->status, cli.get());

  cli->cancel = app.add_subcommand("cancel", "cancel a server's job (a running one stops resumably)");
  cli->cancel->add_option("name", cli->name, "job name")->required();
  AddClientOptions(cli->cancel, cli.get());

  cli->jobs = app.add_subcommand("jobs", "list the jobs of a store, or of a server with --server");
  cli->jobs->add_option("--store", cli->store, "results store (default: out/service/service.sqlite)");
  AddClientOptions(cli->jobs, cli.get());
  return cli;
}

std::optional<int> RunChosenServiceSubcommand(ServiceCli& cli) {
  if (*cli.serve) return Serve(cli);
  if (*cli.submit) return Submit(cli);
  if (*cli.status) {
    PrintStatus(Client(cli).Get("/api/v1/jobs/" + cli.name));
    return 0;
  }
  if (*cli.cancel) {
    PrintStatus(Client(cli).Post("/api/v1/jobs/" + cli.name + "/cancel", nlohmann::json::object()));
    return 0;
  }
  if (*cli.jobs) return Jobs(cli);
  return std::nullopt;
}

}  // namespace calib::cli
