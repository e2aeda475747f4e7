// calib: the command-line front end. Parses options (CLI11), calls the work in
// calib::jobs and prints what it did. Every error from bad input ends here as
// one message on stderr and exit status 2.

#include "calib/core/model_definition.h"
#include "calib/core/parameters.h"
#include "calib/evaluator/recording_compare.h"
#include "calib/jobs/commands.h"
#include "calib/results/frame_report.h"
#include "compare_cli.h"
#include "job_cli.h"
#include "loop_cli.h"
#include "segment_cli.h"
#include "service_cli.h"
#include "synth_cli.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>

namespace {

using calib::CommandSettings;

// The model: the base terms plus effects (docs/effects.md).
void AddEffectsOption(CLI::App* cmd, CommandSettings* settings) {
  cmd->add_option("--effects", settings->model.effects,
                  "effects added to the base model, comma-separated (docs/effects.md); a "
                  "parameter file then also names their parameters")
      ->delimiter(',');
}

// Options of every subcommand that segments a recording.
void AddCacheOptions(CLI::App* cmd, std::string* cache_dir, bool* no_cache) {
  cmd->add_option("--cache-dir", *cache_dir, "segmentation cache folder")->capture_default_str();
  cmd->add_flag("--no-cache", *no_cache, "do not read or write the segmentation cache");
}

// Options shared by every subcommand that meshes and simulates a recording.
void AddModelOptions(CLI::App* cmd, CommandSettings* settings, std::string* integrator,
                     std::string* cache_dir, bool* no_cache) {
  cmd->add_option("--edge", settings->preparation.mesher.edge_length_px,
                  "target mesh edge length, pixels")
      ->capture_default_str();
  cmd->add_option("--min-edges-across", settings->preparation.mesher.min_edges_across,
                  "mesh an object narrower than this many edges finer (job spec "
                  "model.mesh.min_edges_across; 0: --edge whatever the width)")
      ->check(CLI::Range(0, calib::MesherOptions::kMaxEdgesAcross))
      ->capture_default_str();
  cmd->add_option("--substeps", settings->simulation.substeps, "integration substeps per frame")
      ->capture_default_str();
  cmd->add_option("--integrator", *integrator,
                  "first_order (paper eq. 10), verlet (eq. 8) or implicit_first_order (eq. 10 "
                  "implicit in the springs: stable at any stiffness)")
      ->capture_default_str();
  cmd->add_flag("--outline-contact", settings->simulation.outline_contact,
                "obstacles keep out of the outline's edges, not only its nodes (job spec "
                "model.outline_contact)");
  cmd->add_option("--contact-friction", settings->simulation.contact_friction,
                  "Coulomb friction between the obstacles and the object (job spec "
                  "model.contact_friction; 0: frictionless)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_flag("--area-weighted", settings->simulation.area_weighted,
                "with inertia: masses and stiffnesses in proportion to each node's and "
                "element's share of the area, so the parameters are the material's (job spec "
                "model.area_weighted)");
  AddCacheOptions(cmd, cache_dir, no_cache);
  AddEffectsOption(cmd, settings);
}

void Finish(CommandSettings* settings, const std::string& integrator, const std::string& cache_dir,
            bool no_cache) {
  settings->simulation.integrator = calib::IntegratorKindFromString(integrator);
  settings->preparation.cache_dir = no_cache ? std::filesystem::path() : std::filesystem::path(cache_dir);
}

void PrintResult(const calib::EvaluationResult& result) {
  // Exactly (the shortest text that reads back to the same double), as the
  // results store holds a job's scores.
  fmt::print("score (XOR pixel area summed over frames): {}\n", result.xor_sum);
  if (result.ok()) {
    fmt::print("mean IoU: {:.4f} over {} frames\n", result.mean_iou, result.num_frames);
  } else {
    fmt::print("mean IoU: {:.4f} over {} frames, the {} not simulated counting 0\n",
               result.mean_iou, result.num_frames, result.num_frames - result.frames.size());
  }
  if (result.ok()) {
    fmt::print("status: ok\n");
  } else {
    fmt::print("status: failed at frame {}: {}\n", result.failure_frame, result.failure_reason);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "calib: calibrates a 2D mass-spring model of a deformable object against a video.\n"
      "Recordings follow shared/spec/dataset.md."};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("calib ") + CALIB_VERSION);
  // Messages, progress and errors on stderr; results on stdout.
  spdlog::set_default_logger(spdlog::stderr_color_mt("calib"));
  spdlog::set_pattern("%^[%l]%$ %v");

  CommandSettings settings;
  std::string integrator = calib::ToString(settings.simulation.integrator);
  std::string cache_dir = settings.preparation.cache_dir.string();
  bool no_cache = false;
  std::filesystem::path recording, params, out = "out";

  auto* mesh = app.add_subcommand("mesh", "mesh the object in frame 0; write mesh.json and mesh.png");
  mesh->add_option("recording", recording, "recording folder")->required();
  mesh->add_option("--out", out, "output folder")->capture_default_str();
  AddModelOptions(mesh, &settings, &integrator, &cache_dir, &no_cache);

  calib::SimulateOptions simulate_options;
  bool no_video = false;
  auto* simulate = app.add_subcommand(
      "simulate", "simulate with a parameter file; write frames.csv and overlays");
  simulate->add_option("recording", recording, "recording folder")->required();
  simulate->add_option("--params", params, "parameter file (JSON: name -> number)")->required();
  simulate->add_option("--out", out, "output folder")->capture_default_str();
  simulate->add_option("--png-frames", simulate_options.png_frames,
                       "frames to write as overlay PNGs (the worst frame is always written)")
      ->delimiter(',');
  simulate->add_flag("--no-video", no_video, "do not write overlay.mp4");
  AddModelOptions(simulate, &settings, &integrator, &cache_dir, &no_cache);

