// The closed loop (loop.h, docs/loop.md).

#include "calib/discovery/loop.h"

#include "calib/jobs/fit_diagnostics.h"

#include "calib/core/model_definition.h"
#include "calib/discovery/confidence_rates.h"
#include "calib/discovery/confusions.h"
#include "calib/discovery/paired_test.h"
#include "calib/discovery/report_html.h"
#include "calib/discovery/report_overlays.h"
#include "calib/evaluator/mask_geometry.h"
#include "calib/evaluator/object_transfer.h"
#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/fit_diagnostics.h"
#include "calib/results/store.h"
#include "loop_stages.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <stdexcept>
#include <utility>

namespace calib {

namespace fs = std::filesystem;
using nlohmann::json;

// =========================================================================
// Options.

bool LoopOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& message) {
    *error = message;
    return false;
  };
  if (train.empty()) return fail("loop: --train needs at least one recording folder");
  if (out_dir.empty()) return fail("loop: --out (the report folder) is required");
  if (budget < 2) return fail(fmt::format("loop: --budget = {}: must be >= 2", budget));
  if (effect_budget < 0) {
    return fail(fmt::format("loop: effect budget = {}: must be >= 0", effect_budget));
  }
  if (threads < 0) return fail(fmt::format("loop: --threads = {}: must be >= 0", threads));
  if (max_effects < 0) return fail(fmt::format("loop: --max-effects = {}: must be >= 0", max_effects));
  if (tries_per_round < 1) {
    return fail(fmt::format("loop: --tries = {}: must be >= 1", tries_per_round));
  }
  if (!(min_confidence >= 0.0 && min_confidence <= 1.0)) {
    return fail(fmt::format("loop: --min-confidence = {}: must be in [0, 1]", min_confidence));
  }
  if (!(min_relative_drop >= 0.0 && min_relative_drop < 1.0)) {
    return fail(fmt::format("loop: --min-drop = {}: must be in [0, 1)", min_relative_drop));
  }
  if (!(false_discovery_rate > 0.0 && false_discovery_rate < 1.0)) {
    return fail(fmt::format("loop: --fdr = {}: must be in (0, 1)", false_discovery_rate));
  }
  if (test_resamples < 99) {
    return fail(fmt::format("loop: test resamples = {}: must be >= 99", test_resamples));
  }
  if (!(held_out_stretch > 0.0 && held_out_stretch < 1.0)) {
    return fail(fmt::format("loop: --held-out-stretch = {}: must be in (0, 1)", held_out_stretch));
  }
  if (equally_good_fits < 0) {
    return fail(fmt::format("loop: --equally-good-fits = {}: must be >= 0", equally_good_fits));
  }
  if (refit_candidates < 0) {
    return fail(fmt::format("loop: --refit-candidates = {}: must be >= 0", refit_candidates));
  }
  if (restarts < 1) return fail(fmt::format("loop: --restarts = {}: must be >= 1", restarts));
  if (effect_restarts < 1) {
    return fail(fmt::format("loop: --effect-restarts = {}: must be >= 1", effect_restarts));
  }
  if (overlays_per_recording < 0) {
    return fail(fmt::format("loop: overlays per recording = {}: must be >= 0",
                            overlays_per_recording));
  }
  std::string sub;
  if (!simulation.IsValid(&sub)) return fail("loop: simulation options: " + sub);
  if (!preparation.IsValid(&sub)) return fail("loop: preparation options: " + sub);
  return true;
}

SimulationOptions LoopSimulationDefaults() {
  SimulationOptions o;
  o.integrator = IntegratorKind::kImplicitFirstOrder;
  o.outline_contact = true;
  o.contact_friction = 0.5;
  return o;
}

// =========================================================================
// The loop.

