// The closed loop (loop.h, docs/loop.md).

#include "calib/discovery/loop.h"

#include "calib/core/model_definition.h"
#include "calib/discovery/report_html.h"
#include "calib/discovery/report_overlays.h"
#include "calib/jobs/batch_evaluator.h"
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
  if (!(noise_factor >= 0.0) || !std::isfinite(noise_factor)) {
    return fail(fmt::format("loop: noise factor = {}: must be finite and >= 0", noise_factor));
  }
  if (!(min_relative_gain >= 0.0 && min_relative_gain < 1.0)) {
    return fail(fmt::format("loop: minimum relative gain = {}: must be in [0, 1)", min_relative_gain));
  }
  if (equally_good_fits < 0) {
    return fail(fmt::format("loop: --equally-good-fits = {}: must be >= 0", equally_good_fits));
  }
  if (restarts < 1) return fail(fmt::format("loop: --restarts = {}: must be >= 1", restarts));
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
  ReportStage MakeStage(const Fit& fit, const std::string& tried, StageDecision decision) const;
  void AddResiduals(const Fit& fit);
  void AddOverlays(const Fit& fit, const std::string& stage);

  const LoopOptions& o_;
  const LoopLog& log_;
  std::vector<LoopRecording> recs_;
  SearchScales scales_;
  std::unique_ptr<ResultStore> store_;
  int threads_ = 1;
  LoopReport report_;
  std::unique_ptr<KeepCriterion> criterion_;
  std::unique_ptr<StageCalibrator> calibrator_;
};

void Loop::Prepare() {
  std::set<std::string> names;
  auto add = [&](const fs::path& path, bool train) {
    LoopRecording r;
    r.path = path;
    r.train = train;
    Log(fmt::format("preparing {} ({})", path.string(), train ? "train" : "held out"));
    r.prepared = std::make_shared<const PreparedRecording>(
        PrepareRecording(LoadRecording(path), o_.preparation));
    const std::string name = RecordingDisplayName(r.prepared->recording.folder);
    r.name = name;
    for (int k = 2; names.count(r.name) != 0; ++k) r.name = fmt::format("{}_{}", name, k);
    names.insert(r.name);
    r.noise_px = SegmentationNoisePx(r.prepared->object_masks);
    r.residual_facts = std::make_shared<const RecordingResidualFacts>(ComputeResidualFacts(*r.prepared));
    recs_.push_back(std::move(r));
  };
  for (const fs::path& p : o_.train) add(p, true);
  for (const fs::path& p : o_.holdout) add(p, false);

  std::vector<std::shared_ptr<const PreparedRecording>> training;
  for (const LoopRecording& r : recs_) {
    if (r.train) training.push_back(r.prepared);
  }
  scales_ = TrainingScales(training, o_.simulation);
  for (const LoopRecording& r : recs_) {
    report_.recordings.push_back({r.name, r.path.string(), r.train ? "train" : "holdout",
                                  r.prepared->scene.num_frames, r.prepared->recording.fps});
  }
}