  auto* score = app.add_subcommand("score", "simulate with a parameter file and print the score");
  score->add_option("recording", recording, "recording folder")->required();
  score->add_option("--params", params, "parameter file (JSON: name -> number)")->required();
  AddModelOptions(score, &settings, &integrator, &cache_dir, &no_cache);

  auto* params_cmd = app.add_subcommand("params", "list the model's parameters");
  AddEffectsOption(params_cmd, &settings);

  const auto synth_cli = calib::cli::AddSynthSubcommand(app);

  std::filesystem::path compare_a, compare_b, compare_csv;
  auto* compare = app.add_subcommand(
      "compare", "per frame, the pixels where two recordings' segmented objects disagree");
  compare->add_option("a", compare_a, "recording folder")->required();
  compare->add_option("b", compare_b, "recording folder (same frame count and size)")->required();
  compare->add_option("--csv", compare_csv, "also write the per-frame difference here");
  AddCacheOptions(compare, &cache_dir, &no_cache);

  const auto job_cli = calib::cli::AddJobSubcommands(app);  // run, resume, results, best, validate
  const auto loop_cli = calib::cli::AddLoopSubcommand(app);
  const auto benchmark_cli = calib::cli::AddLoopBenchmarkSubcommand(app);
  const auto compare_optimizers_cli = calib::cli::AddCompareSubcommand(app);
  const auto service_cli = calib::cli::AddServiceSubcommands(app);  // serve, submit, status, ...
  const auto segment_cli = calib::cli::AddSegmentSubcommand(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version exit 0; every other parse error is bad input,
    // exit status 2 like the rest (CLI11's own codes are 100 and up).
    const int status = app.exit(e);
    return status == static_cast<int>(CLI::ExitCodes::Success) ? 0 : 2;
  }

  try {
    if (const auto status = calib::cli::RunChosenJobSubcommand(*job_cli, argc, argv)) {
      return *status;
    }
    if (const auto status = calib::cli::RunChosenLoopSubcommand(*loop_cli, argc, argv)) {
      return *status;
    }
    if (const auto status =
            calib::cli::RunChosenLoopBenchmarkSubcommand(*benchmark_cli, argc, argv)) {
      return *status;
    }
    if (const auto status = calib::cli::RunChosenSynthSubcommand(*synth_cli)) return *status;
    if (const auto status = calib::cli::RunChosenCompareSubcommand(*compare_optimizers_cli, argc, argv)) {
      return *status;
    }
    if (const auto status = calib::cli::RunChosenServiceSubcommand(*service_cli)) return *status;
    if (const auto status = calib::cli::RunChosenSegmentSubcommand(*segment_cli)) return *status;
    Finish(&settings, integrator, cache_dir, no_cache);
    if (*mesh) {
      const auto summary = calib::RunMesh(recording, out, settings);
      fmt::print("{}\n", summary.quality.BriefReport());
      fmt::print("clamped nodes: {}\n", summary.clamped_nodes);
      fmt::print("wrote {} and {}\n", summary.mesh_json.string(), summary.mesh_png.string());
    } else if (*simulate) {
      simulate_options.write_video = !no_video;
      const auto summary = calib::RunSimulate(recording, params, out, simulate_options, settings);
      PrintResult(summary.result);
      fmt::print("per-frame report: {}\n", summary.frames_csv.string());
      if (!summary.overlay_video.empty()) {
        fmt::print("overlay video: {}\n", summary.overlay_video.string());
      }
      for (const auto& png : summary.overlay_pngs) fmt::print("overlay: {}\n", png.string());
      return summary.result.ok() ? 0 : 3;  // as `calib score`
    } else if (*score) {
      const auto result = calib::RunScore(recording, params, settings);
      PrintResult(result);
      return result.ok() ? 0 : 3;
    } else if (*compare) {
      const calib::Recording a = calib::LoadRecording(compare_a);
      const calib::Recording b = calib::LoadRecording(compare_b);
      const calib::RecordingDifference d = calib::CompareRecordings(
          a, b, settings.preparation.segmentation, settings.preparation.cache_dir);
      size_t worst = 0;
      for (size_t f = 0; f < d.frames.size(); ++f) {
        if (d.frames[f].xor_px > d.frames[worst].xor_px) worst = f;
      }
      fmt::print("difference (XOR pixels summed over frames): {}\n", d.XorSum());
      fmt::print("mean IoU: {:.4f} over {} frames\n", d.MeanIou(), d.frames.size());
      if (!d.frames.empty()) {
        fmt::print("largest at frame {}: {} px ({} only in a, {} only in b)\n", worst,
                   d.frames[worst].xor_px, d.frames[worst].only_a_px, d.frames[worst].only_b_px);
      }
      if (!compare_csv.empty()) {
        calib::WriteRecordingDifferenceCsv(compare_csv, d);
        fmt::print("per-frame difference: {}\n", compare_csv.string());
      }
    } else if (*params_cmd) {
      for (const auto& spec : calib::ModelParameterSpecs(settings.model)) {
        fmt::print("{:<6} {}{}, {}]  {}  ({})\n", spec.name, spec.lower_open ? "(" : "[",
                   spec.lower, spec.upper, spec.description, spec.unit);
      }
    }
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  return 0;
}
