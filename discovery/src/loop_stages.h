#pragma once
// The closed loop's parts (loop.h), shared by its source files:
//   LoopRecording    a recording and its model-independent facts, once;
//   Fit              one calibrated model and how it does everywhere;
//   StageCalibrator  calibrates a model (stage_calibration.cpp) and measures
//                    it: residuals, equally good fits, sensitivity;
//   KeepCriterion    judges whether an effect earns its place
//                    (keep_criterion.cpp).
// loop.cpp orchestrates them.

#include "calib/discovery/loop.h"
#include "calib/discovery/loop_report.h"
#include "calib/discovery/paired_test.h"
#include "calib/discovery/residual.h"
#include "calib/discovery/stage_calibration.h"
#include "calib/evaluator/evaluation.h"
#include "calib/jobs/job_spec.h"
#include "calib/results/store.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace calib::loop_detail {

struct LoopRecording {
  std::string name;
  std::filesystem::path path;
  bool train = true;
  std::shared_ptr<const PreparedRecording> prepared;
  double noise_px = 0.0;  ///< SegmentationNoisePx
  std::shared_ptr<const RecordingResidualFacts> residual_facts;  ///< shared by every fit's analysis
  /// Held out: the frames the keep rule compares start here. 0 for a
  /// held-out recording; the split for a held-out stretch of a training
  /// video (its first frames are the training recording).
  int first_compared_frame = 0;
  /// An object held by clamps: its tip per frame (the object's pixel
  /// farthest from the clamps' centre, FarthestPixelFrom); empty otherwise.
  std::vector<Vec2> video_tips;
};


// A calibration over lengthening horizons (a swing's: frames from its
// start, 0 for the whole recordings).
struct HorizonFit {
  ParameterValues values;
  double score = std::numeric_limits<double>::infinity();  ///< over the last horizon
};

/// One search over horizon k (its index in the horizons) from `from`: its
/// best values and their score over that horizon (infinite where nothing
/// simulated).
using HorizonSearch = std::function<std::pair<ParameterValues, double>(size_t k, const ParameterValues& from)>;
/// The score of `values` over the first `frames` frames (0: all of them).
using HorizonScore = std::function<double(const ParameterValues& values, int frames)>;

/// Follows `horizons` after the first from `fit`, the first horizon's fit:
/// each later horizon is searched from the previous one's best (from the
/// fit so far where a search simulated nothing). The fit is, of the first
/// horizon's fit and every later search's best, the one that scores best
/// over the last horizon (ties: the later horizon's). A search from a point
/// need not evaluate the point, and over a longer horizon a small step of a
/// swing's values puts it out of phase by the end: a longer horizon's
/// search can end worse over the whole recordings than a shorter one's
/// best. `chosen` (if set) hears where an earlier horizon's best is the
/// fit: its frames, its score and the last search's, over the last horizon.
HorizonFit FollowHorizons(const std::vector<int>& horizons, ParameterValues fit,
                          const HorizonSearch& search, const HorizonScore& score,
                          const std::function<void(int frames, double score, double last)>& chosen = {});

// One calibrated model and how it does everywhere.
struct Fit {
  std::vector<std::string> effects;
  ParameterValues values;
  std::vector<EvaluationResult> results;     ///< per recording (loop order)
  std::vector<ResidualAnalysis> residuals;   ///< per recording
  int evaluations = 0;
  double seconds = 0.0;
  std::vector<int64_t> jobs;  ///< the store's jobs of its calibration
  /// Those of `jobs` that scored their candidates on the whole training
  /// recordings, as the fit's training score is (a swing's shorter
  /// horizons do not): the candidates that rank against the fit.
  std::vector<int64_t> whole_recording_jobs;
  std::vector<double> restart_training_xor;  ///< from scratch: each search's best
  /// Measure: per recording with clamps, the model's tip per frame
  /// simulated (the node farthest from the clamps' centre); empty otherwise.
  std::vector<std::vector<Vec2>> tips;
  /// Every job of the calibration scored all its candidates the same
  /// (FitDiagnostics::uninformative), and the searched parameters the fit
  /// left on a bound of the stage's box.
  bool uninformative = false;
  std::vector<std::string> at_bounds;
  /// The boxes the calibration searched at the end, where it widened
  /// some (WidenPinnedBoxes; a stage that continues this fit searches
  /// boxes at least as wide); empty otherwise.
  std::vector<ParameterSetting> widened_settings;
  EquallyGoodFits equally_good;  ///< MeasureEquallyGood; fits == 0 until then
  /// MeasureSensitivity: the largest move of the held-out XOR sum when one
  /// value moves by 0.1 % (px; 0 until measured), and that value's name.
  double holdout_sensitivity_px = 0.0;
  std::string holdout_sensitivity_parameter;
  /// What a refit where the calibration's best failed on a held-out
  /// recording did (LoopOptions::refit_candidates); empty when none ran.
  std::string refit;
  /// Which of the calibrations of its hypothesis this is (0: the first;
  /// LoopOptions::effect_restarts).
  int restart = 0;