ReportStage Loop::MakeStage(const Fit& fit, const std::string& tried, StageDecision decision) const {
  ReportStage s;
  s.name = StageName(fit.effects);
  s.effect_tried = tried;
  s.decision = decision;
  s.effects = fit.effects;
  s.parameters = fit.values;
  for (size_t r = 0; r < recs_.size(); ++r) {
    s.errors.push_back(RecordingScore::FromEvaluation(recs_[r].name, fit.results[r]));
  }
  s.calibration_time_s = fit.seconds;
  s.evaluations = fit.evaluations;
  s.equally_good = fit.equally_good;
  s.holdout_sensitivity_px = fit.holdout_sensitivity_px;
  if (fit.restart_training_xor.size() > 1) s.restart_training_xor = fit.restart_training_xor;
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

LoopResult Loop::Run() {
  const Clock::time_point start = Clock::now();
  std::string error;
  if (!o_.IsValid(&error)) throw std::invalid_argument(error);
  threads_ = ResolveThreadCount(o_.threads);
  fs::create_directories(o_.out_dir);
  const fs::path store_path = o_.out_dir / "store.sqlite";
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(store_path.string() + suffix);
  store_ = std::make_unique<ResultStore>(store_path);

  report_.title = "calib loop";
  report_.command = o_.command;
  report_.seed = o_.seed;
  Prepare();
  criterion_ = std::make_unique<KeepCriterion>(o_, recs_, scales_);
  calibrator_ = std::make_unique<StageCalibrator>(o_, recs_, scales_, *criterion_, *store_, threads_, log_);
  const bool holdout = criterion_->HasHoldout();
  report_.selection_rule =
      holdout
          ? fmt::format(
                "An effect is kept when, recalibrated with it, the held-out XOR sum (summed over "
                "the held-out recordings and frames) drops by more than max({} x (1 + p) x N, "
                "{:.0f}% of the held-out XOR sum before), where p is the number of parameters the "
                "effect adds and N the held-out recordings' segmentation noise (per frame the "
                "object pixels that flicker for one frame, mean over frames, summed over "
                "frames), the training XOR sum does not rise and the held-out mean IoU does not "
                "fall by more than the margin makes (the margin over the held-out object "
                "pixels; the XOR sum also drops when a mesh leaves an object it overlaps "
                "poorly). "
                "The drop must pass both at the models' best training fits and between the "
                "medians over their equally good fits (fits equally good on training differ on "
                "held-out data): up to {} of a calibration's parameter sets whose training XOR "
                "sum exceeds the best by less than max({} x the training recordings' "
                "segmentation noise, {:.0f}% of it), re-scored on the held-out recordings. The "
                "previous model is replaced by the previous model with the new calibration's "
                "values (the effect off) where that is better on training. Each round tries the {} best ranked hypotheses with confidence >= "
                "{:.2f} and keeps the one with the largest held-out drop that passes; the loop "
                "stops when none passes or {} effects are kept.",
                o_.noise_factor, 100.0 * o_.min_relative_gain, o_.equally_good_fits,
                o_.noise_factor, 100.0 * o_.min_relative_gain, o_.tries_per_round,
                o_.min_confidence, o_.max_effects)
          : fmt::format(
                "No held-out recording: an effect is kept when the Bayesian information criterion "
                "of the per-frame training XOR (n ln(SSE / n) + k ln n over all training frames, "
                "k searched parameters) falls and the training XOR sum drops by more than "
                "max({} x (1 + p) x N, {:.0f}% of it) (N: the training recordings' segmentation "
                "noise, p: parameters added). Each round tries the {} best ranked hypotheses with "
                "confidence >= {:.2f}; the loop stops when none passes or {} effects are kept.",
                o_.noise_factor, 100.0 * o_.min_relative_gain, o_.tries_per_round,
                o_.min_confidence, o_.max_effects);
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
  }

  int index = 1;
  Log(fmt::format("calibrating the base model ({} evaluations{}, {} threads)", o_.budget,
                  o_.restarts > 1 ? fmt::format(" in each of {} independent searches", o_.restarts) : "",
                  threads_));
  Fit current = calibrator_->Calibrate(index++, {}, nullptr);
  calibrator_->MeasureEquallyGood(&current);
  calibrator_->MeasureSensitivity(&current);
  const Fit base = current;
  report_.stages.push_back(MakeStage(base, "", StageDecision::kBase));
  report_.stages.back().criterion = holdout ? "held-out XOR sum" : "training XOR sum";
  report_.stages.back().criterion_value =
      static_cast<double>(base.XorSum(recs_, !holdout));
  report_.stages.back().reason = "the paper's base model";
  AddResiduals(base);
  Log(fmt::format("base: training XOR {:.0f}, held-out XOR {:.0f} ({:.1f} s){}{}{}", base.XorSum(recs_, true),
                  base.XorSum(recs_, false), base.seconds, EquallyGoodLine(base.equally_good),
                  RestartsLine(base.restart_training_xor),
                  holdout ? fmt::format("; a 0.1% nudge of its values moves the held-out XOR by up "
                                        "to {:.0f} px",
                                        base.holdout_sensitivity_px)
                          : std::string()));

  std::set<std::string> rejected_with;  // "model|effect" pairs tried
  for (int round = 1; static_cast<int>(current.effects.size()) < o_.max_effects; ++round) {
    std::vector<std::vector<Hypothesis>> per_recording;
    for (size_t r = 0; r < recs_.size(); ++r) {
      if (recs_[r].train) per_recording.push_back(TraceHypotheses(current.residuals[r], current.effects));
    }
    const std::vector<Hypothesis> ranked = MergeHypotheses(per_recording);
    report_.rounds.push_back({round, StageName(current.effects), ranked});
    Log(fmt::format("round {}: hypotheses from the residual of {}:\n{}", round,
                    StageName(current.effects), HypothesesReport(ranked)));

    std::vector<std::string> tries;
    for (const Hypothesis& h : ranked) {
      if (static_cast<int>(tries.size()) >= o_.tries_per_round) break;
      if (h.confidence < o_.min_confidence) break;
      tries.push_back(h.effect);
    }
    if (tries.empty()) {
      report_.notes.push_back(fmt::format(
          "round {}: no hypothesis reaches confidence {:.2f}: the residual of {} is not traced "
          "to a missing effect",
          round, o_.min_confidence, StageName(current.effects)));
      Log(report_.notes.back());
      break;
    }
    int best = -1;
    double best_gain = 0.0;
    std::vector<Fit> fits;
    std::vector<size_t> stage_index;
    std::vector<uint8_t> passed;
    for (const std::string& effect : tries) {
      std::vector<std::string> effects = current.effects;
      effects.push_back(effect);
      Log(fmt::format("round {}: calibrating {} (warm start from {})", round, StageName(effects),
                      StageName(current.effects)));
      Fit fit = calibrator_->Calibrate(index++, effects, &current);
      calibrator_->MeasureEquallyGood(&fit);
      calibrator_->MeasureSensitivity(&fit);
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
      SearchScales scales = scales_;
      scales.reference = current.values;
      const int extra = SearchSpace(StageParameterSettings({effect}, scales)).dimension() -
                        SearchSpace(StageParameterSettings({}, scales)).dimension();
      KeepCriterion::Verdict v =
          criterion_->Judge(current, ablation_better ? &ablation : nullptr, fit, extra);
      if (ablation_better) {
        v.reason = fmt::format(
            "against the previous model with this calibration's values and {} off (training "
            "XOR {:.0f} < {:.0f} of the previous fit): {}",
            effect, ablation.XorSum(recs_, true), current.XorSum(recs_, true), v.reason);
      }
      ReportStage stage = MakeStage(fit, effect, StageDecision::kRejected);
      stage.criterion = v.criterion;
      stage.criterion_value = v.gain;
      stage.reason = v.reason;
      Log(fmt::format("round {}: {}: {}{}", round, StageName(effects), v.reason,
                      EquallyGoodLine(fit.equally_good)));
      stage_index.push_back(report_.stages.size());
      report_.stages.push_back(std::move(stage));
      passed.push_back(v.pass ? 1 : 0);
      if (v.pass && (best < 0 || v.gain > best_gain)) {
        best = static_cast<int>(fits.size());
        best_gain = v.gain;
      }
      fits.push_back(std::move(fit));
    }
    if (best < 0) {
      report_.notes.push_back(fmt::format("round {}: none of {} tried passes the criterion: stop",
                                          round, fmt::join(tries, ", ")));
      Log(report_.notes.back());
      break;
    }
    ReportStage& kept = report_.stages[stage_index[best]];
    kept.decision = StageDecision::kAccepted;
    kept.reason += "; the largest passing drop of this round: kept";
    for (size_t i = 0; i < fits.size(); ++i) {
      if (static_cast<int>(i) != best && passed[i] != 0) {
        report_.stages[stage_index[i]].reason += fmt::format(
            "; passes, but {} drops more: not kept", fits[best].effects.back());
      }
    }
    current = std::move(fits[best]);
    report_.effects_kept = current.effects;
    AddResiduals(current);
    Log(fmt::format("round {}: kept {}{}", round, current.effects.back(),
                    EquallyGoodLine(current.equally_good)));
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
