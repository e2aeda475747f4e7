// The closed loop (loop.h, docs/loop.md).

#include "calib/jobs/loop.h"

#include "calib/core/model_definition.h"
#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/runner.h"
#include "calib/results/report_html.h"
#include "calib/results/report_overlays.h"
#include "calib/results/store.h"

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

double IouTolerance(double margin_px, const std::vector<const std::vector<BitMask>*>& held_out_masks) {
  double object_px = 0.0;
  for (const std::vector<BitMask>* masks : held_out_masks) {
    for (const BitMask& m : *masks) object_px += static_cast<double>(m.Count());
  }
  return object_px > 0.0 ? std::max(margin_px, 0.0) / object_px : 0.0;
}

// =========================================================================
// Search boxes.

namespace {

ParameterSetting Searched(const std::string& name, double lower, double upper,
                          ParameterScale scale) {
  ParameterSetting s;
  s.name = name;
  s.lower = lower;
  s.upper = upper;
  s.scale = scale;
  return s;
}

ParameterSetting Fixed(const std::string& name, double value) {
  ParameterSetting s;
  s.name = name;
  s.fixed = value;
  return s;
}

// The base model's mass, fixed: with the first-order integrator only
// stiffness / mass ratios matter.
constexpr double kLoopMass = 0.2;

// Loop::MeasureSensitivity: nudges of every value by this relative amount,
// their signs drawn (by RestartStart) from the loop's seed plus this offset,
// a stream apart from the restarts'.
constexpr int kSensitivityNudges = 4;
constexpr double kSensitivityNudge = 1e-3;
constexpr uint64_t kSensitivitySeedOffset = 7919;

double Finite(double v, double fallback) { return std::isfinite(v) && v > 0.0 ? v : fallback; }


}  // namespace

SimulationOptions LoopSimulationDefaults() {
  SimulationOptions o;
  o.integrator = IntegratorKind::kImplicitFirstOrder;
  o.outline_contact = true;
  o.contact_friction = 0.5;
  return o;
}

double ModelDragForce(const Mesh& mesh, const Scene& scene, double mass) {
  double speed = 0.0;
  for (int f = 1; f < scene.num_frames; ++f) {
    for (int k = 0; k < scene.num_obstacles; ++k) {
      const double step =
          (scene.ObstaclesAt(f)[k].centre - scene.ObstaclesAt(f - 1)[k].centre).norm();
      speed = std::max(speed, step / scene.frame_time_s);
    }
  }
  return mesh.NumNodes() * mass * speed;
}

std::vector<ParameterSetting> LoopParameterSettings(const std::vector<std::string>& effects,
                                                    const LoopScales& scales,
                                                    const ParameterValues& reference) {
  using enum ParameterScale;
  // The base model: with the first-order integrator only stiffness / mass
  // ratios matter, so the mass is fixed and the stiffnesses are searched on
  // wide log scales (a wider box than the bundled example job's: effects
  // move the best stiffnesses).
  const double stiff = scales.integrator == IntegratorKind::kImplicitFirstOrder ? 100.0 : 1.0;
  std::vector<ParameterSetting> out = {
      Searched("k_D", 10, 1e5 * stiff, kLog),  Searched("k_d", 1e-3, 100 * stiff, kLog),
      Searched("k_A", 0.1, 1e5 * stiff, kLog), Searched("k_phi", 0.01, 1e4 * stiff, kLog),
      Fixed("mass", kLoopMass),                Searched("tau", 0, 0.5, kLinear)};
  const double force = Finite(scales.peak_force, 1.0);
  const double drag = Finite(scales.drag_force, force);
  const double fps = Finite(scales.fps, 30.0);
  const double duration = Finite(scales.duration_s, 1.0);
  // Gravity 9.81 m/s^2 in pixels; an unknown scale is taken as 0.25 mm/px
  // (the box reaches twice that, so any scale down to 0.125 mm/px fits).
  const double g_px = 9810.0 / Finite(scales.mm_per_px, 0.25);
  auto ref = [&](const char* name, double fallback) {
    const auto it = reference.find(name);
    return it != reference.end() ? Finite(it->second, fallback) : fallback;
  };
  const double k_d = ref("k_D", 100.0);
  for (const std::string& effect : effects) {
    if (effect == "inertia") {
      out.push_back(Searched("inertia_damping_per_s", 0.1, 2.0 * fps, kLog));
      out.push_back(Searched("gravity_px_s2", 0.0, 2.0 * g_px, kLinear));
      out.push_back(Searched("gravity_angle_deg", -180.0, 180.0, kLinear));
    } else if (effect == "table_friction") {
      // Friction competes with the model's drag, not with the sensor's
      // reading: on the bundled pushes 2 x the peak reading (~3) holds a
      // node back by 1e-4 px a substep where the finger moves it 0.1 px.
      out.push_back(Searched("friction_force", 1e-3 * drag, 2.0 * drag, kLog));
    } else if (effect == "plasticity") {
      out.push_back(Searched("plastic_yield_strain", 0.005, 0.5, kLog));
      out.push_back(Searched("plastic_rate_per_s", 0.05, 50.0, kLog));
    } else if (effect == "uneven_stiffness") {
      out.push_back(Searched("uneven_gradient", 0.0, 0.9, kLinear));
      out.push_back(Searched("uneven_angle_deg", -180.0, 180.0, kLinear));
    } else if (effect == "strain_stiffening") {
      out.push_back(Searched("stiffening_k3", 1e-2 * k_d, 1e4 * k_d, kLog));
    } else if (effect == "viscoelastic") {
      out.push_back(Searched("visco_share", 0.0, 0.9, kLinear));
      out.push_back(Searched("visco_time_s", 1.0 / fps, std::max(2.0 * duration, 10.0 / fps), kLog));
    } else if (effect == "push_relaxation") {
      out.push_back(Searched("push_friction_force", 1e-3 * force, 2.0 * force, kLog));
    } else {
      throw std::invalid_argument(
          fmt::format("loop: effect '{}' has no search box (known: {})", effect, EffectNames()));
    }
  }
  return out;
}