  /// The XOR sum over the training (or held-out) recordings; held out: over
  /// their compared frames. +infinity where a recording failed.
  double XorSum(const std::vector<LoopRecording>& recs, bool train) const;
  /// Per held-out recording, the XOR of each compared frame.
  std::vector<std::vector<double>> HeldOutFrameErrors(const std::vector<LoopRecording>& recs) const;
  bool AllOk() const;
};

/// Widens by `factor` (> 1) each bound of a searched log-scaled box in
/// `settings` that `values` lies on (ValuesOnBounds, as DiagnoseFit
/// reports it), within the parameter's range in `specs`: such a
/// box is a guess from the recordings' scales (a stiffness, a damping), and
/// a fit pinned to it may have its optimum outside. `values` holds every
/// searched name (SearchSpace::ToUnit's std::invalid_argument otherwise).
/// Returns one line per bound widened ("k_d: upper 10000 -> 316228");
/// empty when none was.
std::vector<std::string> WidenPinnedBoxes(std::vector<ParameterSetting>& settings,
                                          const ParameterValues& values,
                                          const std::vector<ParameterSpec>& specs, double factor);

/// Widens each searched box of `settings` to hold the box of the same name
/// in `wider` (a previous calibration's widened boxes).
void IncludeBoxes(std::vector<ParameterSetting>& settings, const std::vector<ParameterSetting>& wider);

/// "base+viscoelastic" for logs and reports.
std::string StageName(const std::vector<std::string>& effects);

/// The held-out score of one parameter set on one recording.
struct HeldOutScore {
  bool ok = false;
  double xor_sum = 0.0;
  double mean_iou = 0.0;
  int failure_frame = -1;  ///< failed: the first frame not simulated
};

/// Whether a fit that simulates held-out recording `r` whole (`ok`), or
/// fails there from `failure_frame`, can be compared there with
/// `reference` (null: none given): it simulates the whole recording, or
/// the reference fails there too, no later than it does (the keep rule
/// then compares the frames the reference simulated).
bool ComparableOnHeldOut(bool ok, int failure_frame, const Fit* reference, size_t r);

/// Judges an effect: does recalibrating with it lower the held-out error?
/// Each candidate gets a p-value from a paired block test of the per-frame
/// held-out XOR (paired_test.h); the loop corrects them for the number of
/// hypotheses tried (Benjamini-Hochberg) and keeps only those that pass.
class KeepCriterion {
 public:
  KeepCriterion(const LoopOptions& options, const std::vector<LoopRecording>& recs)
      : o_(options), recs_(recs) {}

  struct Verdict {
    /// Every recording simulates, the training XOR sum does not rise and
    /// the held-out mean IoU does not fall: the test decides.
    bool eligible = false;
    PairedTestResult test;  ///< of the held-out frames (p = 1 when not eligible)
    double before = 0.0;    ///< held-out XOR sum (compared frames)
    double after = 0.0;
    std::string reason;     ///< the measurements in words; the loop adds the decision
  };
  /// `candidate` against `previous`, or against `ablation` (the previous
  /// model with the candidate's values) where that is better on the
  /// training recordings. `seed` seeds the test's signs.
  Verdict Judge(const Fit& previous, const Fit* ablation, const Fit& candidate,
                uint64_t seed) const;

  /// The training recordings' segmentation noise summed over their frames.
  double TrainingNoise() const;

 private:
  const LoopOptions& o_;
  const std::vector<LoopRecording>& recs_;
};

