#pragma once
// The report of a closed calibration loop (`calib loop`): which recordings,
// which models were calibrated (the base model, then one more effect at a
// time), which were kept and why, the hypotheses and their evidence, and the
// error of every model on every training and held-out recording.
//
// Plain data: the loop fills a LoopReport; WriteLoopReportJson writes
// report.json (ReadLoopReportJson reads it back exactly) and
// WriteLoopReportHtml (report_html.h) writes report.html with its plots.

#include "calib/core/parameters.h"
#include "calib/evaluator/evaluation.h"
#include "calib/discovery/hypotheses.h"
#include "calib/discovery/residual.h"

#include <nlohmann/json_fwd.hpp>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace calib {

/// One recording the loop used.
struct ReportRecording {
  std::string name;  ///< unique within the report (the folder's name)
  std::string path;
  std::string role = "train";  ///< "train" or "holdout"
  int num_frames = 0;
  double fps = 0.0;
  /// For an object held by clamps: its tip in every frame, the object's
  /// pixel farthest from the clamps' centre (FarthestPixelFrom), px; empty
  /// otherwise.
  std::vector<double> tip_x_px, tip_y_px;
  /// For an object that moves by itself: per frame, the IoU of the mesh
  /// registered to the video (PreparedRecording::registered_iou), what any
  /// model moving this mesh could reach; empty otherwise.
  std::vector<double> registered_iou;
};

/// How one calibrated model did on one recording.
struct RecordingScore {
  std::string recording;       ///< a ReportRecording::name
  std::string status = "ok";   ///< "ok" or "failed"
  /// Failed: the first frame not simulated and why; -1 and empty when ok.
  int failure_frame = -1;
  std::string failure_reason;
  double xor_sum = 0.0;        ///< XOR pixel area (px^2) summed over the frames
  double mean_iou = 0.0;
  std::vector<double> frame_xor;  ///< per frame (may be empty); plotted
  std::vector<double> frame_iou;
  /// For an object held by clamps: the model's tip per frame simulated
  /// (the pixel of the mesh as scored farthest from the clamps' centre, as
  /// the video's tip is taken), px, and the median over
  /// the frames of its distance to the video's tip (ReportRecording); empty
  /// and NaN otherwise.
  std::vector<double> tip_x_px, tip_y_px;
  double median_tip_distance_px = NAN;

  /// From an evaluation (per-frame values included).
  static RecordingScore FromEvaluation(const std::string& recording, const EvaluationResult& result);
};

/// What the loop did with a stage's model.
enum class StageDecision { kBase, kAccepted, kRejected };
std::string ToString(StageDecision decision);  ///< "base", "accepted", "rejected"
/// Throws std::invalid_argument naming the text.
StageDecision StageDecisionFromString(const std::string& text);

/// How far a calibrated model's held-out error is pinned down by its fit:
/// the parameter sets its calibration found as good as the best on the
/// training recordings (within the loop's margin) re-scored on the
/// held-out recordings. An effect's held-out drop must pass at the best
/// fits and between the medians (docs/loop.md, the criterion).
struct EquallyGoodFits {
  int fits = 0;                       ///< distinct parameter sets re-scored; 0: not measured
  double training_tolerance_px = 0.0;  ///< training XOR sum within this of the best
  double holdout_xor_min = 0.0;       ///< held-out XOR sum over the held-out recordings
  double holdout_xor_max = 0.0;
  double holdout_xor_median = 0.0;    ///< the lower median
  double holdout_iou_at_min = 0.0;    ///< held-out mean IoU of the fit with the minimum
};

/// The keep rule's paired test of a tried effect (paired_test.h).
struct StageTest {
  int frames = 0;          ///< held-out frames compared; 0: not tested
  int blocks = 0;
  double drop = 0.0;       ///< held-out XOR sum before minus after (compared frames)
  double drop_low = 0.0;   ///< its 95 % interval
  double drop_high = 0.0;
  double p_value = 1.0;
  /// Benjamini-Hochberg over the hypotheses tried up to this stage's round.
  int hypotheses = 0;
  bool significant = false;
};