std::vector<double> RestartStart(int dimension, uint64_t seed, int restart) {
  std::vector<double> x(static_cast<size_t>(std::max(dimension, 0)), 0.5);
  if (restart <= 0) return x;
  // SplitMix64 (Steele, Lea & Flood 2014): a fixed sequence on every
  // platform, unlike the standard library's distributions.
  uint64_t state = seed * 0x9E3779B97F4A7C15ULL + static_cast<uint64_t>(restart);
  for (double& u : x) {
    uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    z ^= z >> 31;
    u = 0.1 + 0.8 * static_cast<double>(z >> 11) * 0x1.0p-53;
  }
  return x;
}

double NeutralValue(const ParameterSetting& s) {
  if (s.fixed) return *s.fixed;
  // Parameters whose neutral value is not their lower bound.
  if (s.name == "inertia_damping_per_s") return s.upper;  // overdamped: closest to first order
  if (s.name == "gravity_angle_deg") return 90.0;          // down the image (irrelevant at g = 0)
  if (s.name == "uneven_angle_deg") return 0.0;            // irrelevant at gradient 0
  // Where the effect's strength is 0, its other parameters start in the
  // middle of their (log) box, where the search can reach any value.
  if (s.name == "plastic_yield_strain") return std::sqrt(s.lower * s.upper);
  if (s.name == "visco_time_s") return std::sqrt(s.lower * s.upper);  // irrelevant at share 0
  return s.lower;
}

std::vector<ParameterValues> SelectEquallyGoodFits(const std::vector<EvaluationRecord>& evaluations,
                                                   double tolerance, int limit) {
  std::vector<const EvaluationRecord*> ok;
  for (const EvaluationRecord& e : evaluations) {
    if (e.ok && std::isfinite(e.score)) ok.push_back(&e);
  }
  if (ok.empty() || limit <= 0) return {};
  std::stable_sort(ok.begin(), ok.end(),
                   [](const EvaluationRecord* a, const EvaluationRecord* b) { return a->score < b->score; });
  const double cutoff = ok.front()->score + std::max(tolerance, 0.0);
  std::vector<const ParameterValues*> distinct;
  for (const EvaluationRecord* e : ok) {
    if (e->score > cutoff) break;
    const bool seen = std::any_of(distinct.begin(), distinct.end(),
                                  [&](const ParameterValues* p) { return *p == e->parameters; });
    if (!seen) distinct.push_back(&e->parameters);
  }
  std::vector<ParameterValues> out;
  const size_t n = distinct.size();
  const size_t take = std::min(n, static_cast<size_t>(limit));
  for (size_t i = 0; i < take; ++i) {
    // Ranks 0, ..., n - 1 spread evenly: i (n - 1) / (take - 1), rounded down.
    const size_t rank = take == 1 ? 0 : i * (n - 1) / (take - 1);
    out.push_back(*distinct[rank]);
  }
  return out;
}

namespace {

std::string RecordingName(const PreparedRecording& prepared) {
  std::string name = prepared.recording.folder.filename().string();
  if (name.empty()) name = prepared.recording.folder.parent_path().filename().string();
  return name.empty() ? prepared.recording.folder.string() : name;
}

}  // namespace

// =========================================================================
// Segmentation noise.

double SegmentationNoisePx(const std::vector<BitMask>& masks) {
  if (masks.size() < 3) return 0.0;
  std::vector<double> flicker;
  for (size_t f = 1; f + 1 < masks.size(); ++f) {
    const auto& a = masks[f - 1].words();
    const auto& b = masks[f].words();
    const auto& c = masks[f + 1].words();
    if (a.size() != b.size() || b.size() != c.size()) {
      throw std::invalid_argument(
          fmt::format("segmentation noise: masks {} .. {} differ in shape", f - 1, f + 1));
    }
    int64_t n = 0;
    for (size_t w = 0; w < b.size(); ++w) n += std::popcount((a[w] ^ b[w]) & ~(a[w] ^ c[w]));
    flicker.push_back(static_cast<double>(n));
  }
  double sum = 0.0;
  for (double v : flicker) sum += v;
  return sum / static_cast<double>(flicker.size());
}

// =========================================================================
// The loop.

namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

struct LoopRecording {
  std::string name;
  fs::path path;
  bool train = true;
  std::shared_ptr<const PreparedRecording> prepared;
  double noise_px = 0.0;  ///< SegmentationNoisePx
  std::shared_ptr<const RecordingResidualFacts> residual_facts;  ///< shared by every fit's analysis
};