namespace {

using namespace loop_detail;
using Clock = std::chrono::steady_clock;

double Since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string EquallyGoodLine(const EquallyGoodFits& g) {
  if (g.fits == 0) return "";
  return fmt::format("; {} equally good fits: held-out XOR {:.0f} to {:.0f}, median {:.0f}", g.fits,
                     g.holdout_xor_min, g.holdout_xor_max, g.holdout_xor_median);
}

std::string RestartsLine(const std::vector<double>& training_xor) {
  if (training_xor.size() < 2) return "";
  return fmt::format("; best training XOR of each of {} searches: {:.0f}", training_xor.size(),
                     fmt::join(training_xor, ", "));
}

class Loop {
 public:
  Loop(const LoopOptions& options, const LoopLog& log) : o_(options), log_(log) {}

  LoopResult Run();

 private:
  void Log(const std::string& line) const {
    if (log_) log_(line);
  }
  void Prepare();
  // `held_out` with the first training recording's object model where it
  // shows that object (LoopOptions::carry_object_model), else as it is;
  // says which in the log and the report's notes.
  std::shared_ptr<const PreparedRecording> CarryTrainingObject(
      std::shared_ptr<const PreparedRecording> held_out);
  ReportStage MakeStage(const Fit& fit, const std::string& tried, StageDecision decision) const;
  // Logs what the calibration's history says about the fit, if anything.
  void LogFitDiagnostics(const Fit& fit) const;
  void AddResiduals(const Fit& fit);
  void AddOverlays(const Fit& fit, const std::string& stage);
  // The confusable pairs this round met (confusions.h), judged after its
  // keep decisions are made but before they are marked.
  void AddConfusions(int round, const std::vector<Hypothesis>& ranked,
                     const std::vector<size_t>& stage_index);

