#include "loop_cli.h"

#include "calib/discovery/loop.h"
#include "calib/discovery/loop_benchmark.h"
#include "calib/discovery/loop_spec.h"

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

// The options `calib loop` and `calib loop-benchmark` share: every loop
// setting but the recordings and the report folder.
struct LoopRunFlags {
  uint64_t seed = kDefaults.seed;
  int64_t budget = kDefaults.budget;
  int64_t effect_budget = kDefaults.effect_budget;
  int threads = kDefaults.threads;
  std::string optimizer = kDefaults.optimizer;
  int max_effects = kDefaults.max_effects;
  int tries = kDefaults.tries_per_round;
  double min_confidence = kDefaults.min_confidence;
  std::string rank_by = kDefaults.rank_by_rate ? "rate" : "confidence";
  int overlays = kDefaults.overlays_per_recording;
  int equally_good_fits = kDefaults.equally_good_fits;
  double fdr = kDefaults.false_discovery_rate;
  double min_drop = kDefaults.min_relative_drop;
  double held_out_stretch = kDefaults.held_out_stretch;
  int refit_candidates = kDefaults.refit_candidates;
  int restarts = kDefaults.restarts;
  int effect_restarts = kDefaults.effect_restarts;
  bool own_meshes = !kDefaults.carry_object_model;
  double edge_length_px = kDefaults.preparation.mesher.edge_length_px;
  int min_edges_across = kDefaults.preparation.mesher.min_edges_across;
  std::string cache_dir;
  bool no_cache = false;
  bool outline_contact = kDefaults.simulation.outline_contact;
  double contact_friction = kDefaults.simulation.contact_friction;
  std::string integrator = calib::ToString(kDefaults.simulation.integrator);
  bool no_html = false;
  bool quiet = false;
};

struct LoopCli {
  CLI::App* loop = nullptr;
  std::vector<std::filesystem::path> train;
  std::vector<std::filesystem::path> holdout;
  std::filesystem::path out;
  bool resume = false;
  LoopRunFlags flags;
};

struct LoopBenchmarkCli {
  CLI::App* benchmark = nullptr;
  std::filesystem::path family_dir;
  std::filesystem::path out;
  std::vector<std::string> only;
  std::vector<std::string> cells;
  int limit = 0;
  LoopRunFlags flags;
};

