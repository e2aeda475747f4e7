#pragma once
// The closed loop behind `calib loop`: calibrate the base model, analyse the
// residual of the best fit on every recording, trace it to ranked effect
// hypotheses, add the most promising effects one at a time, recalibrate,
// keep an effect only when it lowers the held-out error by more than noise
// and extra parameters explain, and report everything (report.json,
// report.html, a before / after table). Documented in docs/loop.md.
//
// Each calibration is a job of the results store DIR/store.sqlite (the
// runner of runner.h, OpenMP threads, in process), named after its model
// ("base", "base+viscoelastic", ...). Everything the loop decides depends
// only on the recordings, the options and the seed: the same inputs give the
// same report numbers at any thread count.
//
// The loop never reads what a recording does not declare: recording.json,
// track.csv and the video only (a synthetic recording's truth.json is never
// opened).

#include "calib/core/parameters.h"
#include "calib/core/simulator.h"
#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/hypotheses.h"
#include "calib/evaluator/residual.h"
#include "calib/jobs/job_spec.h"
#include "calib/jobs/objective.h"
#include "calib/results/loop_report.h"
#include "calib/results/store.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace calib {

/// The loop's simulation: the first-order step implicit in the springs
/// (stable at the stiffness of a quasi-static push), obstacles kept out of
/// the outline's edges, contact friction 0.5 (docs/loop.md, "The model the
/// loop calibrates").
SimulationOptions LoopSimulationDefaults();

struct LoopOptions {
  std::vector<std::filesystem::path> train;    ///< >= 1 recording folders (fitted)
  std::vector<std::filesystem::path> holdout;  ///< recording folders (decide, never fitted)
  std::filesystem::path out_dir;               ///< report.json, report.html, store.sqlite, overlays/
  uint64_t seed = 1;
  /// Evaluations of the base model's calibration.
  int64_t budget = 160;
  /// Evaluations of each calibration with an effect added; 0: `budget`.
  int64_t effect_budget = 0;
  int threads = 0;                 ///< OpenMP threads; 0: all cores
  std::string optimizer = "cmaes";  ///< a search::OptimizerNames() name
  int max_effects = 2;             ///< effects kept at most
  /// Hypotheses tried (recalibrated) per round, best ranked first.
  int tries_per_round = 3;
  /// A hypothesis below this confidence is not tried (hypotheses.h: 0 means
  /// no residual worth explaining, or the recording cannot show it).
  double min_confidence = 0.05;
  /// Criterion: the held-out XOR sum must drop by more than
  /// noise_factor x (1 + extra parameters) x the held-out recordings'
  /// segmentation noise (flicker pixels summed over their frames), and by
  /// more than min_relative_gain of itself. See docs/loop.md.
  double noise_factor = 1.0;
  double min_relative_gain = 0.01;
  /// The held-out error of a model is known only up to the spread of its
  /// equally good fits (SelectEquallyGoodFits: its calibration's parameter
  /// sets whose training XOR sum exceeds the best by less than the margin
  /// above computed on the training recordings): up to this many of them
  /// are re-scored on the held-out recordings, and an effect's held-out
  /// drop must pass both at the best fits and between the medians over
  /// them. 0: at the best fits only.
  int equally_good_fits = 16;
  /// Independent searches of a calibration from scratch (the base model),
  /// each with the whole `budget`: the first from the box's centre, the
  /// others from seeded points of the box (RestartStart). The best on the
  /// training recordings is the fit; every search's records count towards
  /// its equally good fits. A flat or two-basin training error lands one
  /// search in the worse basin as often as not (docs/loop.md).
  int restarts = 3;
  SimulationOptions simulation = LoopSimulationDefaults();
  PreparationOptions preparation;
  /// Report: overlay PNGs of the worst frames (base and final model).
  int overlays_per_recording = 2;
  bool write_html = true;
  std::string command;  ///< the command line, for the report

  /// False with a message naming the option and the rule.
  bool IsValid(std::string* error) const;
};

