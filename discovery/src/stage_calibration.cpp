// Stage calibrations of the closed loop (stage_calibration.h) and the
// StageCalibrator that runs and measures them (loop_stages.h).

#include "calib/discovery/stage_calibration.h"

#include "calib/core/effects.h"
#include "calib/core/free_modes.h"
#include "calib/core/model_definition.h"
#include "calib/discovery/signals.h"
#include "calib/evaluator/mask_geometry.h"
#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/fit_diagnostics.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/runner.h"
#include "calib/search/factory.h"
#include "loop_stages.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

namespace calib {

namespace fs = std::filesystem;

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

SwingScale MeasureSwingScale(const PreparedRecording& prepared, bool area_weighted) {
  SwingScale scale;
  const Scene::ObservedMotion& motion = prepared.scene.motion;
  if (!motion.known || motion.node_rest_px.size() != static_cast<size_t>(prepared.mesh.NumNodes())) return scale;
  std::vector<double> x, y;
  x.reserve(prepared.object_masks.size());
  y.reserve(prepared.object_masks.size());
  for (const BitMask& mask : prepared.object_masks) {
    const MaskMoments moments = ComputeMoments(mask);
    x.push_back(moments.centroid_px.x());
    y.push_back(moments.centroid_px.y());
  }
  const double fps = prepared.recording.fps;
  const Oscillation along_x = DetectOscillation(x, fps), along_y = DetectOscillation(y, fps);
  const Oscillation* swing = nullptr;
  for (const Oscillation* o : {&along_x, &along_y}) {
    if (o->found && (swing == nullptr || o->amplitude > swing->amplitude)) swing = o;
  }
  if (swing == nullptr) return scale;
  scale.period_s = swing->period_s;
  scale.decay_per_s = swing->decay_per_s;
  scale.mode_rate = SlowestModeRate(prepared.mesh, ClampedNodes(prepared.mesh, prepared.scene),
                                    motion.node_rest_px, area_weighted);
  scale.stiffness = SwingStiffness(scale.mode_rate, scale.period_s, kCalibrationMass);
  scale.found = std::isfinite(scale.stiffness) && scale.stiffness > 0.0;
  return scale;
}

double HangingAngleDeg(const PreparedRecording& prepared) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const std::optional<Vec2> clamp = ClampCentre(prepared.scene);
  const Scene::ObservedMotion& motion = prepared.scene.motion;
  if (!clamp || !motion.known || prepared.object_masks.empty()) return kNaN;
  // The mean centroid is frame 0's plus the observed mean offset from it.
  const Vec2 mean = ComputeMoments(prepared.object_masks.front()).centroid_px +
                    motion.equilibrium_offset_px;
  const Vec2 away = mean - *clamp;
  if (!away.allFinite() || away.norm() == 0.0) return kNaN;
  return std::atan2(away.y(), away.x()) * (180.0 / std::numbers::pi);
}

SearchScales TrainingScales(const std::vector<std::shared_ptr<const PreparedRecording>>& training,
                            const SimulationOptions& simulation) {
  SearchScales scales;
  bool first = true;
  for (const auto& prepared : training) {
    const Recording& rec = prepared->recording;
    for (const Vec2& f : rec.forces) scales.peak_force = std::max(scales.peak_force, f.norm());
    scales.drag_force = std::max(scales.drag_force,
                                 ModelDragForce(prepared->mesh, prepared->scene, kCalibrationMass));
    scales.duration_s = std::max(scales.duration_s * (first ? 0.0 : 1.0),
                                 rec.num_frames / std::max(rec.fps, 1e-9));
    if (first) {
      scales.fps = rec.fps;
      scales.mm_per_px = rec.mm_per_px.value_or(0.0);
    }
    first = false;
  }
  scales.stiffness_reach = simulation.integrator == IntegratorKind::kImplicitFirstOrder ? 100.0 : 1.0;
  if (!training.empty()) {
    const SwingScale swing = MeasureSwingScale(*training.front(), simulation.area_weighted);
    if (swing.found) {
      scales.swing_stiffness = swing.stiffness;
      scales.swing_period_s = swing.period_s;
    }
    scales.hanging_angle_deg = HangingAngleDeg(*training.front());
  }
  return scales;
}