// One calibrated model and how it does everywhere.
struct Fit {
  std::vector<std::string> effects;
  ParameterValues values;
  std::vector<EvaluationResult> results;     ///< per recording (loop order)
  std::vector<ResidualAnalysis> residuals;   ///< per recording
  int evaluations = 0;
  double seconds = 0.0;
  std::vector<int64_t> jobs;  ///< the store's jobs of its calibration
  std::vector<double> restart_training_xor;  ///< from scratch: each search's best
  EquallyGoodFits equally_good;  ///< MeasureEquallyGood; fits == 0 until then
  /// MeasureSensitivity: how far the held-out XOR sum moves when every
  /// value moves by kSensitivityNudge (px; 0 until measured).
  double holdout_sensitivity_px = 0.0;

  int64_t XorSum(const std::vector<LoopRecording>& recs, bool train) const {
    int64_t s = 0;
    for (size_t r = 0; r < recs.size(); ++r) {
      if (recs[r].train == train) s += results[r].ok() ? results[r].xor_sum : INT64_MAX / 64;
    }
    return s;
  }
  bool AllOk() const {
    return std::all_of(results.begin(), results.end(), [](const EvaluationResult& e) { return e.ok(); });
  }
};

std::string EquallyGoodLine(const EquallyGoodFits& g) {
  if (g.fits == 0) return "";
  return fmt::format("; {} equally good fits: held-out XOR {} to {}, median {}", g.fits,
                     g.holdout_xor_min, g.holdout_xor_max, g.holdout_xor_median);
}

std::string RestartsLine(const std::vector<double>& training_xor) {
  if (training_xor.size() < 2) return "";
  return fmt::format("; best training XOR of each of {} searches: {:.0f}", training_xor.size(),
                     fmt::join(training_xor, ", "));
}

std::string StageName(const std::vector<std::string>& effects) {
  return ModelDefinition{effects}.ToString();
}

std::string JobName(int index, const std::vector<std::string>& effects) {
  std::string name = fmt::format("stage{}-base", index);
  for (const std::string& e : effects) name += "." + e;
  return name;
}

json OptimizerSettings(const std::string& optimizer, int dimension, const std::vector<double>* x0,
                       double sigma, int64_t budget) {
  json settings = json::object();
  if (optimizer == "cmaes") {
    // Generations of 4 + 3 ln n candidates (the CMA-ES default), at least
    // 8 so that two threads and more stay busy.
    // (never more than the budget).
    const int64_t population = std::max(8, 4 + static_cast<int>(3.0 * std::log(dimension)));
    settings["population"] = std::max<int64_t>(2, std::min(population, budget));
    settings["initial_sigma"] = sigma;
    if (x0 != nullptr) settings["x0"] = *x0;
  } else if (optimizer.rfind("nlopt:", 0) == 0 && x0 != nullptr) {
    settings["x0"] = *x0;
  }
  return settings;
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
  Fit Calibrate(int index, const std::vector<std::string>& effects, const Fit* warm);
  // The job's best values and training score; empty values and +inf
  // where no candidate simulated every training recording.
  std::pair<ParameterValues, double> RunJob(const std::string& name,
                                            const std::vector<std::string>& effects,
                                            const std::vector<ParameterSetting>& settings,
                                            const std::vector<double>* x0, double sigma,
                                            int64_t budget, uint64_t seed, Fit* fit);
  double TrainingScore(const std::vector<std::string>& effects, const ParameterValues& values) const;
  void Measure(Fit* fit) const;
  void MeasureEquallyGood(Fit* fit) const;
  void MeasureSensitivity(Fit* fit) const;
  std::vector<int> HeldOutIndices() const;
  std::vector<EvaluationResult> ScoreOnHeldOut(const std::vector<ParameterValues>& sets,
                                               const std::vector<std::string>& effects) const;
  ReportStage MakeStage(const Fit& fit, const std::string& tried, StageDecision decision) const;
  void AddResiduals(const Fit& fit);
  void AddOverlays(const Fit& fit, const std::string& stage);
  struct Verdict {
    bool pass = false;
    double gain = 0.0;       ///< drop of the deciding error (px)
    double margin = 0.0;     ///< what it had to exceed
    std::string criterion;
    std::string reason;
  };
  Verdict Judge(const Fit& previous, const Fit* ablation, const Fit& candidate,
                int extra_parameters) const;
  bool HasHoldout() const {
    return std::any_of(recs_.begin(), recs_.end(), [](const LoopRecording& r) { return !r.train; });
  }
  double NoiseBudget(bool train) const {
    double b = 0.0;
    for (const LoopRecording& r : recs_) {
      if (r.train == train) b += r.noise_px * r.prepared->scene.num_frames;
    }
    return b;
  }
  /// What a drop of the training (`train`) or held-out XOR sum `before` must
  /// exceed to count: max(noise_factor x (1 + extra parameters) x the
  /// recordings' segmentation noise, min_relative_gain x before).
  double Margin(bool train, int extra_parameters, double before) const {
    return std::max(o_.noise_factor * (1 + extra_parameters) * NoiseBudget(train),
                    o_.min_relative_gain * before);
  }

  std::vector<const std::vector<BitMask>*> HeldOutMasks() const {
    std::vector<const std::vector<BitMask>*> out;
    for (const LoopRecording& r : recs_) {
      if (!r.train) out.push_back(&r.prepared->object_masks);
    }
    return out;
  }

  const LoopOptions& o_;
  const LoopLog& log_;
  std::vector<LoopRecording> recs_;
  LoopScales scales_;
  std::unique_ptr<ResultStore> store_;
  int threads_ = 1;
  LoopReport report_;
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
    r.name = RecordingName(*r.prepared);
    for (int k = 2; names.count(r.name) != 0; ++k) r.name = fmt::format("{}_{}", RecordingName(*r.prepared), k);
    names.insert(r.name);
    r.noise_px = SegmentationNoisePx(r.prepared->object_masks);
    r.residual_facts = std::make_shared<const RecordingResidualFacts>(ComputeResidualFacts(*r.prepared));
    recs_.push_back(std::move(r));
  };
  for (const fs::path& p : o_.train) add(p, true);
  for (const fs::path& p : o_.holdout) add(p, false);

  bool first = true;
  for (const LoopRecording& r : recs_) {
    if (!r.train) continue;
    const Recording& rec = r.prepared->recording;
    for (const Vec2& f : rec.forces) scales_.peak_force = std::max(scales_.peak_force, f.norm());
    scales_.drag_force = std::max(scales_.drag_force, ModelDragForce(r.prepared->mesh, r.prepared->scene, kLoopMass));
    scales_.duration_s = std::max(scales_.duration_s * (first ? 0.0 : 1.0),
                                  rec.num_frames / std::max(rec.fps, 1e-9));
    if (first) {
      scales_.fps = rec.fps;
      scales_.mm_per_px = rec.mm_per_px.value_or(0.0);
    }
    scales_.integrator = o_.simulation.integrator;
    first = false;
  }
  for (const LoopRecording& r : recs_) {
    report_.recordings.push_back({r.name, r.path.string(), r.train ? "train" : "holdout",
                                  r.prepared->scene.num_frames, r.prepared->recording.fps});
  }
}

