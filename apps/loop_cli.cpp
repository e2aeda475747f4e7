#include "loop_cli.h"

#include "calib/discovery/loop.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <string>
#include <vector>

namespace calib::cli {

namespace {
// The options' defaults are LoopOptions', stated once there.
const LoopOptions kDefaults{};
}  // namespace

struct LoopCli {
  CLI::App* loop = nullptr;
  std::vector<std::filesystem::path> train;
  std::vector<std::filesystem::path> holdout;
  std::filesystem::path out;
  uint64_t seed = kDefaults.seed;
  int64_t budget = kDefaults.budget;
  int64_t effect_budget = kDefaults.effect_budget;
  int threads = kDefaults.threads;
  std::string optimizer = kDefaults.optimizer;
  int max_effects = kDefaults.max_effects;
  int tries = kDefaults.tries_per_round;
  double min_confidence = kDefaults.min_confidence;
  int overlays = kDefaults.overlays_per_recording;
  int equally_good_fits = kDefaults.equally_good_fits;
  double fdr = kDefaults.false_discovery_rate;
  double held_out_stretch = kDefaults.held_out_stretch;
  int restarts = kDefaults.restarts;
  std::string cache_dir;
  bool no_cache = false;
  bool outline_contact = kDefaults.simulation.outline_contact;
  double contact_friction = kDefaults.simulation.contact_friction;
  std::string integrator = calib::ToString(kDefaults.simulation.integrator);
  bool no_html = false;
  bool quiet = false;
};

std::shared_ptr<LoopCli> AddLoopSubcommand(CLI::App& app) {
  auto cli = std::make_shared<LoopCli>();
  CLI::App* cmd = app.add_subcommand(
      "loop",
      "calibrate the base model, trace its residual to missing effects, add them while they "
      "lower the held-out error; write report.json and report.html (docs/loop.md)");
  cli->loop = cmd;
  cmd->add_option("--train", cli->train, "training recording folders (fitted)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--holdout", cli->holdout,
                  "held-out recording folders (decide which effects are kept; never fitted)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", cli->out, "report folder (report.json, report.html, store.sqlite)")
      ->required();
  cmd->add_option("--seed", cli->seed, "seed of every calibration")->capture_default_str();
  cmd->add_option("--budget", cli->budget, "evaluations of the base model's calibration")
      ->check(CLI::Range(int64_t{2}, int64_t{100000000}))
      ->capture_default_str();
  cmd->add_option("--effect-budget", cli->effect_budget,
                  "evaluations of each calibration with an effect added (0: --budget)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--threads", cli->threads, "OpenMP threads (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--optimizer", cli->optimizer,
                  "optimiser (cmaes, genetic, annealing, random, nlopt:NAME, grid); cmaes and "
                  "nlopt warm-start each effect from the previous best")
      ->capture_default_str();
  cmd->add_option("--max-effects", cli->max_effects, "effects kept at most")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--tries", cli->tries, "hypotheses recalibrated per round, best ranked first")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--min-confidence", cli->min_confidence,
                  "hypotheses below this confidence are not tried")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--fdr", cli->fdr,
                  "false-discovery rate of the keep rule's test, corrected for every hypothesis "
                  "tried (Benjamini-Hochberg)")
      ->check(CLI::Range(0.001, 0.5))
      ->capture_default_str();
  cmd->add_option("--held-out-stretch", cli->held_out_stretch,
                  "without --holdout: the share of each training video, at its end, held out "
                  "(calibrated on the frames before)")
      ->check(CLI::Range(0.05, 0.95))
      ->capture_default_str();
  cmd->add_option("--equally-good-fits", cli->equally_good_fits,
                  "report only: fits of a model as good as its best on the training recordings "
                  "(within max(segmentation noise, 1%)) re-scored on the held-out recordings "
                  "(0: none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--restarts", cli->restarts,
                  "independent searches of the base model's calibration, each with --budget "
                  "evaluations (the first from the box's centre); the best on the training "
                  "recordings is the base fit")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--overlays", cli->overlays,
                  "overlay frames per recording at the worst moments (base and final model)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("--outline-contact,!--node-contact", cli->outline_contact,
                "obstacles keep out of the outline's edges, not only its nodes (job spec "
                "model.outline_contact; the default); --node-contact: the paper's, nodes only");
  cmd->add_option("--contact-friction", cli->contact_friction,
                  "Coulomb friction between the obstacles and the object in every calibration "
                  "(job spec model.contact_friction; 0: frictionless)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--integrator", cli->integrator,
                  "first_order (paper eq. 10) or implicit_first_order (the same, implicit in the "
                  "springs: stable at any stiffness, docs/loop.md)")
      ->check(CLI::IsMember({"first_order", "implicit_first_order"}))
      ->capture_default_str();
  cmd->add_option("--cache-dir", cli->cache_dir, "segmentation cache folder");
  cmd->add_flag("--no-cache", cli->no_cache, "do not read or write the segmentation cache");
  cmd->add_flag("--no-html", cli->no_html, "write report.json only");
  cmd->add_flag("--quiet", cli->quiet, "no progress lines");
  return cli;
}

std::optional<int> RunChosenLoopSubcommand(LoopCli& cli, int argc, char** argv) {
  if (cli.loop == nullptr || !*cli.loop) return std::nullopt;
  LoopOptions options;
  options.train = cli.train;
  options.holdout = cli.holdout;
  options.out_dir = cli.out;
  options.seed = cli.seed;
  options.budget = cli.budget;
  options.effect_budget = cli.effect_budget;
  options.threads = cli.threads;
  options.optimizer = cli.optimizer;
  options.max_effects = cli.max_effects;
  options.tries_per_round = cli.tries;
  options.min_confidence = cli.min_confidence;
  options.overlays_per_recording = cli.overlays;
  options.equally_good_fits = cli.equally_good_fits;
  options.false_discovery_rate = cli.fdr;
  options.held_out_stretch = cli.held_out_stretch;
  options.restarts = cli.restarts;
  options.write_html = !cli.no_html;
  options.simulation.outline_contact = cli.outline_contact;
  options.simulation.contact_friction = cli.contact_friction;
  options.simulation.integrator = IntegratorKindFromString(cli.integrator);
  if (cli.no_cache) {
    options.preparation.cache_dir.clear();
  } else if (!cli.cache_dir.empty()) {
    options.preparation.cache_dir = cli.cache_dir;
  }
  std::string command;
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);
  options.command = command;
  LoopLog log;
  if (!cli.quiet) log = [](const std::string& line) { spdlog::info("{}", line); };
  const LoopResult result = RunLoop(options, log);
  fmt::print("\n{}", result.table);
  fmt::print("run time: {:.1f} s\n", result.report.run_time_s);
  fmt::print("report: {}\n", result.report_json.string());
  if (!result.report_html.empty()) fmt::print("report: {}\n", result.report_html.string());
  fmt::print("results store: {}\n", result.store.string());
  return 0;
}

}  // namespace calib::cli