std::vector<ParameterSetting> StageParameterSettings(const std::vector<std::string>& effects,
                                                     const SearchScales& training_scales) {
  SearchScales scales = training_scales;
  if (std::find(effects.begin(), effects.end(), "inertia") == effects.end()) scales.swing_stiffness = 0.0;
  std::vector<ParameterSetting> out;
  for (const ParameterSpec& spec : ModelParameterSpecs(ModelDefinition{effects})) {
    const SearchBox box = spec.SearchBoxFor(scales);
    ParameterSetting s;
    s.name = spec.name;
    if (box.fixed) {
      s.fixed = box.fixed;
    } else {
      s.lower = box.lower;
      s.upper = box.upper;
      s.scale = box.scale;
    }
    out.push_back(std::move(s));
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
  std::vector<std::string> all;
  for (const EffectInfo& info : EffectTermCatalogue()) all.push_back(info.name);
  for (const ParameterSpec& spec : ModelParameterSpecs(ModelDefinition{all})) {
    if (spec.name == s.name) return spec.NeutralIn(SearchBox{s.lower, s.upper, s.scale, {}});
  }
  throw std::invalid_argument(fmt::format("parameter '{}' is no model term's", s.name));
}

CalibrationRequest StageRequest(const std::string& name, const std::vector<ParameterSetting>& settings,
                                const std::string& optimizer, const std::vector<double>* x0,
                                double step, int64_t budget, uint64_t seed) {
  CalibrationRequest request;
  request.name = name;
  request.parameters = settings;
  const int dimension = SearchSpace(settings).dimension();
  request.optimizer.name = optimizer;
  request.optimizer.settings = search::WithBudget(
      optimizer, search::StartSettings(optimizer, dimension, x0, step, budget), budget);
  request.budget.evaluations = budget;
  request.seed = seed;
  request.checkpoint = {budget, 0.0};
  return request;
}


// =========================================================================
// Stage calibrations (loop_stages.h).

std::optional<Vec2> ClampCentre(const Scene& scene) {
  if (scene.clamps.empty()) return std::nullopt;
  Vec2 sum = Vec2::Zero();
  for (const RectPx& c : scene.clamps) sum += Vec2(c.x + 0.5 * c.width, c.y + 0.5 * c.height);
  return Vec2(sum / static_cast<double>(scene.clamps.size()));
}

double MedianTipDistance(const std::vector<Vec2>& model, const std::vector<Vec2>& video) {
  std::vector<double> d;
  const size_t n = std::min(model.size(), video.size());
  for (size_t f = 0; f < n; ++f) {
    const double distance = (model[f] - video[f]).norm();
    if (std::isfinite(distance)) d.push_back(distance);
  }
  if (d.empty()) return std::numeric_limits<double>::quiet_NaN();
  const size_t mid = d.size() / 2;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(mid), d.end());
  if (d.size() % 2 == 1) return d[mid];
  const double upper = d[mid];
  return 0.5 * (*std::max_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(mid)) + upper);
}

