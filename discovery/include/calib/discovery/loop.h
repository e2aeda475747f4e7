#pragma once
// The closed loop behind `calib loop`: calibrate the base model, analyse the
// residual of the best fit on every recording, trace it to ranked effect
// hypotheses, add the most promising effects one at a time, recalibrate,
// keep an effect only when a paired test says it lowers the held-out error
// (corrected for the hypotheses tried), and report everything (report.json,
// report.html, a before / after table). Documented in docs/loop.md.
//
// Each calibration is a job of the results store DIR/store.sqlite (the
// runner of runner.h, given a typed CalibrationRequest), named after its
// model ("stage1-base", "stage2-base.viscoelastic", ...). Calibrations and
// the re-scoring of parameter sets on the held-out recordings go through a
// BatchEvaluator (OpenMP threads unless LoopOptions::make_evaluator says
// otherwise). Everything the loop decides depends
// only on the recordings, the options and the seed: the same inputs give the
// same report numbers at any thread count.
//
// The loop never reads what a recording does not declare: recording.json,
// track.csv and the video only (a synthetic recording's truth.json is never
// opened).

#include "calib/core/parameters.h"
#include "calib/core/simulator.h"
#include "calib/discovery/hypotheses.h"
#include "calib/discovery/keep_criterion.h"
#include "calib/discovery/loop_report.h"
#include "calib/discovery/residual.h"
#include "calib/discovery/stage_calibration.h"
#include "calib/evaluator/evaluation.h"
#include "calib/jobs/batch_evaluator.h"
#include "calib/jobs/objective.h"
#include "calib/results/store.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
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
  /// Keep out_dir's store and continue the calibration jobs it holds (each
  /// from its last checkpoint; finished ones are read back): a loop killed
  /// part way and resumed with the same options ends with the numbers of an
  /// uninterrupted one. A stored job made by other options is an error.
  /// false: the store is started afresh.
  bool resume = false;
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
  /// Ranks the hypotheses by the rate at which a hypothesis of the same
  /// effect and confidence was right on the tuning family (RankedByRate,
  /// hypotheses.h) instead of by confidence.
  bool rank_by_rate = false;
  /// The keep rule (docs/loop.md): an effect is kept when a paired block
  /// test of its per-frame held-out XOR drop (paired_test.h) is significant
  /// after the Benjamini-Hochberg correction over every hypothesis the loop
  /// has tried, at this false-discovery rate.
  double false_discovery_rate = 0.05;
  /// The smallest held-out drop worth a model term, as a fraction of the
  /// reference's held-out XOR: the test's null hypothesis is "the effect
  /// lowers the held-out error by at most this much", so a term that buys a
  /// consistent but negligible drop (a few pixels a frame) is not kept.
  double min_relative_drop = 0.02;
  /// Random sign sets of the test (its smallest p-value is 1 / (n + 1)).
  int test_resamples = 9999;
  /// With no held-out recording, the training videos' frames from this
  /// fraction on are held out: the loop calibrates on the frames before and
  /// tests on the rest (a held-out stretch of each training video).
  double held_out_stretch = 1.0 / 3.0;
  /// Report only: up to this many of a calibration's parameter sets as good
  /// as its best on training (SelectEquallyGoodFits, within the training
  /// recordings' segmentation noise or 1 % of the best) re-scored on the
  /// held-out recordings, to show how far the training data pin the
  /// held-out error down. 0: not measured.
  int equally_good_fits = 0;
  /// Where a calibration's best fit on the training recordings fails to
  /// simulate a held-out recording (a fit that snaps through on another
  /// push), the effect is refitted within the parameters that simulate:
  /// up to this many of the calibration's next best candidates by training
  /// score are run on the held-out recordings, best first, and the first
  /// that simulates every one of them is the fit. The held-out recordings
  /// answer only "does it simulate"; their scores play no part. 0: the
  /// failing fit is judged as it is (and rejected).
  int refit_candidates = 24;
  /// Independent searches of a calibration from scratch (the base model),
  /// each with the whole `budget`: the first from the box's centre, the
  /// others from seeded points of the box (RestartStart). The best on the
  /// training recordings is the fit; every search's records count towards
  /// its equally good fits. A flat or two-basin training error lands one
  /// search in the worse basin as often as not (docs/loop.md).
  int restarts = 3;
  /// Calibrations of each hypothesis tried (an effect added to the current
  /// model), each from its own seed, the first as a single calibration is,
  /// the others with the new effect's search started at seeded points of its
  /// box (RestartStart). Each calibration is a hypothesis of its own for the
  /// keep rule: its paired test counts in the Benjamini-Hochberg correction,
  /// and the round keeps the largest passing drop, as among effects. An
  /// effect's warm-started search lands in one of its basins by chance
  /// (docs/loop.md, "Restarts of the effect stages"); more calibrations find
  /// the one that holds on another recording more often, at a stricter
  /// correction and their cost.
  int effect_restarts = 1;
  /// A held-out recording of the object the first training recording
  /// shows (held in the same clamps, its own rest shape of the same area,
  /// its frame-0 outline reached by the training mesh on registration:
  /// evaluator/object_transfer.h) is
  /// simulated with the training recording's mesh, rest shape and element
  /// areas, from its own frame-0 pose and velocities. Off: every recording
  /// is meshed and its rest shape estimated on its own.
  bool carry_object_model = true;
  SimulationOptions simulation = LoopSimulationDefaults();
  PreparationOptions preparation;
  /// Report: overlay PNGs of the worst frames (base and final model).
  int overlays_per_recording = 2;
  bool write_html = true;
  std::string command;  ///< the command line, for the report
  /// Makes the batch evaluator of each calibration and of each re-scoring
  /// on the held-out recordings (an objective over those recordings).
  /// Null: OpenMP threads (`threads`). The history and every decision are
  /// the same for any evaluator (batch_evaluator.h).
  std::function<std::unique_ptr<BatchEvaluator>(const Objective& objective, int threads)>
      make_evaluator;
  /// Polled between the candidates of every calibration; true stops the
  /// loop resumably: the calibration stops at a checkpoint and RunLoop
  /// throws LoopStopped (`resume` then continues it, as after a kill).
  /// Null: never (`calib loop` stops on a signal by dying).
  std::function<bool()> interrupted;

  /// False with a message naming the option and the rule.
  bool IsValid(std::string* error) const;
};

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

/// Thrown by RunLoop when LoopOptions::interrupted stopped it; the store
/// keeps every calibration's evaluations and checkpoints.
class LoopStopped : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Runs the loop. Throws LoopStopped when interrupted, and for bad options (std::invalid_argument naming the
/// option), unreadable recordings (RecordingError / JobSpecError naming
/// them) and store errors.
LoopResult RunLoop(const LoopOptions& options, const LoopLog& log = {});

/// The before / after table of a report: per recording its role and the XOR
/// sum and mean IoU of the base and the final model, then the effects kept.
std::string BeforeAfterTable(const LoopReport& report);

}  // namespace calib