// One calibration job of the store: `settings` searched by the loop's
// optimiser (from x0 with initial_sigma when given), `budget` evaluations.
// Returns the best record's values and score.
std::pair<ParameterValues, double> Loop::RunJob(const std::string& name,
                                                const std::vector<std::string>& effects,
                                                const std::vector<ParameterSetting>& settings,
                                                const std::vector<double>* x0, double sigma,
                                                int64_t budget, uint64_t seed, Fit* fit) {
  const SearchSpace space(settings);
  json doc = json::object();
  doc["name"] = name;
  doc["train"] = json::array();
  doc["holdout"] = json::array();
  for (const LoopRecording& r : recs_) {
    doc[r.train ? "train" : "holdout"].push_back(fs::absolute(r.path).string());
  }
  const SimulationOptions& sim = o_.simulation;
  doc["model"] = {{"effects", effects},
                  {"substeps", sim.substeps},
                  {"integrator", ToString(sim.integrator)},
                  {"constraint_iterations", sim.constraint_iterations},
                  {"outline_contact", sim.outline_contact},
                  {"contact_friction", sim.contact_friction},
                  {"min_area_fraction", sim.min_area_fraction},
                  {"divergence_diameters", sim.divergence_diameters},
                  {"segmentation",
                   {{"open_radius_px", o_.preparation.segmentation.open_radius_px},
                    {"close_radius_px", o_.preparation.segmentation.close_radius_px},
                    {"fill_holes", o_.preparation.segmentation.fill_holes}}},
                  {"mesh", {{"edge_length_px", o_.preparation.mesher.edge_length_px}}},
                  {"outline_tolerance_px", o_.preparation.outline_tolerance_px}};
  doc["parameters"] = json::array();
  for (const ParameterSetting& s : settings) {
    if (s.fixed) {
      doc["parameters"].push_back({{"name", s.name}, {"fixed", *s.fixed}});
    } else {
      doc["parameters"].push_back({{"name", s.name},
                                   {"lower", s.lower},
                                   {"upper", s.upper},
                                   {"scale", ToString(s.scale)}});
    }
  }
  doc["optimizer"] = {{"name", o_.optimizer},
                      {"settings", OptimizerSettings(o_.optimizer, space.dimension(), x0, sigma, budget)}};
  doc["budget"] = {{"evaluations", budget}};
  doc["seed"] = seed;
  doc["threads"] = threads_;
  doc["checkpoint"] = {{"every_evaluations", budget}, {"every_seconds", 0}};
  doc["results"] = {{"store", (o_.out_dir / "store.sqlite").string()},
                    {"out_dir", o_.out_dir.string()}};
  JobSpecParseOptions parse;
  parse.recordings = RecordingCheck::kNone;
  const JobSpec spec = ParseJobSpec(doc, "loop stage " + name, o_.out_dir, parse);

  std::vector<std::shared_ptr<const PreparedRecording>> train;
  for (const LoopRecording& r : recs_) {
    if (r.train) train.push_back(r.prepared);
  }
  RecordingObjective objective(train, o_.simulation, ModelDefinition{effects});
  ThreadBatchEvaluator evaluator(objective, threads_);
  const int64_t job = store_->CreateJob(spec.name, ToJson(spec));
  RunControl control;
  const RunSummary run = RunCalibration(spec, *store_, job, evaluator, control);
  fit->evaluations += static_cast<int>(run.evaluations);
  fit->jobs.push_back(job);
  if (!run.best) {
    Log(fmt::format("loop: job {} found no candidate that simulates every training recording ({})",
                    name, run.stop_reason));
    return {ParameterValues{}, std::numeric_limits<double>::infinity()};
  }
  return {run.best->parameters, run.best->score};
}

