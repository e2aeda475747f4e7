#include "synth_cli.h"

#include "calib/synth/family.h"
#include "calib/synth/scenario.h"
#include "calib/synth/synthesize.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace calib::cli {

struct SynthCli {
  CLI::App* synth = nullptr;
  std::filesystem::path scenario;
  std::filesystem::path out;
  bool without_effects = false;
  std::filesystem::path family;
  std::optional<int> count;
  std::optional<uint64_t> seed;
  bool plan = false;
  std::optional<std::string> only;
};

std::shared_ptr<SynthCli> AddSynthSubcommand(CLI::App& app) {
  auto cli = std::make_shared<SynthCli>();
  CLI::App* cmd = app.add_subcommand(
      "synth",
      "make a synthetic recording from a scenario file, or a scene family from a family spec "
      "(docs/scenario.md)");
  cli->synth = cmd;
  auto* scenario = cmd->add_option("scenario", cli->scenario, "scenario file (YAML)");
  cmd->add_option("--out", cli->out, "recording folder (a scenario) or family folder (--family) to write")
      ->required();
  cmd->add_flag("--without-effects", cli->without_effects,
                "switch the scenario's effects off (its twin, for `calib compare`: the effects' "
                "footprint in pixels)")
      ->needs(scenario);
  auto* family = cmd->add_option("--family", cli->family,
                                 "family spec (YAML): make a scene family instead; writes family.json "
                                 "and <object>/<recording>/ folders")
                     ->excludes(scenario);
  cmd->add_option("--count", cli->count, "objects per cell (default: the spec's count)")
      ->check(CLI::Range(1, 10000))
      ->needs(family);
  cmd->add_option("--seed", cli->seed, "family seed (default: the spec's seed)")->needs(family);
  cmd->add_flag("--plan,--dry-run", cli->plan,
                "write family.json and every recording's scenario file, without simulating or "
                "rendering")
      ->needs(family);
  cmd->add_option("--only", cli->only, "make only this object of the family (its id in family.json)")
      ->needs(family);
  return cli;
}

namespace {

int RunScenario(const SynthCli& cli) {
  synth::Scenario scenario = synth::LoadScenario(cli.scenario);
  if (cli.without_effects) scenario = synth::WithoutEffects(scenario);
  const auto summary = synth::Synthesize(scenario, cli.out);
  fmt::print("wrote {} (recording.json, video.mp4, track.csv, truth.json)\n", summary.folder.string());
  fmt::print("{}\n", summary.BriefReport());
  fmt::print("time: {:.1f} s, size: {:.2f} MB\n", summary.total_s, summary.bytes / 1e6);
  return 0;
}

int RunFamily(const SynthCli& cli) {
  const synth::FamilySpec spec = synth::LoadFamilySpec(cli.family);
  const uint64_t seed = cli.seed.value_or(spec.seed);
  const int count = cli.count.value_or(spec.count);
  const synth::FamilyPlan plan = synth::PlanFamily(spec, seed, count);
  synth::FamilyOptions options;
  options.plan_only = cli.plan;
  options.only = cli.only;
  options.progress = [](const std::string& line) { spdlog::info("{}", line); };
  fmt::print("family {}: {} cells x {} objects, seed {}{}\n", plan.name, spec.cells.size(), count, seed,
             cli.plan ? " (plan only)" : "");
  const synth::FamilySummary summary = synth::MakeFamily(plan, cli.out, options);
  fmt::print("wrote {} ({} objects{})\n", (cli.out / "family.json").string(), summary.objects,
             cli.plan ? ", scenario files only" : fmt::format(", {} recordings", summary.recordings));
  if (summary.recordings > 0) {
    fmt::print("time: {:.1f} s ({:.1f} s per recording: simulation {:.1f} s, rendering {:.1f} s), size: {:.2f} MB\n",
               summary.total_s, summary.total_s / summary.recordings,
               summary.simulation_s / summary.recordings, summary.rendering_s / summary.recordings,
               summary.bytes / 1e6);
  }
  if (!summary.not_made.empty()) {
    // The family is usable without them (loop-benchmark leaves them out);
    // the status says that not everything asked for was made.
    fmt::print(stderr, "{} of {} objects not made (family.json marks them not_made):\n",
               summary.not_made.size(), summary.objects);
    for (const auto& [id, reason] : summary.not_made) fmt::print(stderr, "  {}: {}\n", id, reason);
    return 1;
  }
  return 0;
}

}  // namespace

std::optional<int> RunChosenSynthSubcommand(SynthCli& cli) {
  if (cli.synth == nullptr || !*cli.synth) return std::nullopt;
  if (cli.family.empty() && cli.scenario.empty()) {
    throw std::invalid_argument("synth: give a scenario file or --family SPEC");
  }
  return cli.family.empty() ? RunScenario(cli) : RunFamily(cli);
}

}  // namespace calib::cli