/// Calibrates models on the training recordings (jobs of the loop's store)
/// and measures them on every recording.
class StageCalibrator {
 public:
  StageCalibrator(const LoopOptions& options, const std::vector<LoopRecording>& recs,
                  const SearchScales& scales, const KeepCriterion& criterion, ResultStore& store,
                  int threads, const LoopLog& log)
      : o_(options), recs_(recs), scales_(scales), criterion_(criterion), store_(store),
        threads_(threads), log_(log) {}

  /// Calibration `index` of the base model plus `effects`: from scratch
  /// (independent searches) or warm-started from the fit `warm` of the
  /// model without the last effect. Measured on every recording. A warm
  /// start's `restart` > 0 (LoopOptions::effect_restarts) starts the new
  /// effect's search at RestartStart's point of its box instead of its
  /// neutral values.
  Fit Calibrate(int index, const std::vector<std::string>& effects, const Fit* warm,
                int restart = 0);
  /// Whether Calibrate starts `effects` from scratch although a fit `warm`
  /// of the model without its last effect is given: adding inertia to a
  /// first-order model of a swinging object (SearchScales::swing_stiffness).
  bool StartsCold(const std::vector<std::string>& effects, const Fit& warm) const;
  /// The fit's results and residuals on every recording.
  void Measure(Fit* fit) const;
  /// Where `fit` simulates every training recording but fails on a
  /// held-out one where it cannot be compared with `reference` (the model
  /// it will be judged against, may be null; ComparableOnHeldOut): the
  /// first of its
  /// calibration's next best candidates by training score
  /// (RankedByTrainingScore) that simulates every held-out recording, or
  /// as far as the reference does, becomes the fit, measured again
  /// (LoopOptions::refit_candidates). Says what it did in fit->refit.
  void RefitWhereHeldOutFails(Fit* fit, const Fit* reference) const;
  /// The spread of the held-out error over the fit's equally good fits.
  void MeasureEquallyGood(Fit* fit) const;
  /// How far a 0.1 % nudge of each of the fit's values moves its held-out
  /// error (report only).
  void MeasureSensitivity(Fit* fit) const;

 private:
  void Log(const std::string& line) const {
    if (log_) log_(line);
  }
  // The job's best values and training score; empty values and +inf
  // where no candidate simulated every training recording.
  int64_t FindOrCreateJob(const JobSpec& spec);
  std::pair<ParameterValues, double> RunJob(const std::string& name,
                                            const std::vector<std::string>& effects,
                                            const std::vector<ParameterSetting>& settings,
                                            const std::vector<double>* x0, double sigma,
                                            int64_t budget, uint64_t seed, Fit* fit,
                                            int frames = 0);
  // Calibration of a model with inertia on a freely swinging object
  // (SearchScales::swing_stiffness): horizons lengthening from two swing
  // periods to the whole recordings. Returns the fit's values.
  ParameterValues CalibrateSwing(int index, const std::vector<std::string>& effects,
                                 std::vector<ParameterSetting>* settings, int64_t budget,
                                 uint64_t seed, Fit* fit);
  /// The training recordings (their first `frames` frames; 0: every frame).
  std::vector<std::shared_ptr<const PreparedRecording>> TrainingRecordings(int frames) const;
  /// The training recordings' XOR sum of `values` (over their first
  /// `frames` frames; 0: every frame); infinity where it fails.
  double TrainingScore(const std::vector<std::string>& effects, const ParameterValues& values,
                       int frames = 0) const;
  std::vector<int> HeldOutIndices() const;
  /// Held-out recordings are there and none is a stretch of a training video.
  bool WholeRecordingsHeldOut() const;
  /// Every parameter set of `sets` on every held-out recording, through the
  /// batch evaluator: result i is set i / H on held-out recording i % H (H
  /// held-out recordings). A set the model rejects is a failed result.
  std::vector<HeldOutScore> ScoreOnHeldOut(const std::vector<ParameterValues>& sets,
                                           const std::vector<std::string>& effects) const;
  std::unique_ptr<BatchEvaluator> MakeEvaluator(const Objective& objective) const;

  const LoopOptions& o_;
  const std::vector<LoopRecording>& recs_;
  const SearchScales& scales_;
  const KeepCriterion& criterion_;
  ResultStore& store_;
  int threads_ = 1;
  const LoopLog& log_;
};

}  // namespace calib::loop_detail