namespace {

void AddLoopRunOptions(CLI::App* cmd, LoopRunFlags* f) {
  cmd->add_option("--seed", f->seed, "seed of every calibration")->capture_default_str();
  cmd->add_option("--budget", f->budget, "evaluations of the base model's calibration")
      ->check(CLI::Range(kLoopBudgetRange.low, kLoopBudgetRange.high))
      ->capture_default_str();
  cmd->add_option("--effect-budget", f->effect_budget,
                  "evaluations of each calibration with an effect added (0: --budget)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--threads", f->threads, "OpenMP threads (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--optimizer", f->optimizer,
                  "optimiser (cmaes, genetic, annealing, random, nlopt:NAME, grid); cmaes and "
                  "nlopt warm-start each effect from the previous best")
      ->capture_default_str();
  cmd->add_option("--max-effects", f->max_effects, "effects kept at most")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--tries", f->tries, "hypotheses recalibrated per round, best ranked first")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--min-confidence", f->min_confidence,
                  "hypotheses below this confidence are not tried")
      ->check(CLI::Range(kLoopMinConfidenceRange.low, kLoopMinConfidenceRange.high))
      ->capture_default_str();
  cmd->add_option("--rank-by", f->rank_by,
                  "order in which hypotheses are tried: confidence, or rate (how often a "
                  "hypothesis of that effect and confidence was right on the tuning family, "
                  "docs/loop.md)")
      ->check(CLI::IsMember({"confidence", "rate"}))
      ->capture_default_str();
  cmd->add_option("--fdr", f->fdr,
                  "false-discovery rate of the keep rule's test, corrected for every hypothesis "
                  "tried (Benjamini-Hochberg)")
      ->check(CLI::Range(kLoopFdrRange.low, kLoopFdrRange.high))
      ->capture_default_str();
  cmd->add_option("--min-drop", f->min_drop,
                  "the smallest held-out drop worth an effect, as a fraction of the held-out XOR: "
                  "the keep rule's test asks for a drop beyond it")
      ->check(CLI::Range(kLoopMinDropRange.low, kLoopMinDropRange.high))
      ->capture_default_str();
  cmd->add_option("--held-out-stretch", f->held_out_stretch,
                  "without --holdout: the share of each training video, at its end, held out "
                  "(calibrated on the frames before)")
      ->check(CLI::Range(kLoopHeldOutStretchRange.low, kLoopHeldOutStretchRange.high))
      ->capture_default_str();
  cmd->add_option("--equally-good-fits", f->equally_good_fits,
                  "report only: fits of a model as good as its best on the training recordings "
                  "(within max(segmentation noise, 1%)) re-scored on the held-out recordings "
                  "(0: none)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--refit-candidates", f->refit_candidates,
                  "where a calibration's best fit fails to simulate a held-out recording: its "
                  "next best candidates on training tried there, best first; the first that "
                  "simulates every held-out recording is the fit (0: judge the failing fit)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--restarts", f->restarts,
                  "independent searches of the base model's calibration, each with --budget "
                  "evaluations (the first from the box's centre); the best on the training "
                  "recordings is the base fit")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--effect-restarts", f->effect_restarts,
                  "calibrations of each hypothesis tried, each from its own seed (the new "
                  "effect's search from seeded points of its box after the first); each is a "
                  "hypothesis of the keep rule's test, and the largest passing drop is kept")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_flag("--own-meshes", f->own_meshes,
                "mesh every held-out recording and estimate its rest shape on its own, even where "
                "it shows the training recording's object (by default that object's mesh, rest "
                "shape and element areas are carried to it, docs/loop.md)");
  cmd->add_option("--overlays", f->overlays,
                  "overlay frames per recording at the worst moments (base and final model)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("--outline-contact,!--node-contact", f->outline_contact,
                "obstacles keep out of the outline's edges, not only its nodes (job spec "
                "model.outline_contact; the default); --node-contact: the paper's, nodes only");
  cmd->add_option("--contact-friction", f->contact_friction,
                  "Coulomb friction between the obstacles and the object in every calibration "
                  "(job spec model.contact_friction; 0: frictionless)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--integrator", f->integrator,
                  "first_order (paper eq. 10) or implicit_first_order (the same, implicit in the "
                  "springs: stable at any stiffness, docs/loop.md)")
      ->check(CLI::IsMember({"first_order", "implicit_first_order"}))
      ->capture_default_str();
  cmd->add_option("--edge", f->edge_length_px, "target mesh edge length, pixels")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--min-edges-across", f->min_edges_across,
                  "mesh an object narrower than this many edges finer: edges at most its mean "
                  "width (2 area / perimeter) over this (0: --edge whatever the width)")
      ->check(CLI::Range(0, MesherOptions::kMaxEdgesAcross))
      ->capture_default_str();
  cmd->add_option("--cache-dir", f->cache_dir, "segmentation cache folder");
  cmd->add_flag("--no-cache", f->no_cache, "do not read or write the segmentation cache");
  cmd->add_flag("--no-html", f->no_html, "write the reports' JSON only (no report.html)");
  cmd->add_flag("--quiet", f->quiet, "no progress lines");
}

LoopOptions ToLoopOptions(const LoopRunFlags& f, int argc, char** argv) {
  LoopOptions options;
  options.seed = f.seed;
  options.budget = f.budget;
  options.effect_budget = f.effect_budget;
  options.threads = f.threads;
  options.optimizer = f.optimizer;
  options.max_effects = f.max_effects;
  options.tries_per_round = f.tries;
  options.min_confidence = f.min_confidence;
  options.rank_by_rate = f.rank_by == "rate";
  options.overlays_per_recording = f.overlays;
  options.equally_good_fits = f.equally_good_fits;
  options.false_discovery_rate = f.fdr;
  options.min_relative_drop = f.min_drop;
  options.held_out_stretch = f.held_out_stretch;
  options.refit_candidates = f.refit_candidates;
  options.restarts = f.restarts;
  options.effect_restarts = f.effect_restarts;
  options.carry_object_model = !f.own_meshes;
  options.preparation.mesher.edge_length_px = f.edge_length_px;
  options.preparation.mesher.min_edges_across = f.min_edges_across;
  options.write_html = !f.no_html;
  options.simulation.outline_contact = f.outline_contact;
  options.simulation.contact_friction = f.contact_friction;
  options.simulation.integrator = IntegratorKindFromString(f.integrator);
  if (f.no_cache) {
    options.preparation.cache_dir.clear();
  } else if (!f.cache_dir.empty()) {
    options.preparation.cache_dir = f.cache_dir;
  }
  std::string command;
  for (int i = 0; i < argc; ++i) {
    if (i > 0) command += ' ';
    command += argv[i];
  }
  options.command = command;
  return options;
}