namespace loop_detail {
namespace {

bool HasInertia(const std::vector<std::string>& effects) {
  return std::find(effects.begin(), effects.end(), "inertia") != effects.end();
}

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// MeasureSensitivity: each value is nudged up and down by this relative
// amount, one at a time.
constexpr double kSensitivityNudge = 1e-3;

// Calibration `restart` > 0 of a hypothesis (LoopOptions::effect_restarts)
// shares its stage's index: its jobs are named apart.
std::string JobName(int index, const std::vector<std::string>& effects, int restart) {
  std::string name = fmt::format("stage{}-base", index);
  for (const std::string& e : effects) name += "." + e;
  if (restart > 0) name += fmt::format("-calibration{}", restart + 1);
  return name;
}

}  // namespace

std::string StageName(const std::vector<std::string>& effects) {
  return ModelDefinition{effects}.ToString();
}

std::vector<std::string> WidenPinnedBoxes(std::vector<ParameterSetting>& settings,
                                          const ParameterValues& values,
                                          const std::vector<ParameterSpec>& specs, double factor) {
  if (!(factor > 1.0)) throw std::invalid_argument(fmt::format("WidenPinnedBoxes: factor {} <= 1", factor));
  std::vector<std::string> widened;
  for (const BoundHit& hit : ValuesOnBounds(settings, values)) {
    const auto s_it = std::find_if(settings.begin(), settings.end(),
                                   [&](const ParameterSetting& p) { return p.name == hit.name; });
    const auto spec = std::find_if(specs.begin(), specs.end(),
                                   [&](const ParameterSpec& p) { return p.name == hit.name; });
    if (s_it == settings.end() || s_it->scale != ParameterScale::kLog || spec == specs.end()) continue;
    ParameterSetting& s = *s_it;
    if (hit.upper && s.upper < spec->upper) {
      const double upper = std::min(spec->upper, s.upper * factor);
      widened.push_back(fmt::format("{}: upper {:g} -> {:g}", s.name, s.upper, upper));
      s.upper = upper;
    } else if (!hit.upper && s.lower > spec->lower) {
      const double lower = std::max(spec->lower, s.lower / factor);
      if (!(lower > 0.0)) continue;  // a log box stays positive
      widened.push_back(fmt::format("{}: lower {:g} -> {:g}", s.name, s.lower, lower));
      s.lower = lower;
    }
  }
  return widened;
}

void IncludeBoxes(std::vector<ParameterSetting>& settings, const std::vector<ParameterSetting>& wider) {
  for (ParameterSetting& s : settings) {
    if (!s.searched()) continue;
    for (const ParameterSetting& w : wider) {
      if (w.name != s.name || !w.searched() || w.scale != s.scale) continue;
      s.lower = std::min(s.lower, w.lower);
      s.upper = std::max(s.upper, w.upper);
    }
  }
}

// The store's job for `spec`: the one of its name when the loop resumes
// (it must have been made with the same request, recordings and model; the
// thread count may differ, since it changes no result), else a new one.
int64_t StageCalibrator::FindOrCreateJob(const JobSpec& spec) {
  nlohmann::json wanted = ToJson(spec);
  if (o_.resume) {
    if (std::optional<JobInfo> stored = store_.FindJob(spec.name)) {
      nlohmann::json had = stored->spec;
      had.erase("threads");
      wanted.erase("threads");
      if (had != wanted) {
        throw std::invalid_argument(fmt::format(
            "{}: job '{}' was made by a loop with other options (recordings, model, search or "
            "seed); resume with the options that made it, or start over without --resume",
            store_.path().string(), spec.name));
      }
      return stored->id;
    }
  }
  return store_.CreateJob(spec.name, ToJson(spec));
}

// One calibration job of the store: `settings` searched by the loop's
// optimiser (from x0 with initial_sigma when given), `budget` evaluations.
// Returns the best record's values and score.
std::pair<ParameterValues, double> StageCalibrator::RunJob(const std::string& name,
                                                const std::vector<std::string>& effects,
                                                const std::vector<ParameterSetting>& settings,
                                                const std::vector<double>* x0, double sigma,
                                                int64_t budget, uint64_t seed, Fit* fit,
                                                int frames) {
  // The store keeps the job as a job spec (the request plus the
  // recordings, the model and where results go), as for `calib run`.
  JobSpec spec;
  static_cast<CalibrationRequest&>(spec) =
      StageRequest(name, settings, o_.optimizer, x0, sigma, budget, seed);
  spec.source = "loop stage " + name;
  spec.base_dir = fs::absolute(o_.out_dir);
  for (const LoopRecording& r : recs_) {
    (r.train ? spec.train : spec.holdout).push_back(fs::absolute(r.path));
  }
  spec.model.effects = effects;
  spec.model.simulation = o_.simulation;
  // Area weighting acts only with inertia; the job spec says so.
  spec.model.simulation.area_weighted = o_.simulation.area_weighted && HasInertia(effects);
  spec.model.preparation = o_.preparation;
  spec.model.preparation.max_frames = frames;
  spec.threads = threads_;
  spec.results.store = spec.base_dir / "store.sqlite";
  spec.results.out_dir = spec.base_dir;
  spec.parameter_specs = ModelParameterSpecs(ModelDefinition{effects});

  RecordingObjective objective(TrainingRecordings(frames), o_.simulation, ModelDefinition{effects});
  const std::unique_ptr<BatchEvaluator> evaluator = MakeEvaluator(objective);
  const int64_t job = FindOrCreateJob(spec);
  RunControl control;
  control.interrupted = o_.interrupted;
  const RunSummary run = RunCalibration(spec.request(), store_, job, *evaluator, control);
  if (run.status == JobStatus::kStopped && o_.interrupted && o_.interrupted()) {
    throw LoopStopped(fmt::format("loop: stopped in calibration {} after {} evaluations ({})",
                                  name, run.evaluations, run.stop_reason));
  }
  fit->evaluations += static_cast<int>(run.evaluations);
  fit->jobs.push_back(job);
  if (frames <= 0) fit->whole_recording_jobs.push_back(job);
  if (!run.best) {
    Log(fmt::format("loop: job {} found no candidate that simulates every training recording ({})",
                    name, run.stop_reason));
    return {ParameterValues{}, std::numeric_limits<double>::infinity()};
  }
  return {run.best->parameters, run.best->score};
}

std::vector<std::shared_ptr<const PreparedRecording>> StageCalibrator::TrainingRecordings(int frames) const {
  std::vector<std::shared_ptr<const PreparedRecording>> train;
  for (const LoopRecording& r : recs_) {
    if (!r.train) continue;
    train.push_back(frames > 0 ? std::make_shared<const PreparedRecording>(FirstFrames(*r.prepared, frames))
                               : r.prepared);
  }
  return train;
}

double StageCalibrator::TrainingScore(const std::vector<std::string>& effects, const ParameterValues& values,
                                      int frames) const {
  const ObjectiveResult result = RecordingObjective(TrainingRecordings(frames), o_.simulation, ModelDefinition{effects})
                                     .MakeWorker()
                                     ->Evaluate(values);
  return result.ok() ? result.score : std::numeric_limits<double>::infinity();
}

HorizonFit FollowHorizons(const std::vector<int>& horizons, ParameterValues fit,
                          const HorizonSearch& search, const HorizonScore& score,
                          const std::function<void(int, double, double)>& chosen) {
  HorizonFit out;
  out.values = std::move(fit);
  if (horizons.size() < 2) return out;
  // Each horizon's best (the first's: the fit given), in order.
  std::vector<ParameterValues> bests = {out.values};
  for (size_t k = 1; k < horizons.size(); ++k) {
    auto [values, searched] = search(k, bests.back());
    if (!std::isfinite(searched)) {
      bests.push_back(bests.back());  // nothing simulated: the fit so far goes on
      continue;
    }
    bests.push_back(std::move(values));
    if (k + 1 == horizons.size()) out.score = searched;
  }
  out.values = bests.back();
  const double last = out.score;  // infinite where the last search simulated nothing
  // The values scored last: a horizon whose search simulated nothing
  // passed them on unchanged.
  const ParameterValues* scored = std::isfinite(last) ? &bests.back() : nullptr;
  for (size_t k = horizons.size() - 1; k-- > 0;) {
    if (scored != nullptr && bests[k] == *scored) continue;
    const double earlier = score(bests[k], horizons.back());
    scored = &bests[k];
    if (earlier < out.score) {
      out.values = bests[k];
      out.score = earlier;
      if (chosen) chosen(horizons[k], earlier, last);
    }
  }
  return out;
}

ParameterValues StageCalibrator::CalibrateSwing(int index, const std::vector<std::string>& effects,
                                                std::vector<ParameterSetting>* settings,
                                                int64_t budget, uint64_t seed, Fit* fit) {
  // A swing a few per cent off the video's period is out of phase within a
  // few of its cycles, and a still mesh on the mean pose then scores better
  // than any swing: over the whole recording the score has no slope towards
  // the right period. Over two periods it has. So the horizon starts at two
  // swing periods, where independent searches find the swing, and doubles
  // to the whole recordings, each horizon's search starting from the
  // previous best with a small step. Half the budget goes to each search of
  // the first horizon, the whole budget to each later one: a short
  // horizon's candidates cost a fraction of a whole recording's, and a
  // few generations from the previous best (a share of the budget, 30
  // evaluations at the loop's defaults) left the whole-recording fit of
  // concave_1 at mean IoU 0.60-0.68 where a plain search reaches 0.86.
  int shortest = std::numeric_limits<int>::max();
  double fps = 0.0;
  for (const LoopRecording& r : recs_) {
    if (!r.train) continue;
    shortest = std::min(shortest, r.prepared->scene.num_frames);
    if (fps == 0.0) fps = r.prepared->recording.fps;
  }
  std::vector<int> horizons;
  for (int h = static_cast<int>(std::ceil(2.0 * scales_.swing_period_s * fps)); h > 0 && h < shortest;
       h *= 2) {
    horizons.push_back(h);
  }
  horizons.push_back(0);  // the whole recordings
  constexpr int64_t kMinJob = 24;
  const int64_t first_budget =
      horizons.size() == 1 ? budget : std::max<int64_t>(kMinJob, budget / 2);
  const int64_t later_budget = horizons.size() == 1 ? 0 : std::max<int64_t>(kMinJob, budget);
  const std::string base_name = JobName(index, effects, fit->restart);
  const auto horizon_name = [&](int h) {
    return h == 0 ? base_name : fmt::format("{}-frames{}", base_name, h);
  };

  // The first horizon: independent searches, as a cold calibration.
  const int dimension = SearchSpace(*settings).dimension();
  ParameterValues best_values;
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r < o_.restarts; ++r) {
    const std::vector<double> x0 = RestartStart(dimension, seed, r);
    const std::string name = horizon_name(horizons.front()) + (r == 0 ? "" : fmt::format("-restart{}", r));
    const auto [values, score] = RunJob(name, effects, *settings, r == 0 ? nullptr : &x0, 0.3, first_budget,
                                        seed + 100000 * static_cast<uint64_t>(r), fit, horizons.front());
    fit->restart_training_xor.push_back(score);
    if (score < best) {
      best = score;
      best_values = values;
    }
  }
  if (best_values.empty()) {
    throw std::runtime_error(fmt::format(
        "loop: calibrating {} found no candidate that simulates the first {} frames of every "
        "training recording",
        StageName(effects), horizons.front()));
  }
  // Longer horizons, each from the previous one's best; the fit is the
  // best of those over the whole recordings (FollowHorizons). On concave_1
  // at seed 3 the 504-frame search's best scored 574 222 over the whole
  // video, and the 1008-frame search from it ended at 1 198 536 there.
  constexpr double kHorizonSigma = 0.1;
  double best_whole = best;  // one horizon: the first is the whole recordings
  if (horizons.size() > 1) {
    const HorizonFit followed = FollowHorizons(
        horizons, best_values,
        [&](size_t k, const ParameterValues& from) {
          std::vector<double> x0 = SearchSpace(*settings).ToUnit(from);
          for (double& u : x0) u = std::clamp(u, 0.0, 1.0);
          return RunJob(horizon_name(horizons[k]), effects, *settings, &x0, kHorizonSigma, later_budget,
                        seed + 500 + k, fit, horizons[k]);
        },
        [&](const ParameterValues& values, int frames) {
          ++fit->evaluations;
          return TrainingScore(effects, values, frames);
        },
        [&](int frames, double score, double last) {
          Log(fmt::format("loop: {}: the best over the first {} frames scores {:.0f} over the whole "
                          "training recordings, the search over them {:.0f}; it is the fit",
                          StageName(effects), frames, score, last));
        });
    best_values = followed.values;
    best_whole = followed.score;
    if (!std::isfinite(best_whole)) {
      throw std::runtime_error(fmt::format(
          "loop: calibrating {}: no fit on the first frames simulates the whole training recordings",
          StageName(effects)));
    }
  }
  // A fit on a bound of a log-scaled box: the box (a stiffness's or a
  // damping's, set from the recordings' scales before anything was fitted)
  // may end short of the optimum. The edge damping of concave_1's swing
  // ended on the first-order box's top (1e4). The box is widened there by
  // kBoxWidening and searched again over the whole recordings from the fit,
  // at most kMaxBoxWidenings times, while that improves the training score.
  constexpr double kBoxWidening = kSwingStiffnessReach;
  constexpr int kMaxBoxWidenings = 2;
  const std::vector<ParameterSpec> specs = ModelParameterSpecs(ModelDefinition{effects});
  for (int w = 1; w <= kMaxBoxWidenings; ++w) {
    const std::vector<std::string> widened = WidenPinnedBoxes(*settings, best_values, specs, kBoxWidening);
    if (widened.empty()) break;
    std::string list;
    for (const std::string& line : widened) list += (list.empty() ? "" : ", ") + line;
    Log(fmt::format("loop: {} ended on its search box's bound; widened ({}) and searched again",
                    StageName(effects), list));
    fit->widened_settings = *settings;
    std::vector<double> x0 = SearchSpace(*settings).ToUnit(best_values);
    for (double& u : x0) u = std::clamp(u, 0.0, 1.0);
    const auto [values, score] =
        RunJob(fmt::format("{}-widened{}", base_name, w), effects, *settings, &x0, kHorizonSigma,
               std::max<int64_t>(kMinJob, budget), seed + 900 + static_cast<uint64_t>(w), fit, 0);
    if (!(score < best_whole)) break;
    best_values = values;
    best_whole = score;
  }
  return best_values;
}