double Loop::TrainingScore(const std::vector<std::string>& effects, const ParameterValues& values) const {
  std::vector<std::shared_ptr<const PreparedRecording>> train;
  for (const LoopRecording& r : recs_) {
    if (r.train) train.push_back(r.prepared);
  }
  const ObjectiveResult result =
      RecordingObjective(train, o_.simulation, ModelDefinition{effects}).MakeWorker()->Evaluate(values);
  return result.ok() ? result.score : std::numeric_limits<double>::infinity();
}

Fit Loop::Calibrate(int index, const std::vector<std::string>& effects, const Fit* warm) {
  const Clock::time_point start = Clock::now();
  const std::vector<ParameterSetting> settings =
      LoopParameterSettings(effects, scales_, warm != nullptr ? warm->values : ParameterValues{});
  const int64_t budget = (effects.empty() || o_.effect_budget == 0) ? o_.budget : o_.effect_budget;
  const uint64_t seed = o_.seed * 1000 + static_cast<uint64_t>(index);
  Fit fit;
  fit.effects = effects;
  if (warm == nullptr) {
    // Independent searches; the best on the training recordings is the fit
    // (the first on ties, so one restart is the plain search).
    const int dimension = SearchSpace(settings).dimension();
    double best = std::numeric_limits<double>::infinity();
    for (int r = 0; r < o_.restarts; ++r) {
      const std::vector<double> x0 = RestartStart(dimension, seed, r);
      const std::string name = JobName(index, effects) + (r == 0 ? "" : fmt::format("-restart{}", r));
      const auto [values, score] = RunJob(name, effects, settings, r == 0 ? nullptr : &x0, 0.3, budget,
                                          seed + 100000 * static_cast<uint64_t>(r), &fit);
      fit.restart_training_xor.push_back(score);
      if (score < best) {
        best = score;
        fit.values = values;
      }
    }
    if (fit.values.empty()) {
      throw std::runtime_error(fmt::format(
          "loop: calibrating {} found no candidate that simulates every training recording",
          StageName(effects)));
    }
  } else {
    // Warm start in two phases. (1) The new effect's parameters alone, over
    // their whole box, the previous model's held at their best: a small
    // search that sees what the effect can do. (2) Everything together from
    // there, with a small step: the previous parameters adjust to the effect.
    // The warm start itself (the effect neutral) and phase 1's best compete
    // with phase 2's: the best on the training recordings is the result.
    ParameterValues start_values;
    std::vector<ParameterSetting> effect_only;
    for (const ParameterSetting& s : settings) {
      const auto it = warm->values.find(s.name);
      if (it != warm->values.end()) {
        const double v = std::clamp(it->second, s.fixed.value_or(s.lower), s.fixed.value_or(s.upper));
        start_values[s.name] = v;
        effect_only.push_back(Fixed(s.name, v));
      } else {
        start_values[s.name] = NeutralValue(s);
        effect_only.push_back(s);
      }
    }
    // Phase 1 rarely finds much by itself (the previous model's values are
    // a fit without the effect: a stiffness or a damping there already
    // imitates part of it), so it gets a quarter of the budget; phase 2,
    // where those values can move away from their imitation, the rest,
    // with a step wide enough to leave the previous optimum's basin
    // (kJointSigma of each unit box).
    const int64_t budget1 = std::max<int64_t>(2, budget / 4);
    const int64_t budget2 = std::max<int64_t>(2, budget - budget1);
    std::vector<double> x1 = SearchSpace(effect_only).ToUnit(start_values);
    for (double& u : x1) u = std::clamp(u, 0.0, 1.0);
    const auto [values1, score1] = RunJob(JobName(index, effects) + "-effect", effects, effect_only,
                                          &x1, 0.3, budget1, seed, &fit);
    // (A phase that found no candidate simulating every training recording
    // scores +inf; where none did, the fit is the warm start, which the
    // criterion rejects if it does not simulate either.)
    std::vector<double> x2 =
        SearchSpace(settings).ToUnit(std::isfinite(score1) ? values1 : start_values);
    for (double& u : x2) u = std::clamp(u, 0.0, 1.0);
    constexpr double kJointSigma = 0.25;
    const auto [values2, score2] = RunJob(JobName(index, effects), effects, settings, &x2,
                                          kJointSigma, budget2, seed + 500, &fit);
    const double score0 = TrainingScore(effects, start_values);
    ++fit.evaluations;
    fit.values = values2;
    double best = score2;
    if (score1 < best) {
      fit.values = values1;
      best = score1;
    }
    if (score0 < best || !std::isfinite(best)) fit.values = start_values;
  }
  Measure(&fit);
  fit.seconds = Since(start);
  return fit;
}