  // A copy: Prepare sets simulation.area_weighted for hanging objects.
  LoopOptions o_;
  const LoopLog& log_;
  std::vector<LoopRecording> recs_;
  SearchScales scales_;
  std::unique_ptr<ResultStore> store_;
  int threads_ = 1;
  LoopReport report_;
  std::unique_ptr<KeepCriterion> criterion_;
  std::unique_ptr<StageCalibrator> calibrator_;
};

std::shared_ptr<const PreparedRecording> Loop::CarryTrainingObject(
    std::shared_ptr<const PreparedRecording> held_out) {
  const auto training = std::find_if(recs_.begin(), recs_.end(), [](const LoopRecording& r) { return r.train; });
  if (!o_.carry_object_model || training == recs_.end() ||
      training->prepared->scene.motion.node_rest_px.empty()) {
    return held_out;
  }
  PreparedRecording carried = *held_out;
  const ObjectTransfer transfer =
      CarryObjectModel(*training->prepared, carried, o_.preparation.motion_window_s);
  Log(transfer.reason);
  report_.notes.push_back(transfer.reason);
  if (!transfer.carried) return held_out;
  return std::make_shared<const PreparedRecording>(std::move(carried));
}

void Loop::Prepare() {
  std::set<std::string> names;
  auto add = [&](const fs::path& path, std::shared_ptr<const PreparedRecording> prepared,
                 bool train, int first_compared_frame, const std::string& suffix) {
    LoopRecording r;
    r.path = path;
    r.train = train;
    r.first_compared_frame = first_compared_frame;
    r.prepared = std::move(prepared);
    const std::string name = RecordingDisplayName(r.prepared->recording.folder) + suffix;
    r.name = name;
    for (int k = 2; names.count(r.name) != 0; ++k) r.name = fmt::format("{}_{}", name, k);
    names.insert(r.name);
    r.noise_px = SegmentationNoisePx(r.prepared->object_masks);
    if (const std::optional<Vec2> clamp = ClampCentre(r.prepared->scene)) {
      for (const BitMask& mask : r.prepared->object_masks) r.video_tips.push_back(FarthestPixelFrom(mask, *clamp));
    }
    r.residual_facts = std::make_shared<const RecordingResidualFacts>(ComputeResidualFacts(*r.prepared));
    recs_.push_back(std::move(r));
  };
  auto prepare = [&](const fs::path& path, bool train) {
    Log(fmt::format("preparing {} ({})", path.string(), train ? "train" : "held out"));
    return std::make_shared<const PreparedRecording>(PrepareRecording(LoadRecording(path), o_.preparation));
  };
  if (!o_.holdout.empty()) {
    for (const fs::path& p : o_.train) add(p, prepare(p, true), true, 0, "");
    for (const fs::path& p : o_.holdout) add(p, CarryTrainingObject(prepare(p, false)), false, 0, "");
  } else {
    // No held-out recording: calibrate on the first frames of each training
    // video and hold out the rest (whole videos are scored there, but only
    // the frames from the split on are compared).
    std::vector<std::pair<fs::path, std::shared_ptr<const PreparedRecording>>> full;
    for (const fs::path& p : o_.train) full.emplace_back(p, prepare(p, true));
    for (const auto& [path, prepared] : full) {
      const int n = prepared->scene.num_frames;
      const int split = std::clamp(static_cast<int>(std::lround(n * (1.0 - o_.held_out_stretch))), 1, n - 1);
      add(path, std::make_shared<const PreparedRecording>(FirstFrames(*prepared, split)), true, 0, "");
      add(path, prepared, false, split, fmt::format("_frames_{}-{}", split, n - 1));
      report_.notes.push_back(fmt::format(
          "no held-out recording: {} is calibrated on frames 0-{} and frames {}-{} are held out",
          path.string(), split - 1, split, n - 1));
    }
  }

  std::vector<std::shared_ptr<const PreparedRecording>> training;
  for (const LoopRecording& r : recs_) {
    if (r.train) training.push_back(r.prepared);
  }
  // A clamped object moves by itself (it swings, sags): its fits with
  // inertia are to carry to other recordings and other meshes of it, so
  // their masses and stiffnesses are the material's (area weighted).
  const bool hanging = std::any_of(training.begin(), training.end(), [](const auto& p) {
    return !p->scene.clamps.empty();
  });
  if (hanging && !o_.simulation.area_weighted) {
    o_.simulation.area_weighted = true;
    report_.notes.push_back(
        "the training recordings hold the object in clamps: the models with inertia are area "
        "weighted (each node's mass and each element's stiffness in proportion to its share of "
        "the object's area, docs/effects.md)");
  }
  scales_ = TrainingScales(training, o_.simulation);
  for (const LoopRecording& r : recs_) {
    ReportRecording rec{r.name, r.path.string(), r.train ? "train" : "holdout",
                        r.prepared->scene.num_frames, r.prepared->recording.fps, {}, {}, {}};
    for (const Vec2& t : r.video_tips) {
      rec.tip_x_px.push_back(t.x());
      rec.tip_y_px.push_back(t.y());
    }
    rec.registered_iou = r.prepared->registered_iou;
    report_.recordings.push_back(std::move(rec));
  }
}

void Loop::LogFitDiagnostics(const Fit& fit) const {
  FitDiagnostics d;
  d.uninformative = fit.uninformative;
  d.at_bounds = fit.at_bounds;
  d.scored = fit.evaluations;
  const std::string summary = d.Summary();
  if (!summary.empty()) Log(fmt::format("{}: {}", StageName(fit.effects), summary));
}

ReportStage Loop::MakeStage(const Fit& fit, const std::string& tried, StageDecision decision) const {
  ReportStage s;
  s.name = StageName(fit.effects);
  s.effect_tried = tried;
  s.decision = decision;
  s.effects = fit.effects;
  s.parameters = fit.values;
  for (size_t r = 0; r < recs_.size(); ++r) {
    RecordingScore e = RecordingScore::FromEvaluation(recs_[r].name, fit.results[r]);
    if (r < fit.tips.size() && !fit.tips[r].empty() && !recs_[r].video_tips.empty()) {
      for (const Vec2& t : fit.tips[r]) {
        e.tip_x_px.push_back(t.x());
        e.tip_y_px.push_back(t.y());
      }
      e.median_tip_distance_px = MedianTipDistance(fit.tips[r], recs_[r].video_tips);
    }
    s.errors.push_back(std::move(e));
  }
  s.calibration_time_s = fit.seconds;
  s.evaluations = fit.evaluations;
  s.equally_good = fit.equally_good;
  s.holdout_sensitivity_px = fit.holdout_sensitivity_px;
  s.holdout_sensitivity_parameter = fit.holdout_sensitivity_parameter;
  if (fit.restart_training_xor.size() > 1) s.restart_training_xor = fit.restart_training_xor;
  s.uninformative = fit.uninformative;
  s.at_bounds = fit.at_bounds;
  return s;
}

void Loop::AddResiduals(const Fit& fit) {
  for (size_t r = 0; r < recs_.size(); ++r) {
    report_.residuals.push_back({recs_[r].name, StageName(fit.effects), fit.residuals[r]});
  }
}

void Loop::AddOverlays(const Fit& fit, const std::string& stage) {
  if (o_.overlays_per_recording == 0) return;
  const ModelDefinition model{fit.effects};
  for (size_t r = 0; r < recs_.size(); ++r) {
    std::vector<double> frame_xor;
    for (const FrameScore& f : fit.results[r].frames) frame_xor.push_back(f.xor_px);
    const int gap = std::max(1, static_cast<int>(frame_xor.size()) / 10);
    std::vector<int> frames = WorstFrames(frame_xor, o_.overlays_per_recording, gap);
    std::sort(frames.begin(), frames.end());
    if (frames.empty()) continue;
    try {
      OverlayCapture capture(*recs_[r].prepared, frames, o_.out_dir, stage);
      Evaluator evaluator(*recs_[r].prepared, o_.simulation, model);
      evaluator.Evaluate(fit.values, capture);
      for (const ReportOverlay& ov : capture.overlays()) report_.overlays.push_back(ov);
    } catch (const std::exception& e) {
      report_.notes.push_back(
          fmt::format("no overlays of {} on {}: {}", stage, recs_[r].name, e.what()));
    }
  }
}

void Loop::AddConfusions(int round, const std::vector<Hypothesis>& ranked,
                         const std::vector<size_t>& stage_index) {
  std::vector<const ReportStage*> tried;
  for (size_t i : stage_index) tried.push_back(&report_.stages[i]);
  double eccentricity = 0.0;
  for (size_t r = 0; r < recs_.size(); ++r) {
    if (!recs_[r].train || report_.stages.empty()) continue;
    // The residual of the model this round extended, on a training recording.
    for (const ReportResidual& res : report_.residuals) {
      if (res.recording == recs_[r].name && res.analysis.push.has_push) {
        eccentricity = std::max(eccentricity, res.analysis.push.load_eccentricity);
      }
    }
  }
  for (ReportConfusion& c : JudgeConfusions(round, ranked, tried, eccentricity, o_.min_confidence)) {
    Log(fmt::format("round {}: {} / {}: {}{}", round, c.effect,
                    c.confused_with.empty() ? "the base model" : c.confused_with, c.evidence,
                    c.proposal.empty() ? "" : "; proposed recording: " + c.proposal));
    report_.confusions.push_back(std::move(c));
  }
}

LoopResult Loop::Run() {
  const Clock::time_point start = Clock::now();
  std::string error;
  if (!o_.IsValid(&error)) throw std::invalid_argument(error);
  threads_ = ResolveThreadCount(o_.threads);
  fs::create_directories(o_.out_dir);
  const fs::path store_path = o_.out_dir / "store.sqlite";
  if (!o_.resume) {
    for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(store_path.string() + suffix);
  }
  store_ = std::make_unique<ResultStore>(store_path);

  report_.title = "calib loop";
  report_.command = o_.command;
  report_.seed = o_.seed;
  Prepare();
  criterion_ = std::make_unique<KeepCriterion>(o_, recs_);
  calibrator_ = std::make_unique<StageCalibrator>(o_, recs_, scales_, *criterion_, *store_, threads_, log_);
  report_.selection_rule = fmt::format(
      "An effect is kept when, recalibrated with it on the training {}, it lowers the XOR of the "
      "held-out {} frame by frame by more than {:g}% of their error beyond what chance "
      "explains: a one-sided paired test of the per-frame differences (old model minus new, "
      "less that share of the old error), by random sign flips of blocks of "
      "consecutive frames (blocks twice the automatic length of Politis and White, at least 10 "
      "per recording; {} sign sets), corrected for every hypothesis the loop has tried by the "
      "Benjamini-Hochberg procedure at a false-discovery rate of {:g}%. The training XOR sum must "
      "not rise and the held-out mean IoU must not fall. The previous model is replaced by the "
      "previous model with the new calibration's values (the effect off) where that is better on "
      "training. Each round tries the {} best ranked hypotheses with confidence >= {:.2f} (ranked "
      "by {}) and keeps, of those that pass, the one with the largest held-out drop; the loop stops when none "
      "passes or {} effects are kept.",
      o_.holdout.empty() ? "frames" : "recordings",
      o_.holdout.empty()
          ? fmt::format("stretch of each training video (its last {:.0f}%)", 100.0 * o_.held_out_stretch)
          : std::string("recordings"),
      100.0 * o_.min_relative_drop,
      o_.test_resamples, 100.0 * o_.false_discovery_rate, o_.tries_per_round, o_.min_confidence,
      o_.rank_by_rate ? "the rate at which a hypothesis of the same effect and confidence was right "
                        "on the tuning family, that effect's count shrunk toward every effect's"
                      : "confidence",
      o_.max_effects);
  report_.notes.push_back(fmt::format(
      "base model: the best on the training recordings of {} independent search{} of {} "
      "evaluations ({})",
      o_.restarts, o_.restarts == 1 ? "" : "es", o_.budget,
      o_.restarts == 1 ? "from the box's centre"
                       : "the first from the box's centre, the others from seeded points of the box"));
  const SimulationOptions& sim = o_.simulation;
  report_.notes.push_back(fmt::format(
      "simulation: {} integrator, {} substeps per frame, {}, {}", ToString(sim.integrator),
      sim.substeps,
      sim.outline_contact ? "outline contact (obstacles keep out of the outline's edges and nodes)"
                          : "node contact (obstacles keep out of the nodes, the paper's)",
      sim.contact_friction > 0.0
          ? fmt::format("contact friction {:g}", sim.contact_friction)
          : std::string("frictionless contact")));
  for (const LoopRecording& r : recs_) {
    report_.notes.push_back(fmt::format("{}: segmentation noise {:.0f} px per frame ({} frames)",
                                        r.name, r.noise_px, r.prepared->scene.num_frames));
    if (r.prepared->motion_blur_frames > 0.0) {
      report_.notes.push_back(fmt::format(
          "{}: motion blur {:.3f} frames (the mask widens by that times the object's speed across its "
          "outline): the mesh is scored as the camera sees it, and a swing starts from the rest shape "
          "posed on frame 0",
          r.name, r.prepared->motion_blur_frames));
    }
  }

  int index = 1;
  Log(fmt::format("calibrating the base model ({} evaluations{}, {} threads)", o_.budget,
                  o_.restarts > 1 ? fmt::format(" in each of {} independent searches", o_.restarts) : "",
                  threads_));
  Fit current = calibrator_->Calibrate(index++, {}, nullptr);
  LogFitDiagnostics(current);
  calibrator_->MeasureEquallyGood(&current);
  calibrator_->MeasureSensitivity(&current);
  const Fit base = current;
  report_.stages.push_back(MakeStage(base, "", StageDecision::kBase));
  report_.stages.back().criterion = "held-out XOR sum";
  report_.stages.back().criterion_value = base.XorSum(recs_, false);
  report_.stages.back().reason =
      base.uninformative ? "the paper's base model; uninformative: its score does not depend on "
                           "its parameters (nothing moves the mesh)"
                         : "the paper's base model";
  AddResiduals(base);
  Log(fmt::format("base: training XOR {:.0f}, held-out XOR {:.0f} ({:.1f} s){}{}{}",
                  base.XorSum(recs_, true), base.XorSum(recs_, false), base.seconds,
                  EquallyGoodLine(base.equally_good), RestartsLine(base.restart_training_xor),
                  base.holdout_sensitivity_px > 0.0
                      ? fmt::format("; a 0.1% nudge of one value moves the held-out XOR by up "
                                    "to {:.0f} px ({})",
                                    base.holdout_sensitivity_px, base.holdout_sensitivity_parameter)
                      : std::string()));

  // Every hypothesis tried so far, in order: the p-values the
  // Benjamini-Hochberg correction runs over.
  std::vector<double> p_values;
  for (int round = 1; static_cast<int>(current.effects.size()) < o_.max_effects; ++round) {
    std::vector<std::vector<Hypothesis>> per_recording;
    for (size_t r = 0; r < recs_.size(); ++r) {
      if (recs_[r].train) per_recording.push_back(TraceHypotheses(current.residuals[r], current.effects));
    }
    // With rank_by_rate, in the order of how often such a hypothesis was
    // right on the tuning family (the table counts the first round's; later
    // rounds use it as it is).
    const std::vector<Hypothesis> ranked =
        o_.rank_by_rate ? RankedByRate(MergeHypotheses(per_recording), TuningFamilyConfidenceRates())
                        : MergeHypotheses(per_recording);
    report_.rounds.push_back({round, StageName(current.effects), ranked});
    Log(fmt::format("round {}: hypotheses from the residual of {}:\n{}", round,
                    StageName(current.effects), HypothesesReport(ranked)));

    std::vector<std::string> tries;
    for (const Hypothesis& h : ranked) {
      if (static_cast<int>(tries.size()) >= o_.tries_per_round) break;
      if (h.confidence >= o_.min_confidence) tries.push_back(h.effect);
    }
    if (tries.empty()) {
      report_.notes.push_back(fmt::format(
          "round {}: no hypothesis reaches confidence {:.2f}: the residual of {} is not traced "
          "to a missing effect",
          round, o_.min_confidence, StageName(current.effects)));
      Log(report_.notes.back());
      break;
    }
    std::vector<Fit> fits;
    std::vector<size_t> stage_index;
    std::vector<KeepCriterion::Verdict> verdicts;
    std::vector<size_t> p_index;
    // Each hypothesis is calibrated effect_restarts times; each calibration
    // is tested, and counts in the correction, on its own.
    std::vector<std::pair<std::string, int>> calibrations;
    for (const std::string& effect : tries) {
      for (int r = 0; r < o_.effect_restarts; ++r) calibrations.emplace_back(effect, r);
    }
    for (const auto& [effect, restart] : calibrations) {
      std::vector<std::string> effects = current.effects;
      effects.push_back(effect);
      const std::string which =
          o_.effect_restarts > 1 ? fmt::format(", calibration {} of {}", restart + 1, o_.effect_restarts)
                                 : std::string();
      Log(calibrator_->StartsCold(effects, current)
              ? fmt::format("round {}: calibrating {} from scratch, over horizons from two swing "
                            "periods (a first-order fit's stiffnesses are no start for a swing){}",
                            round, StageName(effects), which)
              : fmt::format("round {}: calibrating {} (warm start from {}{})", round,
                            StageName(effects), StageName(current.effects), which));
      Fit fit = calibrator_->Calibrate(index, effects, &current, restart);
      if (!fit.refit.empty()) Log(fmt::format("round {}: {}: {}", round, StageName(effects), fit.refit));
      LogFitDiagnostics(fit);
      calibrator_->MeasureEquallyGood(&fit);
      // The reference: the previous model, or the previous model with the
      // candidate's values (the effect switched off) where that is better
      // on the training recordings: a recalibration that found better base
      // values gives the effect no credit for them.
      Fit ablation;
      ablation.effects = current.effects;
      for (const auto& [name, value] : current.values) ablation.values[name] = fit.values.at(name);
      calibrator_->Measure(&ablation);
      const bool ablation_better =
          ablation.AllOk() && ablation.XorSum(recs_, true) < current.XorSum(recs_, true);
      KeepCriterion::Verdict v = criterion_->Judge(
          current, ablation_better ? &ablation : nullptr, fit, o_.seed * 1000 + static_cast<uint64_t>(index));
      // A hypothesis's calibrations share its stage index (their jobs and
      // seeds differ by restart), so its first is a loop's without restarts.
      if (restart + 1 == o_.effect_restarts) ++index;
      if (ablation_better) {
        v.reason = fmt::format(
            "against the previous model with this calibration's values and {} off (training "
            "XOR {:.0f} < {:.0f} of the previous fit): {}",
            effect, ablation.XorSum(recs_, true), current.XorSum(recs_, true), v.reason);
      }
      if (!fit.refit.empty()) v.reason = fmt::format("{}; {}", fit.refit, v.reason);
      p_index.push_back(p_values.size());
      p_values.push_back(v.test.p_value);
      ReportStage stage = MakeStage(fit, effect, StageDecision::kRejected);
      stage.restart = fit.restart;
      stage.criterion = "held-out XOR drop";
      stage.criterion_value = v.test.total;
      stage.test = {v.test.frames, v.test.blocks,  v.test.total, v.test.total_low,
                    v.test.total_high, v.test.p_value, 0, false};
      stage_index.push_back(report_.stages.size());
      report_.stages.push_back(std::move(stage));
      verdicts.push_back(std::move(v));
      fits.push_back(std::move(fit));
    }
    // The correction over every hypothesis tried so far decides this round.
    const std::vector<bool> significant = BenjaminiHochberg(p_values, o_.false_discovery_rate);
    int best = -1;
    for (size_t i = 0; i < fits.size(); ++i) {
      const KeepCriterion::Verdict& v = verdicts[i];
      ReportStage& stage = report_.stages[stage_index[i]];
      stage.test.hypotheses = static_cast<int>(p_values.size());
      stage.test.significant = significant[p_index[i]];
      const bool pass = v.eligible && stage.test.significant;
      stage.reason = fmt::format(
          "{}; Benjamini-Hochberg over the {} hypotheses tried so far at a false-discovery rate "
          "of {:g}%: {}",
          v.reason, p_values.size(), 100.0 * o_.false_discovery_rate,
          stage.test.significant ? "significant" : "not significant");
      if (pass && (best < 0 || v.test.total > verdicts[static_cast<size_t>(best)].test.total)) {
        best = static_cast<int>(i);
      }
      Log(fmt::format("round {}: {}{}: {}{}", round, StageName(fits[i].effects),
                      o_.effect_restarts > 1 ? fmt::format(" (calibration {})", fits[i].restart + 1)
                                             : std::string(),
                      stage.reason, EquallyGoodLine(fits[i].equally_good)));
    }
    if (best < 0) {
      AddConfusions(round, ranked, stage_index);
      report_.notes.push_back(fmt::format("round {}: none of {} tried passes the criterion: stop",
                                          round, fmt::join(tries, ", ")));
      Log(report_.notes.back());
      break;
    }
    AddConfusions(round, ranked, stage_index);
    ReportStage& kept = report_.stages[stage_index[best]];
    kept.decision = StageDecision::kAccepted;
    kept.reason += "; the largest passing drop of this round: kept";
    for (size_t i = 0; i < fits.size(); ++i) {
      if (static_cast<int>(i) != best && verdicts[i].eligible && report_.stages[stage_index[i]].test.significant) {
        report_.stages[stage_index[i]].reason +=
            fits[i].effects.back() == fits[best].effects.back()
                ? fmt::format("; passes, but calibration {} of {} drops more: not kept",
                              fits[best].restart + 1, fits[best].effects.back())
                : fmt::format("; passes, but {} drops more: not kept", fits[best].effects.back());
      }
    }
    current = std::move(fits[best]);
    report_.effects_kept = current.effects;
    AddResiduals(current);
    Log(fmt::format("round {}: kept {}{}", round, current.effects.back(),
                    EquallyGoodLine(current.equally_good)));
  }
  if (!current.effects.empty()) {
    // How smooth the final model's held-out error is in its values.
    calibrator_->MeasureSensitivity(&current);
    for (ReportStage& s : report_.stages) {
      if (s.decision == StageDecision::kAccepted && s.effects == current.effects) {
        s.holdout_sensitivity_px = current.holdout_sensitivity_px;
        s.holdout_sensitivity_parameter = current.holdout_sensitivity_parameter;
      }
    }
  }

  AddOverlays(base, "base");
  if (!current.effects.empty()) AddOverlays(current, StageName(current.effects));
  report_.run_time_s = Since(start);

  LoopResult result;
  result.store = store_path;
  result.report_json = o_.out_dir / "report.json";
  if (o_.write_html) {
    WriteLoopReport(o_.out_dir, report_);
    result.report_html = o_.out_dir / "report.html";
  } else {
    WriteLoopReportJson(result.report_json, report_);
  }
  result.table = BeforeAfterTable(report_);
  result.report = std::move(report_);
  return result;
}

}  // namespace