/// What one calibration of the loop searches: the parameter settings (a
/// box, or fixed) for `effects` on top of the base model. The boxes of the
/// effects' parameters scale with what the recordings show (peak force,
/// frame rate, duration, mm per pixel) and with the previous best base
/// values (`reference`: k_D for the stiffening coefficient).
struct LoopScales {
  double peak_force = 0.0;       ///< largest |force| of the training tracks; 0: no sensor
  double fps = 30.0;             ///< of the first training recording
  double duration_s = 1.0;       ///< longest training recording
  double mm_per_px = 0.0;        ///< 0: unknown
  /// The model's own force scale: the first-order drag of the whole mesh
  /// moving at the fastest obstacle's speed, nodes x mass x speed (largest
  /// over the training recordings). The model's forces are not in the
  /// sensor's unit (only stiffness / mass ratios are calibrated), so
  /// table friction is sized on this. 0: no obstacle moves.
  double drag_force = 0.0;
  /// The stiffness boxes reach 100x higher with the implicit step, which is
  /// stable there (the quasi-static regime of a pushed sponge).
  IntegratorKind integrator = IntegratorKind::kFirstOrder;
};
/// LoopScales::drag_force of one recording: the mesh's nodes x `mass` x
/// the fastest obstacle's speed between two frames (px/s); 0 without a
/// moving obstacle.
double ModelDragForce(const Mesh& mesh, const Scene& scene, double mass);

std::vector<ParameterSetting> LoopParameterSettings(const std::vector<std::string>& effects,
                                                    const LoopScales& scales,
                                                    const ParameterValues& reference);

/// Where independent search `restart` (>= 1) of a calibration from scratch
/// starts, in unit-box coordinates: each coordinate drawn from [0.1, 0.9]
/// by a generator seeded with (`seed`, `restart`), so that a restart is
/// the same at every thread count and after a resume. Restart 0 starts
/// at the centre (0.5).
std::vector<double> RestartStart(int dimension, uint64_t seed, int restart);

/// The value of each effect parameter that leaves the model (nearly) as it
/// was without the effect; the warm start of a new effect.
double NeutralValue(const ParameterSetting& setting);

/// Segmentation noise of a recording: per frame, the object pixels that
/// differ from both neighbouring frames while those agree (one-frame
/// flicker, which no motion smoother than the frame rate makes). Returns the
/// mean over frames 1..n-2 (0 with fewer than 3 frames).
double SegmentationNoisePx(const std::vector<BitMask>& object_masks);

/// The fall of the held-out mean IoU that an XOR margin of `margin_px`
/// allows: the margin over the object pixels of the held-out recordings
/// (summed over their frames). A rise of the XOR sum by the margin, spread
/// over the frames, lowers each frame's IoU by at most its share over the
/// object's pixels; an IoU fall the XOR margin calls insignificant is no
/// fall (docs/loop.md, the criterion). 0 without object pixels.
double IouTolerance(double margin_px, const std::vector<const std::vector<BitMask>*>& held_out_masks);

/// The parameter sets of a calibration as good as its best on the training
/// recordings: the successful `evaluations` (of one or more jobs of the same
/// model) whose score is within `tolerance` of the lowest, distinct, best
/// first. With more than `limit` of them, `limit` spread evenly over their
/// ranks (the best and the last always among them), so that a fit that
/// converged keeps its spread along flat directions. Deterministic: ties
/// keep the order of `evaluations`.
std::vector<ParameterValues> SelectEquallyGoodFits(const std::vector<EvaluationRecord>& evaluations,
                                                   double tolerance, int limit);

/// Progress lines for people (stage started, calibrated, decided); called
/// on the loop's thread. Presentation only.
using LoopLog = std::function<void(const std::string& line)>;

struct LoopResult {
  LoopReport report;
  std::filesystem::path report_json;
  std::filesystem::path report_html;  ///< empty when not written
  std::filesystem::path store;
  /// The before / after table as text (what `calib loop` prints).
  std::string table;
};

/// Runs the loop. Throws for bad options (std::invalid_argument naming the
/// option), unreadable recordings (RecordingError / JobSpecError naming
/// them) and store errors.
LoopResult RunLoop(const LoopOptions& options, const LoopLog& log = {});

/// The before / after table of a report: per recording its role and the XOR
/// sum and mean IoU of the base and the final model, then the effects kept.
std::string BeforeAfterTable(const LoopReport& report);

}  // namespace calib