void Loop::Measure(Fit* fit) const {
  const int n = static_cast<int>(recs_.size());
  fit->results.assign(n, {});
  fit->residuals.assign(n, {});
  const ModelDefinition model{fit->effects};
  std::vector<std::string> errors(n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(std::max(1, std::min(threads_, n)))
  for (int r = 0; r < n; ++r) {
    try {
      Evaluator evaluator(*recs_[r].prepared, o_.simulation, model);
      ResidualAnalyzer analyzer(recs_[r].residual_facts);
      fit->results[r] = evaluator.Evaluate(fit->values, analyzer);
      fit->residuals[r] = analyzer.Finish();
      fit->residuals[r].recording = recs_[r].name;
    } catch (const std::exception& e) {
      errors[r] = e.what();
    }
  }
  for (int r = 0; r < n; ++r) {
    if (!errors[r].empty()) {
      throw std::runtime_error(fmt::format("loop: measuring {} on {}: {}", StageName(fit->effects),
                                           recs_[r].name, errors[r]));
    }
  }
}

// Re-scores the fit's equally good parameter sets on the held-out
// recordings (nothing without held-out recordings or with the option 0).
std::vector<int> Loop::HeldOutIndices() const {
  std::vector<int> held;
  for (size_t r = 0; r < recs_.size(); ++r) {
    if (!recs_[r].train) held.push_back(static_cast<int>(r));
  }
  return held;
}

// Every parameter set of `sets` on every held-out recording, in parallel:
// result i is set i / H on held-out recording i % H (H held-out recordings).
// A set the model rejects is a failed result.
std::vector<EvaluationResult> Loop::ScoreOnHeldOut(const std::vector<ParameterValues>& sets,
                                                   const std::vector<std::string>& effects) const {
  const std::vector<int> held = HeldOutIndices();
  const int n = static_cast<int>(sets.size() * held.size());
  std::vector<EvaluationResult> results(n);
  const ModelDefinition model{effects};
#pragma omp parallel for schedule(dynamic, 1) num_threads(std::max(1, std::min(threads_, n)))
  for (int i = 0; i < n; ++i) {
    const LoopRecording& rec = recs_[held[i % held.size()]];
    try {
      Evaluator evaluator(*rec.prepared, o_.simulation, model);
      results[i] = evaluator.Evaluate(sets[i / held.size()]);
    } catch (const std::exception&) {
      results[i].status = EvaluationStatus::kFailed;
    }
  }
  return results;
}

// A model's held-out error is a number only as far as it does not hang on
// digits the calibration cannot resolve: while the implicit step left its
// contacts to the projections (contacts switching between sticking and
// sliding), moving every value by 0.1 % moved the held-out XOR sum of
// push_viscoelastic_offset by up to 12 %; with the contacts in the step it
// is 0.01-0.3 % on the bundled pushes. The largest move over
// kSensitivityNudges nudges (each value times 1 +- 0.1 %, signs drawn from
// the loop's seed) is a floor of the held-out margin; a nudge that fails to
// simulate makes the whole held-out sum the floor.
void Loop::MeasureSensitivity(Fit* fit) const {
  if (!HasHoldout()) return;
  const std::vector<int> held = HeldOutIndices();
  std::vector<ParameterValues> nudged(kSensitivityNudges, fit->values);
  for (int k = 0; k < kSensitivityNudges; ++k) {
    const std::vector<double> u = RestartStart(static_cast<int>(fit->values.size()),
                                               o_.seed + kSensitivitySeedOffset, k + 1);  // in [0.1, 0.9]
    size_t j = 0;
    for (auto& [name, value] : nudged[k]) value *= 1.0 + (u[j++] < 0.5 ? -1.0 : 1.0) * kSensitivityNudge;
  }
  // A value nudged out of its range fails like a simulation.
  const std::vector<EvaluationResult> results = ScoreOnHeldOut(nudged, fit->effects);
  const double at_fit = static_cast<double>(fit->XorSum(recs_, false));
  double worst = 0.0;
  for (int k = 0; k < kSensitivityNudges; ++k) {
    double sum = 0.0;
    bool ok = true;
    for (size_t h = 0; h < held.size(); ++h) {
      const EvaluationResult& e = results[k * held.size() + h];
      ok &= e.ok();
      sum += static_cast<double>(e.xor_sum);
    }
    worst = std::max(worst, ok ? std::abs(sum - at_fit) : at_fit);
  }
  fit->holdout_sensitivity_px = worst;
}

void Loop::MeasureEquallyGood(Fit* fit) const {
  if (!HasHoldout() || o_.equally_good_fits == 0) return;
  std::vector<EvaluationRecord> evaluations;
  for (int64_t job : fit->jobs) {
    for (EvaluationRecord& e : store_->Evaluations(job)) evaluations.push_back(std::move(e));
  }
  // Equally good: worse than the best on the training recordings by no more
  // than the margin an effect must beat to count as better there (the
  // training segmentation noise, or the minimum relative gain).
  const double tolerance = Margin(true, 0, static_cast<double>(fit->XorSum(recs_, true)));
  std::vector<ParameterValues> sets = SelectEquallyGoodFits(evaluations, tolerance, o_.equally_good_fits);
  // The fit itself is always one of them (a warm start's best may be its
  // starting point, which no job recorded); Measure scored it already.
  std::erase(sets, fit->values);

  const std::vector<int> held = HeldOutIndices();
  const std::vector<EvaluationResult> results = ScoreOnHeldOut(sets, fit->effects);  // failures counted out below
  EquallyGoodFits g;
  g.training_tolerance_px = tolerance;
  std::vector<int64_t> sums;
  // One fit's held-out results, results_of(h) on the h-th held-out recording.
  auto add = [&](const auto& results_of) {
    int64_t xor_sum = 0;
    double iou = 0.0;
    for (size_t h = 0; h < held.size(); ++h) {
      const EvaluationResult& e = results_of(h);
      if (!e.ok()) return;  // a fit that fails on held-out data pins nothing down
      xor_sum += e.xor_sum;
      iou += e.mean_iou;
    }
    iou /= static_cast<double>(held.size());
    if (g.fits == 0 || xor_sum < g.holdout_xor_min) {
      g.holdout_xor_min = xor_sum;
      g.holdout_iou_at_min = iou;
    }
    g.holdout_xor_max = g.fits == 0 ? xor_sum : std::max(g.holdout_xor_max, xor_sum);
    sums.push_back(xor_sum);
    ++g.fits;
  };
  add([&](size_t h) -> const EvaluationResult& { return fit->results[held[h]]; });
  for (size_t k = 0; k < sets.size(); ++k) {
    add([&](size_t h) -> const EvaluationResult& { return results[k * held.size() + h]; });
  }
  if (!sums.empty()) {
    auto middle = sums.begin() + static_cast<std::ptrdiff_t>((sums.size() - 1) / 2);
    std::nth_element(sums.begin(), middle, sums.end());
    g.holdout_xor_median = *middle;
  }
  fit->equally_good = g;
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
    std::vector<int64_t> frame_xor;
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

Loop::Verdict Loop::Judge(const Fit& previous, const Fit* ablation, const Fit& candidate,
                          int extra_parameters) const {
  // The reference on the training recordings: the previous fit, or the
  // ablation where it is better there.
  const Fit& current = ablation != nullptr ? *ablation : previous;
  Verdict v;
  const int64_t train_before = current.XorSum(recs_, true);
  const int64_t train_after = candidate.XorSum(recs_, true);
  if (!candidate.AllOk()) {
    v.criterion = "every recording simulates";
    v.reason = "the calibrated model fails to simulate a recording";
    return v;
  }
  if (HasHoldout()) {
    // A model's held-out error is known only up to the spread of its
    // equally good fits, and a search that converged tightly has less
    // spread than one that did not: the effect must lower the held-out error
    // both at the best training fits and at the median over the equally
    // good fits (its best training fit where they were not measured). The
    // ablation, one more fit of the previous model, is the reference where
    // it does better on training.
    auto typical = [&](const Fit& fit) {
      return fit.equally_good.fits > 0 ? static_cast<double>(fit.equally_good.holdout_xor_median)
                                       : static_cast<double>(fit.XorSum(recs_, false));
    };
    const double best_before = static_cast<double>(current.XorSum(recs_, false));
    const double best_after = static_cast<double>(candidate.XorSum(recs_, false));
    double typical_before = typical(previous);
    if (ablation != nullptr) typical_before = std::min(typical_before, best_before);
    const double typical_after = typical(candidate);
    const double noise = NoiseBudget(false);
    // Neither model's held-out error can be read closer than a nudge of its
    // values moves it.
    const double sensitivity =
        std::max(previous.holdout_sensitivity_px, candidate.holdout_sensitivity_px);
    auto margin = [&](double before) {
      return std::max(Margin(false, extra_parameters, before), sensitivity);
    };
    // The deciding comparison: the one whose drop exceeds its margin by less.
    const double best_slack = best_before - best_after - margin(best_before);
    const double typical_slack = typical_before - typical_after - margin(typical_before);
    const bool decided_at_best = best_slack <= typical_slack;
    const double before = decided_at_best ? best_before : typical_before;
    const double after = decided_at_best ? best_after : typical_after;
    v.gain = before - after;
    v.margin = margin(before);
    v.criterion = "held-out XOR sum";
    const bool train_ok = train_after <= train_before;
    // The XOR sum also falls when the mesh leaves an object it overlaps
    // poorly (less than half): the held-out mean IoU must not fall.
    double iou_before = 0.0, iou_after = 0.0;
    int held = 0;
    for (size_t r = 0; r < recs_.size(); ++r) {
      if (recs_[r].train) continue;
      iou_before += current.results[r].mean_iou;
      iou_after += candidate.results[r].mean_iou;
      ++held;
    }
    iou_before /= std::max(held, 1);
    iou_after /= std::max(held, 1);
    // A fall the XOR margin calls insignificant is no fall.
    const double iou_tolerance = IouTolerance(v.margin, HeldOutMasks());
    const bool iou_ok = iou_after >= iou_before - iou_tolerance;
    v.pass = v.gain > v.margin && train_ok && iou_ok;
    auto spread = [](const EquallyGoodFits& g) {
      return g.fits == 0 ? std::string("not measured")
                         : fmt::format("{} fits, {} to {}", g.fits, g.holdout_xor_min, g.holdout_xor_max);
    };
    auto percent = [](double b, double a) { return b > 0 ? 100.0 * (a - b) / b : 0.0; };
    v.reason = fmt::format(
        "held-out XOR sum at the best training fits {:.0f} -> {:.0f} ({:+.1f}%), median over the "
        "equally good fits {:.0f} -> {:.0f} ({:+.1f}%) (training XOR within {:.0f} px of the best; "
        "before: {}; after: {}): the deciding drop ({}), {:.0f} px, {} the margin {:.0f} px = max({} x "
        "(1 + {} extra parameters) x segmentation noise {:.0f} px, {:.0f}% of {:.0f}, what a 0.1% "
        "nudge of either model's values moves: {:.0f} px); training "
        "XOR sum {} -> {}{}; held-out mean IoU {:.5f} -> {:.5f}{}",
        best_before, best_after, percent(best_before, best_after), typical_before, typical_after,
        percent(typical_before, typical_after), candidate.equally_good.training_tolerance_px,
        spread(previous.equally_good), spread(candidate.equally_good),
        decided_at_best ? "at the best fits" : "of the medians", v.gain,
        v.gain > v.margin ? "exceeds" : "does not exceed", v.margin, o_.noise_factor,
        extra_parameters, noise, 100.0 * o_.min_relative_gain, before, sensitivity, train_before,
        train_after,
        train_ok ? "" : " (rose: the fit got worse where it was fitted)", iou_before, iou_after,
        iou_after >= iou_before ? ""
        : iou_ok ? fmt::format(" (fell by less than the margin's {:.5f})", iou_tolerance)
                 : fmt::format(" (fell by more than the margin's {:.5f}: the XOR drop comes from "
                               "a mesh that overlaps the object less)",
                               iou_tolerance));
    return v;
  }
  // No held-out recording: BIC on the per-frame errors of the training
  // recordings (Gaussian per-frame XOR), plus the noise margin.
  auto sse = [&](const Fit& fit, int64_t* n) {
    double s = 0.0;
    *n = 0;
    for (size_t r = 0; r < recs_.size(); ++r) {
      if (!recs_[r].train) continue;
      for (const FrameScore& f : fit.results[r].frames) {
        s += static_cast<double>(f.xor_px) * f.xor_px;
        ++*n;
      }
    }
    return s;
  };
  int64_t n = 0;
  const double sse_before = sse(current, &n);
  const double sse_after = sse(candidate, &n);
  const int k_before = static_cast<int>(SearchSpace(LoopParameterSettings(current.effects, scales_, current.values)).dimension());
  const int k_after = k_before + extra_parameters;
  auto bic = [&](double s, int k) {
    return n * std::log(std::max(s, 1.0) / std::max<int64_t>(n, 1)) + k * std::log(std::max<int64_t>(n, 2));
  };
  const double b0 = bic(sse_before, k_before), b1 = bic(sse_after, k_after);
  v.gain = static_cast<double>(train_before - train_after);
  v.margin = Margin(true, extra_parameters, static_cast<double>(train_before));
  v.criterion = "BIC of per-frame training XOR";
  v.pass = b1 < b0 && v.gain > v.margin;
  v.reason = fmt::format(
      "no held-out recording: BIC {:.1f} -> {:.1f} over {} frames ({} -> {} parameters); training "
      "XOR sum {} -> {}, drop {:.0f} px {} the margin {:.0f} px",
      b0, b1, n, k_before, k_after, train_before, train_after, v.gain,
      v.gain > v.margin ? "exceeds" : "does not exceed", v.margin);
  return v;
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
  const bool holdout = HasHoldout();
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
  Fit current = Calibrate(index++, {}, nullptr);
  MeasureEquallyGood(&current);
  MeasureSensitivity(&current);
  const Fit base = current;
  report_.stages.push_back(MakeStage(base, "", StageDecision::kBase));
  report_.stages.back().criterion = holdout ? "held-out XOR sum" : "training XOR sum";
  report_.stages.back().criterion_value =
      static_cast<double>(base.XorSum(recs_, !holdout));
  report_.stages.back().reason = "the paper's base model";
  AddResiduals(base);
  Log(fmt::format("base: training XOR {}, held-out XOR {} ({:.1f} s){}{}{}", base.XorSum(recs_, true),
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
      Fit fit = Calibrate(index++, effects, &current);
      MeasureEquallyGood(&fit);
      MeasureSensitivity(&fit);
      // The reference: the previous model, or the previous model with the
      // candidate's values (the effect switched off) where that is better
      // on the training recordings: a recalibration that found better base
      // values gives the effect no credit for them.
      Fit ablation;
      ablation.effects = current.effects;
      for (const auto& [name, value] : current.values) ablation.values[name] = fit.values.at(name);
      Measure(&ablation);
      const bool ablation_better =
          ablation.AllOk() && ablation.XorSum(recs_, true) < current.XorSum(recs_, true);
      const int extra = static_cast<int>(SearchSpace(LoopParameterSettings({effect}, scales_, current.values)).dimension()) -
                        static_cast<int>(SearchSpace(LoopParameterSettings({}, scales_, current.values)).dimension());
      Verdict v = Judge(current, ablation_better ? &ablation : nullptr, fit, extra);
      if (ablation_better) {
        v.reason = fmt::format(
            "against the previous model with this calibration's values and {} off (training "
            "XOR {} < {} of the previous fit): {}",
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
    out += fmt::format("{:<22} {:<8} {:>12} {:>12} {:>7.1f}% {:>9.4f} {:>9.4f}\n", rec.name, rec.role,
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
