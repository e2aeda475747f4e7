#include "job_cli.h"

#include "calib/jobs/job_commands.h"
#include "calib/jobs/mpi_evaluator.h"
#include "calib/results/convergence_plot.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <string>

namespace calib::cli {

struct JobCli {
  CLI::App* run = nullptr;
  CLI::App* resume = nullptr;
  CLI::App* results = nullptr;
  CLI::App* best = nullptr;
  CLI::App* validate = nullptr;

  std::filesystem::path spec_path;
  std::string job;
  std::string store;
  std::string progress = "auto";
  double progress_interval_s = 10.0;
  std::string cache_dir;
  bool no_cache = false;
  bool no_report = false;
  bool no_video = false;
  std::optional<int> threads;
  double wall_time_s = 0.0;
  std::filesystem::path out;
  std::filesystem::path csv;
  std::filesystem::path json;
  std::filesystem::path plot;
  bool fresh = false;
  std::optional<std::string> name;
  std::optional<uint64_t> seed;
  std::optional<int64_t> budget;
};

void AddProgressAndCacheOptions(CLI::App* cmd, std::string* progress, double* progress_interval_s,
                                std::string* cache_dir, bool* no_cache) {
  cmd->add_option("--progress", *progress,
                  "auto (a bar on a terminal, log lines otherwise), bar, log or none")
      ->check(CLI::IsMember({"auto", "bar", "log", "none"}))
      ->capture_default_str();
  cmd->add_option("--progress-interval", *progress_interval_s,
                  "seconds between progress lines when they are logged (not a terminal)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--cache-dir", *cache_dir, "segmentation cache folder");
  cmd->add_flag("--no-cache", *no_cache, "do not read or write the segmentation cache");
}

namespace {

void AddOverrideOptions(CLI::App* cmd, JobCli* cli) {
  cmd->add_option("--name", cli->name,
                  "the job's name, in place of the spec's `name` (its default store and report "
                  "folder follow it)");
}

JobSpecOverrides Overrides(const JobCli& cli) {
  JobSpecOverrides overrides;
  overrides.name = cli.name;
  overrides.seed = cli.seed;
  overrides.budget_evaluations = cli.budget;
  return overrides;
}

// The command that continues a stopped job: the same spec, name, seed,
// budget and store.
std::string ResumeCommand(const JobCli& cli) {
  std::string command = "calib resume " + cli.spec_path.string();
  if (cli.name) command += " --name " + *cli.name;
  if (cli.seed) command += fmt::format(" --seed {}", *cli.seed);
  if (cli.budget) command += fmt::format(" --budget {}", *cli.budget);
  if (!cli.store.empty()) command += " --store " + cli.store;
  return command;
}

void AddRunOptions(CLI::App* cmd, JobCli* cli) {
  cmd->add_option("job", cli->spec_path, "job spec file (YAML or JSON; docs/job_spec.md)")
      ->required();
  cmd->add_option("--threads", cli->threads,
                  "OpenMP threads, 0: all cores (default: the spec's `threads`)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--store", cli->store, "results store (default: the spec's results.store)");
  cmd->add_option("--wall-time", cli->wall_time_s,
                  "stop (resumably) after this many seconds (default: the spec's budget.wall_time_s)")
      ->check(CLI::PositiveNumber);
  AddProgressAndCacheOptions(cmd, &cli->progress, &cli->progress_interval_s, &cli->cache_dir,
                             &cli->no_cache);
  cmd->add_flag("--no-report", cli->no_report,
                "do not write the report (best parameters, overlays, summary) at the end");
  cmd->add_flag("--no-video", cli->no_video, "write the report without overlay videos");
  AddOverrideOptions(cmd, cli);
  cmd->add_option("--seed", cli->seed, "the job's seed, in place of the spec's `seed`");
  cmd->add_option("--budget", cli->budget,
                  "evaluations, in place of the spec's budget.evaluations; on resume a larger "
                  "one extends the job, finished or not (docs/job_spec.md)");
}

void AddJobArgument(CLI::App* cmd, JobCli* cli) {
  cmd->add_option("job", cli->job, "job spec file, or a job name with --store")->required();
  cmd->add_option("--store", cli->store, "results store (default: the spec's results.store)");
  AddOverrideOptions(cmd, cli);
}

std::optional<std::filesystem::path> OptionalPath(const std::string& text) {
  if (text.empty()) return std::nullopt;
  return std::filesystem::path(text);
}

void PrintRun(const JobCommandResult& result) {
  if (result.run.status == JobStatus::kCreated) {
    fmt::print("nothing to do: {}\n", result.run.stop_reason);
  } else {
    fmt::print("{}", result.run.BriefReport());
  }
  fmt::print("store: {}\n", result.store.string());
  if (result.report) fmt::print("{}", result.report->Report());
}

int RunOrResume(JobCli& cli, JobStart start, int argc, char** argv) {
  // MPI is initialised only under an MPI launcher, so a plain `calib run`
  // never needs an MPI runtime.
  std::unique_ptr<MpiSession> mpi;
  if (LaunchedByMpi()) mpi = std::make_unique<MpiSession>(&argc, &argv);
  const bool manager = !mpi || mpi->rank() == 0;
  if (!manager) spdlog::set_level(spdlog::level::warn);

  JobSpecParseOptions parse;
  parse.overrides = Overrides(cli);
  const JobSpec spec = LoadJobSpec(cli.spec_path, parse);
  JobCommandOptions options;
  options.fresh = cli.fresh;
  options.program_version = std::string("calib ") + CALIB_VERSION;
  options.command = start == JobStart::kRun ? (cli.fresh ? "run --fresh" : "run") : "resume";
  if (cli.budget) options.command += fmt::format(" --budget {}", *cli.budget);
  options.threads = cli.threads;
  options.store = OptionalPath(cli.store);
  if (cli.wall_time_s > 0.0) options.wall_time_s = cli.wall_time_s;
  options.cache_dir = OptionalPath(cli.cache_dir);
  options.no_cache = cli.no_cache;
  options.write_report = !cli.no_report;
  options.report_video = !cli.no_video;
  options.progress = ProgressModeFromString(cli.progress);
  options.progress_interval_s = cli.progress_interval_s;
  options.mpi = mpi.get();
  const JobCommandResult result = RunJob(spec, start, options);
  if (result.mpi_worker) return 0;
  PrintRun(result);
  switch (result.run.status) {
    case JobStatus::kAborted: return 3;
    case JobStatus::kStopped:
      fmt::print("continue it with: {}\n", ResumeCommand(cli));
      return 4;
    default: return 0;
  }
}

}  // namespace

std::shared_ptr<JobCli> AddJobSubcommands(CLI::App& app) {
  auto cli = std::make_shared<JobCli>();
  cli->run = app.add_subcommand(
      "run", "calibrate: run a job spec, recording every evaluation in the results store");
  AddRunOptions(cli->run, cli.get());
  cli->run->add_flag("--fresh", cli->fresh,
                     "start over: delete a job of the same name in the store first, asking "
                     "nothing (refused while a process works on it)");
  cli->resume = app.add_subcommand(
      "resume", "continue a stopped or killed job from its last good checkpoint");
  AddRunOptions(cli->resume, cli.get());

  cli->results = app.add_subcommand("results", "print a job's summary; export its evaluations");
  AddJobArgument(cli->results, cli.get());
  cli->results->add_option("--csv", cli->csv, "also write every evaluation as CSV here");
  cli->results->add_option("--json", cli->json, "also write the job and its evaluations as JSON here");
  cli->results->add_option("--plot", cli->plot,
                           "also write the convergence plot (score and best so far against "
                           "evaluations, SVG) here");

  cli->best = app.add_subcommand(
      "best", "write the best parameters of a job as a parameter file (for calib simulate)");
  AddJobArgument(cli->best, cli.get());
  cli->best->add_option("--out", cli->out, "parameter file to write")->required();

  cli->validate = app.add_subcommand(
      "validate", "check a job spec and its recordings without running anything (exit 0: valid)");
  cli->validate->add_option("job", cli->spec_path, "job spec file (YAML or JSON)")->required();
  AddOverrideOptions(cli->validate, cli.get());
  return cli;
}

std::optional<int> RunChosenJobSubcommand(JobCli& cli, int argc, char** argv) {
  if (*cli.run) return RunOrResume(cli, JobStart::kRun, argc, argv);
  if (*cli.resume) return RunOrResume(cli, JobStart::kResume, argc, argv);
  if (*cli.validate) {
    JobSpecParseOptions parse;
    parse.overrides = Overrides(cli);
    const JobSpec spec = LoadJobSpec(cli.spec_path, parse);
    CheckRecordings(spec);
    fmt::print("{}: valid: job '{}', {} searched parameters, optimiser {}, {} evaluations, {} "
               "training and {} held-out recordings\n",
               spec.source, spec.name, spec.SearchedNames().size(), spec.optimizer.name,
               spec.budget.evaluations, spec.train.size(), spec.holdout.size());
    fmt::print("store: {}\nreport: {}\n", ResolveStorePath(spec, OptionalPath(cli.store)).string(),
               spec.results.out_dir.string());
    return 0;
  }
  if (*cli.results) {
    auto [store, job] = OpenJob(LocateJob(cli.job, OptionalPath(cli.store), Overrides(cli)));
    fmt::print("{}", JobResultsText(store, job));
    if (!cli.csv.empty()) {
      store.ExportCsv(job, cli.csv);
      fmt::print("wrote {}\n", cli.csv.string());
    }
    if (!cli.json.empty()) {
      store.ExportJson(job, cli.json);
      fmt::print("wrote {}\n", cli.json.string());
    }
    if (!cli.plot.empty()) {
      WriteConvergencePlot(cli.plot, store.Evaluations(job), store.Job(job).name);
      fmt::print("wrote {}\n", cli.plot.string());
    }
    return 0;
  }
  if (*cli.best) {
    auto [store, job] = OpenJob(LocateJob(cli.job, OptionalPath(cli.store), Overrides(cli)));
    if (cli.out.has_parent_path()) std::filesystem::create_directories(cli.out.parent_path());
    store.WriteBestParameterFile(job, cli.out);
    const auto best = store.Best(job);
    fmt::print("best: evaluation {}, score {}, mean IoU {:.4f}\n", best->id, best->score,
               best->mean_iou);
    fmt::print("wrote {}\n", cli.out.string());
    return 0;
  }
  return std::nullopt;
}

}  // namespace calib::cli