/// One calibrated model: the base model, or the kept effects plus one tried.
struct ReportStage {
  std::string name;            ///< e.g. "base", "base+plasticity"
  std::string effect_tried;    ///< empty for the base stage
  StageDecision decision = StageDecision::kBase;
  std::vector<std::string> effects;  ///< the model's effects
  ParameterValues parameters;        ///< calibrated values by name
  std::vector<RecordingScore> errors;  ///< one per recording, training and held out
  std::string criterion;        ///< what decided, e.g. "held-out XOR sum"
  double criterion_value = 0.0;
  std::string reason;           ///< the decision in words, with numbers
  double calibration_time_s = 0.0;
  int evaluations = 0;
  /// Measured for the models the loop builds on (the base, each kept one)
  /// when there are held-out recordings; `fits == 0` otherwise.
  EquallyGoodFits equally_good;
  /// A calibration from scratch (the base model) runs `--restarts`
  /// independent searches: the best training XOR sum each reached, in
  /// order (the first from the box's centre). Empty for warm-started stages.
  std::vector<double> restart_training_xor;
  /// Which calibration of its hypothesis a tried stage is, from 0 (one per
  /// `--effect-restarts`; written only when > 0).
  int restart = 0;
  /// Every successful candidate of the calibration scored the same: the
  /// score does not depend on the parameters (nothing moves the mesh), so
  /// the stage is no fit of them (FitDiagnostics).
  bool uninformative = false;
  /// Searched parameters the fit left on a bound of its box, e.g.
  /// "k_phi = 1e+06 (upper bound)".
  std::vector<std::string> at_bounds;
  /// With held-out recordings, for the base and the final model: the
  /// largest move of the held-out XOR sum when one value of the stage's fit
  /// moves by 0.1 %, and that value; 0: not measured.
  double holdout_sensitivity_px = 0.0;
  std::string holdout_sensitivity_parameter;
  /// The keep rule's test of this stage against the model it extends
  /// (tried stages only; `frames == 0`: not tested).
  StageTest test;

  /// The error on `recording`, or nullptr.
  const RecordingScore* ErrorOn(const std::string& recording) const;
};

/// The hypotheses traced from one stage's residual.
struct HypothesisRound {
  int round = 0;
  std::string stage;  ///< the ReportStage::name whose residual was traced
  std::vector<Hypothesis> hypotheses;  ///< ranked
};

/// The residual analysis of one stage on one recording (heat maps, phases,
/// signatures; written without the per-frame records).
struct ReportResidual {
  std::string recording;
  std::string stage;
  ResidualAnalysis analysis;
};

/// A diagnostic overlay image (evaluator/overlay.h) at a bad moment.
struct ReportOverlay {
  std::string recording;
  std::string stage;
  int frame = 0;
  double xor_px = 0.0;  ///< the frame's XOR area, px^2
  double iou = 0.0;
  std::string png_file;  ///< relative to the report's folder
  std::string caption;
};

/// A pair of effects that look alike in the residual, met in a round
/// (confusions.h): separated or not, by what, and the recording that would.
struct ReportConfusion {
  int round = 0;
  std::string effect;
  std::string confused_with;  ///< "" for the base model (no effect)
  bool separated = false;
  std::string evidence;       ///< what decided, in numbers, or why these recordings cannot
  std::string proposal;       ///< the recording that would separate them; empty when separated
};

struct LoopReport {
  std::string title = "calib loop";
  std::string command;         ///< the command line that made it
  uint64_t seed = 0;
  std::string selection_rule;  ///< how an effect is kept, in words
  double run_time_s = 0.0;
  std::vector<ReportRecording> recordings;
  std::vector<ReportStage> stages;  ///< in the order calibrated; the first is the base
  std::vector<HypothesisRound> rounds;
  std::vector<ReportConfusion> confusions;
  std::vector<std::string> effects_kept;
  std::vector<ReportResidual> residuals;
  std::vector<ReportOverlay> overlays;
  std::vector<std::string> notes;

  /// The first stage, or nullptr.
  const ReportStage* BaseStage() const;
  /// The last kAccepted stage, else the base stage, or nullptr.
  const ReportStage* FinalStage() const;
};

/// report.json: every field above, plus (derived, ignored on reading)
/// "error_table": per recording its role and the XOR sum and mean IoU of
/// the base and the final model, and "final_parameters". NaN is written
/// as null.
nlohmann::json ToJson(const LoopReport& report);
/// Reads what ToJson writes. Throws std::invalid_argument naming the key.
LoopReport LoopReportFromJson(const nlohmann::json& doc);

/// Writes / reads report.json. Throw std::runtime_error naming the path
/// (and std::invalid_argument from LoopReportFromJson for a malformed file).
void WriteLoopReportJson(const std::filesystem::path& path, const LoopReport& report);
LoopReport ReadLoopReportJson(const std::filesystem::path& path);

/// The `count` frames of largest XOR that lie at least `min_gap` frames
/// apart, worst first (for overlays).
std::vector<int> WorstFrames(const std::vector<double>& frame_xor, int count, int min_gap);

}  // namespace calib