bool StageCalibrator::StartsCold(const std::vector<std::string>& effects, const Fit& warm) const {
  // A first-order fit's stiffnesses set relaxation rates; with inertia on
  // a swinging object they set the swing's period, orders of magnitude
  // apart (the boxes move to the swing stiffness): nothing to warm-start
  // from.
  return scales_.swing_stiffness > 0.0 && HasInertia(effects) && !HasInertia(warm.effects);
}

Fit StageCalibrator::Calibrate(int index, const std::vector<std::string>& effects, const Fit* warm,
                               int restart) {
  const Clock::time_point start = Clock::now();
  const Fit* const previous = warm;
  if (warm != nullptr && StartsCold(effects, *warm)) warm = nullptr;
  SearchScales scales = scales_;
  if (warm != nullptr) scales.reference = warm->values;
  std::vector<ParameterSetting> settings = StageParameterSettings(effects, scales);
  // A box the previous calibration widened stays as wide: its fit may lie
  // outside this stage's own box.
  if (warm != nullptr) IncludeBoxes(settings, warm->widened_settings);
  const int64_t budget = (effects.empty() || o_.effect_budget == 0) ? o_.budget : o_.effect_budget;
  // A hypothesis's first calibration has the seed a loop without
  // effect restarts gives it; the others seeds of their own.
  const uint64_t seed = o_.seed * 1000 + static_cast<uint64_t>(index) + 1000000 * static_cast<uint64_t>(restart);
  Fit fit;
  fit.effects = effects;
  fit.restart = restart;
  if (warm != nullptr && !warm->widened_settings.empty()) fit.widened_settings = settings;
  const bool swing = warm == nullptr && scales_.swing_stiffness > 0.0 && HasInertia(effects);
  if (swing) {
    fit.values = CalibrateSwing(index, effects, &settings, budget, seed, &fit);
  } else if (warm == nullptr) {
    // Independent searches; the best on the training recordings is the fit
    // (the first on ties, so one restart is the plain search).
    const int dimension = SearchSpace(settings).dimension();
    double best = std::numeric_limits<double>::infinity();
    for (int r = 0; r < o_.restarts; ++r) {
      const std::vector<double> x0 = RestartStart(dimension, seed, r);
      const std::string name = JobName(index, effects, restart) + (r == 0 ? "" : fmt::format("-restart{}", r));
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
        ParameterSetting fixed;
        fixed.name = s.name;
        fixed.fixed = v;
        effect_only.push_back(std::move(fixed));
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
    // A restart starts the effect's search elsewhere in its box: the
    // effect's basins are what the restarts are for.
    std::vector<double> x1 = restart > 0
                                 ? RestartStart(SearchSpace(effect_only).dimension(), seed, restart)
                                 : SearchSpace(effect_only).ToUnit(start_values);
    for (double& u : x1) u = std::clamp(u, 0.0, 1.0);
    const auto [values1, score1] = RunJob(JobName(index, effects, restart) + "-effect", effects, effect_only,
                                          &x1, 0.3, budget1, seed, &fit);
    // (A phase that found no candidate simulating every training recording
    // scores +inf; where none did, the fit is the warm start, which the
    // criterion rejects if it does not simulate either.)
    std::vector<double> x2 =
        SearchSpace(settings).ToUnit(std::isfinite(score1) ? values1 : start_values);
    for (double& u : x2) u = std::clamp(u, 0.0, 1.0);
    constexpr double kJointSigma = 0.25;
    const auto [values2, score2] = RunJob(JobName(index, effects, restart), effects, settings, &x2,
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
  // What the calibration's history says about the fit: a score no
  // parameter moved in any of its jobs, values on the box's bounds.
  bool every_job_flat = !fit.jobs.empty();
  int64_t scored = 0;
  for (int64_t job : fit.jobs) {
    const std::vector<EvaluationRecord> evaluations = store_.Evaluations(job);
    const FitDiagnostics d = DiagnoseFit(settings, {}, evaluations);
    scored += d.scored;
    every_job_flat = every_job_flat && (d.uninformative || d.scored == 0);
  }
  fit.uninformative = every_job_flat && scored >= 2;
  Measure(&fit);
  // A swing's shorter horizons score fewer frames than the fit's training
  // score: only its jobs over the whole recordings rank (whole_recording_jobs).
  if (!effects.empty()) RefitWhereHeldOutFails(&fit, previous);
  fit.at_bounds = DiagnoseFit(settings, fit.values, {}).at_bounds;
  fit.seconds = Since(start);
  return fit;
}

void StageCalibrator::Measure(Fit* fit) const {
  const int n = static_cast<int>(recs_.size());
  fit->results.assign(n, {});
  fit->residuals.assign(n, {});
  fit->tips.assign(n, {});
  const ModelDefinition model{fit->effects};
  std::vector<std::string> errors(n);
#pragma omp parallel for schedule(dynamic, 1) num_threads(std::max(1, std::min(threads_, n)))
  for (int r = 0; r < n; ++r) {
    try {
      Evaluator evaluator(*recs_[r].prepared, o_.simulation, model);
      ResidualAnalyser analyser(recs_[r].residual_facts);
      const std::optional<Vec2> clamp = ClampCentre(recs_[r].prepared->scene);
      std::vector<Vec2>& tips = fit->tips[r];
      const auto measure = [&](int frame, const Simulator& simulator, const BitMask& mesh_mask,
                               const FrameScore& score) {
        analyser(frame, simulator, mesh_mask, score);
        if (!clamp) return;
        // The mesh's tip as the video's is taken: the farthest pixel of the
        // mesh as scored (covered at least half, widened by the camera's
        // motion blur), not its farthest node. Off the roi: the node.
        Vec2 tip = FarthestPixelFrom(mesh_mask, *clamp);
        if (!std::isfinite(tip.x())) {
          tip = simulator.positions().front();
          for (const Vec2& p : simulator.positions()) {
            if ((p - *clamp).squaredNorm() > (tip - *clamp).squaredNorm()) tip = p;
          }
        }
        tips.push_back(tip);
      };
      fit->results[r] = evaluator.Evaluate(fit->values, measure);
      fit->residuals[r] = analyser.Finish();
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

bool StageCalibrator::WholeRecordingsHeldOut() const {
  const std::vector<int> held = HeldOutIndices();
  return !held.empty() && std::all_of(held.begin(), held.end(), [&](int r) {
    return recs_[static_cast<size_t>(r)].first_compared_frame == 0;
  });
}

std::vector<int> StageCalibrator::HeldOutIndices() const {
  std::vector<int> held;
  for (size_t r = 0; r < recs_.size(); ++r) {
    if (!recs_[r].train) held.push_back(static_cast<int>(r));
  }
  return held;
}

std::unique_ptr<BatchEvaluator> StageCalibrator::MakeEvaluator(const Objective& objective) const {
  if (o_.make_evaluator) return o_.make_evaluator(objective, threads_);
  return std::make_unique<ThreadBatchEvaluator>(objective, threads_);
}

void StageCalibrator::RefitWhereHeldOutFails(Fit* fit, const Fit* reference) const {
  if (o_.refit_candidates == 0) return;
  int failed = -1;
  for (size_t r = 0; r < recs_.size(); ++r) {
    const EvaluationResult& e = fit->results[r];
    if (e.ok()) continue;
    if (recs_[r].train) return;  // not a fit that simulates its training data
    if (failed < 0 && !ComparableOnHeldOut(false, e.failure_frame, reference, r)) {
      failed = static_cast<int>(r);
    }
  }
  if (failed < 0) return;
  const EvaluationResult& failure = fit->results[static_cast<size_t>(failed)];
  const std::string what = fmt::format("the calibration's best fit on training failed to simulate {} "
                                       "(held out) from frame {} ({})",
                                       recs_[static_cast<size_t>(failed)].name, failure.failure_frame,
                                       failure.failure_reason);
  std::vector<EvaluationRecord> evaluations;
  for (int64_t job : fit->whole_recording_jobs) {
    for (EvaluationRecord& e : store_.Evaluations(job)) evaluations.push_back(std::move(e));
  }
  const std::vector<ParameterValues> candidates =
      RankedByTrainingScore(evaluations, fit->values, o_.refit_candidates);
  const std::vector<int> held = HeldOutIndices();
  // In fixed batches, best first, so that the choice is the same at any
  // thread count: the first candidate that simulates every held-out
  // recording, or as far as the reference does.
  constexpr size_t kBatch = 8;
  for (size_t begin = 0; begin < candidates.size(); begin += kBatch) {
    const size_t end = std::min(candidates.size(), begin + kBatch);
    const std::vector<ParameterValues> batch(candidates.begin() + static_cast<std::ptrdiff_t>(begin),
                                             candidates.begin() + static_cast<std::ptrdiff_t>(end));
    const std::vector<HeldOutScore> scores = ScoreOnHeldOut(batch, fit->effects);
    for (size_t k = 0; k < batch.size(); ++k) {
      bool ok = true;
      for (size_t h = 0; h < held.size(); ++h) {
        const HeldOutScore& s = scores[k * held.size() + h];
        ok = ok && ComparableOnHeldOut(s.ok, s.failure_frame, reference, static_cast<size_t>(held[h]));
      }
      if (!ok) continue;
      const double training_before = fit->XorSum(recs_, true);
      fit->values = batch[k];
      Measure(fit);
      const bool reference_fails = reference != nullptr && !reference->AllOk();
      fit->refit = fmt::format(
          "{}; refitted: of its next {} candidates by training XOR, number {} is the first that "
          "simulates every held-out recording{} (training XOR {:.0f} -> {:.0f})",
          what, candidates.size(), begin + k + 1, reference_fails ? " as far as the previous model does" : "",
          training_before, fit->XorSum(recs_, true));
      return;
    }
  }
  fit->refit = fmt::format("{}; none of its next {} candidates by training XOR simulates every "
                           "held-out recording", what, candidates.size());
}

std::vector<HeldOutScore> StageCalibrator::ScoreOnHeldOut(const std::vector<ParameterValues>& sets,
                                                          const std::vector<std::string>& effects) const {
  const std::vector<int> held = HeldOutIndices();
  std::vector<HeldOutScore> scores(sets.size() * held.size());
  if (sets.empty()) return scores;
  std::vector<PendingCandidate> batch(sets.size());
  for (size_t k = 0; k < sets.size(); ++k) batch[k] = {static_cast<int64_t>(k), sets[k]};
  const ModelDefinition model{effects};
  for (size_t h = 0; h < held.size(); ++h) {
    // One objective per held-out recording: its score is that recording's
    // XOR sum and its mean IoU that recording's, summed in frame order as
    // Evaluator::Evaluate sums them.
    const RecordingObjective objective({recs_[held[h]].prepared}, o_.simulation, model);
    const std::unique_ptr<BatchEvaluator> evaluator = MakeEvaluator(objective);
    evaluator->Evaluate(
        batch, /*max_attempts=*/1, /*prune=*/nullptr, [] { return false; },
        [&](std::vector<FinishedCandidate>&& done) {
          for (const FinishedCandidate& c : done) {
            HeldOutScore& s = scores[static_cast<size_t>(c.id) * held.size() + h];
            s.ok = c.result.ok();
            s.xor_sum = std::isfinite(c.result.score) ? c.result.score : 0.0;
            s.mean_iou = c.result.iou.mean;
            s.failure_frame = c.result.failure_frame;
          }
        },
        /*tick_s=*/1.0);
  }
  return scores;
}

// How smooth the held-out error is in the parameters at a fit: each
// searched value times 1 +- 0.1 %, one at a time, re-scored on the held-out recordings;
// the largest move of the held-out XOR sum and the value that made it. A
// nudge that fails to simulate (or leaves the value's range) moves it by
// the whole sum. Measured where whole recordings are held out and the fit
// simulates every one of them (a fit that fails there has no held-out sum
// to move: 0, not measured).
void StageCalibrator::MeasureSensitivity(Fit* fit) const {
  if (!WholeRecordingsHeldOut() || !std::isfinite(fit->XorSum(recs_, false))) return;
  const std::vector<int> held = HeldOutIndices();
  std::vector<ParameterValues> nudged;
  std::vector<std::string> names;
  SearchScales scales = scales_;
  scales.reference = fit->values;
  for (const ParameterSetting& setting : StageParameterSettings(fit->effects, scales)) {
    if (!setting.searched()) continue;
    const std::string& name = setting.name;
    const double value = fit->values.at(name);
    for (double sign : {1.0, -1.0}) {
      ParameterValues v = fit->values;
      v[name] = value * (1.0 + sign * kSensitivityNudge);
      nudged.push_back(std::move(v));
      names.push_back(name);
    }
  }
  const std::vector<HeldOutScore> results = ScoreOnHeldOut(nudged, fit->effects);
  const double at_fit = fit->XorSum(recs_, false);
  double worst = 0.0;
  std::string worst_name;
  for (size_t k = 0; k < nudged.size(); ++k) {
    double sum = 0.0;
    bool ok = true;
    for (size_t h = 0; h < held.size(); ++h) {
      const HeldOutScore& e = results[k * held.size() + h];
      ok &= e.ok;
      sum += e.xor_sum;
    }
    const double move = ok ? std::abs(sum - at_fit) : at_fit;
    if (move > worst) {
      worst = move;
      worst_name = names[k];
    }
  }
  fit->holdout_sensitivity_px = worst;
  fit->holdout_sensitivity_parameter = worst_name;
}

void StageCalibrator::MeasureEquallyGood(Fit* fit) const {
  if (!WholeRecordingsHeldOut() || o_.equally_good_fits == 0) return;
  std::vector<EvaluationRecord> evaluations;
  for (int64_t job : fit->whole_recording_jobs) {
    for (EvaluationRecord& e : store_.Evaluations(job)) evaluations.push_back(std::move(e));
  }
  // Equally good: worse than the best on the training recordings by no more
  // than their segmentation noise, or 1 % of the best.
  const double best = fit->XorSum(recs_, true);
  const double tolerance = std::max(criterion_.TrainingNoise(), 0.01 * best);
  std::vector<ParameterValues> sets = SelectEquallyGoodFits(evaluations, tolerance, o_.equally_good_fits);
  // The fit itself is always one of them (a warm start's best may be its
  // starting point, which no job recorded); Measure scored it already.
  std::erase(sets, fit->values);

  const std::vector<int> held = HeldOutIndices();
  const std::vector<HeldOutScore> results = ScoreOnHeldOut(sets, fit->effects);  // failures counted out below
  EquallyGoodFits g;
  g.training_tolerance_px = tolerance;
  std::vector<double> sums;
  // One fit's held-out results, results_of(h) on the h-th held-out recording.
  auto add = [&](const auto& results_of) {
    double xor_sum = 0.0;
    double iou = 0.0;
    for (size_t h = 0; h < held.size(); ++h) {
      const HeldOutScore e = results_of(h);
      if (!e.ok) return;  // a fit that fails on held-out data pins nothing down
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
  add([&](size_t h) {
    const EvaluationResult& e = fit->results[held[h]];
    return HeldOutScore{e.ok(), static_cast<double>(e.xor_sum), e.mean_iou};
  });
  for (size_t k = 0; k < sets.size(); ++k) {
    add([&](size_t h) { return results[k * held.size() + h]; });
  }
  if (!sums.empty()) {
    auto middle = sums.begin() + static_cast<std::ptrdiff_t>((sums.size() - 1) / 2);
    std::nth_element(sums.begin(), middle, sums.end());
    g.holdout_xor_median = *middle;
  }
  fit->equally_good = g;
}

}  // namespace loop_detail

}  // namespace calib
