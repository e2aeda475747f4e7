#include "compare_cli.h"

#include "calib/jobs/comparison.h"
#include "calib/jobs/mpi_evaluator.h"
#include "job_cli.h"

#include <fmt/format.h>

#include <filesystem>
#include <string>

namespace calib::cli {

struct CompareCli {
  CLI::App* command = nullptr;
  std::filesystem::path spec;
  std::filesystem::path out;
  std::optional<int> threads;
  std::string progress = "auto";
  double progress_interval_s = 10.0;
  std::string cache_dir;
  bool no_cache = false;
};

std::shared_ptr<CompareCli> AddCompareSubcommand(CLI::App& app) {
  auto cli = std::make_shared<CompareCli>();
  CLI::App* cmd = app.add_subcommand(
      "compare-optimizers",
      "run several optimisers and seeds on one objective and compare them with statistics "
      "(resumable: run it again to continue)");
  cli->command = cmd;
  cmd->add_option("spec", cli->spec, "comparison spec (YAML or JSON; docs/compare.md)")->required();
  cmd->add_option("--out", cli->out,
                  "folder for the results store, the report and its CSV files (default: "
                  "out/compare/<the spec's name>/ in the current folder)");
  cmd->add_option("--threads", cli->threads, "OpenMP threads per run, 0: all cores (default: the spec's)")
      ->check(CLI::NonNegativeNumber);
  AddProgressAndCacheOptions(cmd, &cli->progress, &cli->progress_interval_s, &cli->cache_dir,
                             &cli->no_cache);
  return cli;
}

std::optional<int> RunChosenCompareSubcommand(CompareCli& cli) {
  if (!*cli.command) return std::nullopt;
  if (LaunchedByMpi()) {
    // Every rank would run the whole comparison against one store.
    throw std::invalid_argument(
        "compare-optimizers does not run under an MPI launcher yet: run it as one process "
        "(--threads N), or run its jobs with calib run");
  }
  const ComparisonSpec spec = LoadComparisonSpec(cli.spec, cli.out);
  ComparisonOptions options;
  options.threads = cli.threads;
  if (!cli.cache_dir.empty()) options.cache_dir = std::filesystem::path(cli.cache_dir);
  options.no_cache = cli.no_cache;
  options.progress = ProgressModeFromString(cli.progress);
  options.progress_interval_s = cli.progress_interval_s;
  options.program_version = std::string("calib ") + CALIB_VERSION;
  const ComparisonResult result = RunComparison(spec, spec.out_dir, options);
  fmt::print("{} runs: {} done before, {} run now\nstore: {}\n", result.runs, result.already_done,
             result.run_now, result.store.string());
  if (result.stopped) {
    fmt::print("stopped: run the same command again to continue\n");
    return 4;
  }
  fmt::print("{}\nreport: {}\n", result.analysis->verdict, result.report->html.string());
  return 0;
}

}  // namespace calib::cli
