#include "compare_cli.h"

#include "calib/jobs/comparison.h"
#include "calib/jobs/mpi_evaluator.h"
#include "job_cli.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>
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
  bool status = false;
  std::filesystem::path base_dir;
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
  cmd->add_option("--base-dir", cli->base_dir,
                  "resolve the spec's relative paths (recordings) against this folder instead of "
                  "the spec's own");
  cmd->add_flag("--status", cli->status,
                "print where each run stands (finished, running, interrupted, not started) and "
                "run nothing");
  return cli;
}

std::optional<int> RunChosenCompareSubcommand(CompareCli& cli, int argc, char** argv) {
  if (!*cli.command) return std::nullopt;
  const ComparisonSpec spec = LoadComparisonSpec(cli.spec, cli.out, {}, cli.base_dir);
  if (cli.status) {
    fmt::print("{}", ComparisonStatusText(spec));
    return 0;
  }
  // MPI is initialised only under an MPI launcher: rank 0 runs the
  // comparison, the others evaluate each run's candidates.
  std::unique_ptr<MpiSession> mpi;
  if (LaunchedByMpi()) mpi = std::make_unique<MpiSession>(&argc, &argv);
  if (mpi && mpi->rank() != 0) spdlog::set_level(spdlog::level::warn);
  ComparisonOptions options;
  options.mpi = mpi.get();
  options.threads = cli.threads;
  if (!cli.cache_dir.empty()) options.cache_dir = std::filesystem::path(cli.cache_dir);
  options.no_cache = cli.no_cache;
  options.progress = ProgressModeFromString(cli.progress);
  options.progress_interval_s = cli.progress_interval_s;
  options.program_version = std::string("calib ") + CALIB_VERSION;
  const ComparisonResult result = RunComparison(spec, spec.out_dir, options);
  if (result.mpi_worker) return 0;
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