LoopLog ProgressLog(const LoopRunFlags& f) {
  if (f.quiet) return {};
  return [](const std::string& line) { spdlog::info("{}", line); };
}

}  // namespace

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
  cmd->add_flag("--resume", cli->resume,
                "continue the loop whose store is in --out (killed or stopped part way), with "
                "the options that started it; without it the store is started afresh");
  AddLoopRunOptions(cmd, &cli->flags);
  return cli;
}

std::optional<int> RunChosenLoopSubcommand(LoopCli& cli, int argc, char** argv) {
  if (cli.loop == nullptr || !*cli.loop) return std::nullopt;
  LoopOptions options = ToLoopOptions(cli.flags, argc, argv);
  options.train = cli.train;
  options.holdout = cli.holdout;
  options.out_dir = cli.out;
  options.resume = cli.resume;
  const LoopResult result = RunLoop(options, ProgressLog(cli.flags));
  fmt::print("\n{}", result.table);
  fmt::print("run time: {:.1f} s\n", result.report.run_time_s);
  fmt::print("report: {}\n", result.report_json.string());
  if (!result.report_html.empty()) fmt::print("report: {}\n", result.report_html.string());
  fmt::print("results store: {}\n", result.store.string());
  return 0;
}

std::shared_ptr<LoopBenchmarkCli> AddLoopBenchmarkSubcommand(CLI::App& app) {
  auto cli = std::make_shared<LoopBenchmarkCli>();
  CLI::App* cmd = app.add_subcommand(
      "loop-benchmark",
      "run the loop on every object of a family of recordings (FAMILY_DIR/family.json) and "
      "measure how often it keeps the effect each has; write benchmark.json, .csv, .html "
      "(docs/loop.md)");
  cli->benchmark = cmd;
  cmd->add_option("family_dir", cli->family_dir, "family folder (family.json, the recordings)")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", cli->out,
                  "benchmark folder (objects/<id>/ per object, benchmark.json, .csv, .html); "
                  "objects already done there with the same options are read back")
      ->required();
  cmd->add_option("--only", cli->only, "object ids to run (default: all)");
  cmd->add_option("--cells", cli->cells, "cells to run (default: all)");
  cmd->add_option("--limit", cli->limit, "the first N objects of each cell (0: all)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  AddLoopRunOptions(cmd, &cli->flags);
  return cli;
}

std::optional<int> RunChosenLoopBenchmarkSubcommand(LoopBenchmarkCli& cli, int argc, char** argv) {
  if (cli.benchmark == nullptr || !*cli.benchmark) return std::nullopt;
  LoopBenchmarkOptions options;
  options.loop = ToLoopOptions(cli.flags, argc, argv);
  options.command = options.loop.command;
  options.family_dir = cli.family_dir;
  options.out_dir = cli.out;
  options.only = cli.only;
  options.cells = cli.cells;
  options.limit_per_cell = cli.limit;
  options.write_html = !cli.flags.no_html;
  const LoopBenchmarkResult result = RunLoopBenchmark(options, ProgressLog(cli.flags));
  const BenchmarkAggregate& a = result.report.aggregate;
  fmt::print("\nobjects: {} ({} run, {} read back, {} failed{})\n", a.objects, result.ran, result.resumed,
             result.failed,
             result.not_made > 0 ? fmt::format(", {} not made by the generator", result.not_made) : "");
  fmt::print("false discoveries: {} / {}\n", a.false_discoveries.successes,
             a.false_discoveries.trials);
  for (const DetectionRate& d : a.detection) {
    fmt::print("detected {} ({}): {} / {}\n", d.effect, d.magnitude.empty() ? "-" : d.magnitude,
               d.detected.successes, d.detected.trials);
  }
  fmt::print("run time: {:.1f} s\n", a.total_run_time_s);
  fmt::print("benchmark: {}\n", result.json.string());
  fmt::print("benchmark: {}\n", result.csv.string());
  if (!result.html.empty()) fmt::print("benchmark: {}\n", result.html.string());
  return 0;
}

}  // namespace calib::cli