LoopResult RunLoop(const LoopOptions& options, const LoopLog& log) {
  return Loop(options, log).Run();
}

std::string BeforeAfterTable(const LoopReport& report) {
  const ReportStage* base = report.BaseStage();
  const ReportStage* final_stage = report.FinalStage();
  if (base == nullptr || final_stage == nullptr) return "no calibrated model\n";
  std::string out = fmt::format("{:<22} {:<8} {:>12} {:>12} {:>8} {:>9} {:>9}\n", "recording", "role",
                                "XOR base", "XOR final", "change", "IoU base", "IoU final");
  for (const ReportRecording& rec : report.recordings) {
    const RecordingScore* b = base->ErrorOn(rec.name);
    const RecordingScore* f = final_stage->ErrorOn(rec.name);
    if (b == nullptr || f == nullptr) continue;
    const double change = b->xor_sum > 0 ? 100.0 * (double(f->xor_sum) - double(b->xor_sum)) / double(b->xor_sum) : 0.0;
    out += fmt::format("{:<22} {:<8} {:>12.0f} {:>12.0f} {:>7.1f}% {:>9.4f} {:>9.4f}\n", rec.name, rec.role,
                       b->xor_sum, f->xor_sum, change, b->mean_iou, f->mean_iou);
  }
  // Against the mesh registered to the video: what a model falls short of
  // there is its motion; what the registered mesh itself misses, no model
  // of this mesh covers.
  for (const ReportRecording& rec : report.recordings) {
    const RecordingScore* f = final_stage->ErrorOn(rec.name);
    if (rec.registered_iou.empty() || f == nullptr || f->frame_iou.empty()) continue;
    const auto mean = [](const std::vector<double>& v, size_t count) {
      count = std::min(count, v.size());
      return count == 0 ? 0.0 : std::accumulate(v.begin(), v.begin() + count, 0.0) / count;
    };
    const size_t second = static_cast<size_t>(std::max(1L, std::lround(rec.fps)));
    out += fmt::format(
        "{}: mean IoU {:.4f} (first second {:.4f}); the mesh registered to the video "
        "{:.4f} ({:.4f})\n",
        rec.name, mean(f->frame_iou, f->frame_iou.size()), mean(f->frame_iou, second),
        mean(rec.registered_iou, rec.registered_iou.size()), mean(rec.registered_iou, second));
  }
  std::vector<std::string> tried;
  for (const ReportStage& s : report.stages) {
    if (!s.effect_tried.empty()) tried.push_back(fmt::format("{} ({})", s.effect_tried, ToString(s.decision)));
  }
  out += fmt::format("effects tried: {}\n", tried.empty() ? std::string("none") : fmt::format("{}", fmt::join(tried, ", ")));
  out += fmt::format("effects kept: {}\n", report.effects_kept.empty()
                                               ? std::string("none")
                                               : fmt::format("{}", fmt::join(report.effects_kept, ", ")));
  return out;
}

}  // namespace calib
