#pragma once
// Residual analysis: where, when and how the simulated mesh of a fitted model
// and the segmented object still disagree, summarised as numbers that point
// at a physical effect the model lacks (hypotheses.h turns them into ranked
// effects).
//
// One pass. A ResidualAnalyser is built from a recording's object masks, rest
// mesh and scene; it is then fed every simulated frame in order, directly as
// the on_frame callback of Evaluator::Evaluate:
//
//   ResidualAnalyser analyser(prepared);
//   evaluator.Evaluate(params, analyser);
//   const ResidualAnalysis analysis = analyser.Finish();
//
// What does not depend on the model (load phases, the object masks'
// moments, change and deformation, the push, the rest shape's figures) is a
// RecordingResidualFacts, computed once per recording and shared read-only
// by the analysers of every fit on it (also on several threads at once):
//
//   auto facts = std::make_shared<const RecordingResidualFacts>(
//       ComputeResidualFacts(prepared));
//   ResidualAnalyser analyser(facts);  // one per fit
//
// Per frame it splits the XOR of object and mesh into missed pixels (object,
// not mesh) and extra pixels (mesh, not object); counts them in distance
// bands around every obstacle disc; maps each one back to the rest shape
// (extra pixels through the barycentric coordinates of the simulated
// triangle that covers them, missed pixels through the nearest point of the
// simulated boundary) and accumulates heat maps and region counts there; and
// measures global motion (centroid and principal-axis orientation of both
// masks). Over time it splits the recording into load phases (from the force
// track and the pusher's motion), and finds trends, oscillations, lags, the
// residual that persists after release and the relation of error to
// deformation.
//
// It reads the mesh as the bit mask that Evaluator hands on_frame (the
// pixels the mesh covers at least half), so its counts are whole pixels,
// near but not equal to the score's XOR of pixel areas (scoring.h).
//
// Conventions: frame pixels (x right, y down, origin at the top-left pixel's
// corner; a mask pixel stands for its centre). Angles in radians, measured
// from +x towards +y (clockwise on screen). "Offset" is always mesh minus
// object. Values that cannot be measured (an empty mask, no release) are NaN
// in the structs and null in JSON.

#include "calib/core/mesh.h"
#include "calib/core/scene.h"
#include "calib/core/simulator.h"
#include "calib/discovery/load_phases.h"
#include "calib/discovery/signals.h"
#include "calib/evaluator/bit_mask.h"
#include "calib/evaluator/mask_geometry.h"
#include "calib/evaluator/rasterizer.h"
#include "calib/evaluator/scoring.h"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace calib {

struct PreparedRecording;
struct EvaluationResult;

// ===========================================================================
// The analysis.

struct ResidualOptions {
  /// Upper edges of the distance bands around each obstacle disc, pixels
  /// from the disc's edge (negative distances, inside the disc, fall in the
  /// first band); pixels beyond the last edge of every obstacle are "far".
  std::vector<double> obstacle_bands_px = {5.0, 10.0, 20.0, 40.0};
  /// Rest-shape heat map: about this many square cells over the rest
  /// shape's bounding box.
  int heat_map_cells = 150;
  /// Smallest radius of the contact zone on the rest shape, pixels (it
  /// grows with the object: PushSummary::contact_zone_radius_px).
  double contact_radius_px = 10.0;
  /// An obstacle touches the object when an object pixel lies within this
  /// distance of its disc.
  double contact_margin_px = 3.0;
  /// Largest lag searched between object and mesh motion, seconds.
  double max_lag_s = 1.0;
  PhaseOptions phases;
  OscillationOptions oscillation;

  bool IsValid(std::string* error) const;
};

/// The turns of the mesh ResidualFrame::rigid_xor_px searches: within
/// +-kRigidTurnSearchDeg, every 2 degrees, then half degrees around the
/// best.
inline constexpr double kRigidTurnSearchDeg = 20.0;

/// What one frame's residual looks like.
struct ResidualFrame {
  int frame = 0;
  double time_s = 0.0;
  LoadPhase phase = LoadPhase::kFree;
  int64_t missed_px = 0;  ///< object, not mesh
  int64_t extra_px = 0;   ///< mesh, not object
  int64_t object_px = 0;
  int64_t mesh_px = 0;
  double iou = 0.0;
  /// XOR after shifting the mesh mask by the rounded centroid offset: the
  /// part of the error that a translation cannot remove ("shape error").
  int64_t aligned_xor_px = 0;
  /// XOR after the rigid motion that lays the mesh best onto the object
  /// (centroid onto centroid, then the best turn about it within
  /// +-kRigidTurnSearchDeg): the part of the error no change of pose
  /// removes, the shape's own. A pose left wrong (the body turned or slid
  /// otherwise than the object) is not in it.
  int64_t rigid_xor_px = 0;
  double rigid_turn_rad = 0.0;  ///< that turn of the mesh (counterclockwise in the image > 0)
  Vec2 object_centroid_px{NAN, NAN};
  Vec2 mesh_centroid_px{NAN, NAN};
  Vec2 offset_px{NAN, NAN};  ///< mesh centroid - object centroid
  double object_angle_rad = NAN;
  double mesh_angle_rad = NAN;
  double angle_diff_rad = NAN;  ///< mesh - object, in (-pi/2, pi/2]
  double force_n = 0.0;         ///< |force| of the sensor, 0 without one
  /// Object deformation: XOR of this frame's object with frame 0's, aligned
  /// by centroid, over frame 0's object area (model independent).
  double object_deformation = 0.0;
  double mesh_mean_strain = 0.0;  ///< mean |l / l0 - 1| over the mesh edges
  double mesh_max_strain = 0.0;
  /// XOR with the previous frame's mask (0 in frame 0): how much each moves.
  int64_t object_change_px = 0;
  int64_t mesh_change_px = 0;
  /// Per obstacle o and band b (index o * num_bands + b): residual pixels
  /// whose distance to disc o's edge falls in band b.
  std::vector<int64_t> band_missed_px;
  std::vector<int64_t> band_extra_px;
  int64_t far_missed_px = 0;  ///< beyond the last band of every obstacle
  int64_t far_extra_px = 0;
};

/// Residual pixels counted over regions of the rest shape (pixel-frames).
struct RegionCounts {
  int64_t missed = 0;
  int64_t extra = 0;
};

/// Regions of the rest shape. Axes: `push_axis` points from the pusher into
/// the object (image +y without a push), `side_axis` is push_axis turned
/// +90 degrees. "near"/"far": the halves towards / away from the pusher,
/// split through the rest centroid; "side_neg"/"side_pos": the halves either
/// side of the line through the contact site (the rest centroid without a
/// push) along push_axis; left/right/top/bottom: image-axis halves through
/// the rest centroid; "contact": within PushSummary::contact_zone_radius_px
/// of the contact site.
enum class RestRegion {
  kNear, kFar, kSideNeg, kSidePos, kLeft, kRight, kTop, kBottom, kContact, kAll
};
inline constexpr int kNumRestRegions = 10;
std::string ToString(RestRegion region);

/// Heat map of residual pixels over the rest shape: a cols x rows grid of
/// square cells of cell_px, top-left corner at origin_px; values per cell,
/// row-major (index row * cols + col), summed over frames.
struct RestHeatMap {
  Vec2 origin_px = Vec2::Zero();
  double cell_px = 1.0;
  int cols = 0;
  int rows = 0;
  std::vector<double> area_px;  ///< rest-shape pixels in each cell
  std::vector<double> missed;   ///< all frames
  std::vector<double> extra;
  std::vector<double> loaded_missed;    ///< loading, hold and unloading frames
  std::vector<double> loaded_extra;
  std::vector<double> released_missed;  ///< released frames
  std::vector<double> released_extra;
};

/// Mean figures over the frames of one phase.
struct PhaseSummary {
  LoadPhase phase = LoadPhase::kFree;
  int num_frames = 0;
  int first_frame = -1;
  int last_frame = -1;
  double mean_xor_px = 0.0;
  double mean_missed_px = 0.0;
  double mean_extra_px = 0.0;
  double mean_aligned_xor_px = 0.0;
  double mean_iou = 0.0;
  double mean_offset_px = 0.0;  ///< mean |offset|
  double xor_slope_px_per_s = 0.0;
  double offset_slope_px_per_s = 0.0;  ///< trend of |offset|
  double mean_object_change_px = 0.0;
  double mean_mesh_change_px = 0.0;
  double mean_force_n = 0.0;
  /// Centroid travel (net displacement first -> last frame of the phase's
  /// first run), pixels.
  double object_travel_px = 0.0;
  double mesh_travel_px = 0.0;
};

/// Global motion of object and mesh.
struct MotionSummary {
  Vec2 mean_offset_px{NAN, NAN};
  double mean_abs_offset_px = NAN;
  double max_abs_offset_px = NAN;
  /// |mean offset| / mean |offset|: 1 when the offset always points one way.
  double offset_consistency = 0.0;
  double offset_slope_px_per_s = 0.0;  ///< trend of |offset|
  double mean_angle_diff_rad = NAN;
  double max_abs_angle_diff_rad = NAN;
  double mean_anisotropy = 0.0;  ///< of the object (angles mean little below ~0.2)
  /// Principal direction of the object's centroid motion (unit) and the RMS
  /// of object / mesh centroid positions along it.
  Vec2 motion_axis{NAN, NAN};
  double object_motion_rms_px = 0.0;
  double mesh_motion_rms_px = 0.0;
  /// Lag (frames, > 0: the mesh follows the object later) maximising the
  /// correlation of the two centroid tracks along motion_axis, and that
  /// correlation; lag_correlation0 is the correlation at lag 0.
  int lag_frames = 0;
  double lag_s = 0.0;
  double lag_correlation = 0.0;
  double lag_correlation0 = 0.0;
  /// Net centroid displacement, first to last analysed frame.
  Vec2 object_displacement_px = Vec2::Zero();
  Vec2 mesh_displacement_px = Vec2::Zero();
  /// Path length of the (5-frame smoothed) centroid tracks.
  double object_path_px = 0.0;
  double mesh_path_px = 0.0;
  /// Mean offset along image +y (down): > 0 when the mesh hangs lower.
  double mean_offset_down_px = NAN;
};

/// Oscillations of the residual and of the motions.
struct OscillationSummary {
  Oscillation offset;          ///< offset along its principal direction
  Oscillation object_motion;   ///< object centroid along motion_axis
  Oscillation mesh_motion;     ///< mesh centroid along motion_axis
  Oscillation xor_px;          ///< the XOR count
  Oscillation angle_diff;      ///< orientation difference
};

/// What happens after the load is gone (only when there is a release).
struct PersistenceSummary {
  bool released = false;
  int release_frame = -1;    ///< first frame of the first kReleased run
  int released_frames = 0;
  double before_xor_px = NAN;    ///< mean XOR before the load (the fit's floor)
  double loaded_xor_px = NAN;    ///< mean XOR over loaded frames
  double peak_loaded_xor_px = NAN;  ///< mean XOR over the loaded third of largest force
  double released_xor_px = NAN;  ///< mean XOR over the released frames
  double released_early_xor_px = NAN;  ///< first third of the released frames
  double released_late_xor_px = NAN;   ///< last third
  /// (late released - before) / (loaded - before), clamped to >= 0: the share
  /// of the loaded residual that stays (NaN without a before phase the
  /// floor is 0).
  double persistent_ratio = NAN;
  /// The same over the rigidly aligned XOR (ResidualFrame::rigid_xor_px):
  /// the share of the loaded shape error that stays once the load is gone,
  /// a pose left wrong not counted.
  double before_rigid_xor_px = NAN;
  double loaded_rigid_xor_px = NAN;
  double released_late_rigid_xor_px = NAN;
  double shape_persistent_ratio = NAN;
  /// (early released - late released) / (loaded - before), >= 0: the share
  /// that fades after release.
  double fading_ratio = NAN;
  /// Share of the released residual (rest-shape pixels) inside the contact
  /// zone, and that share over the zone's share of the rest area.
  double contact_fraction = NAN;
  double contact_concentration = NAN;
  /// Exponential fit of the XOR after release.
  ExponentialFit recovery;
  /// Seconds after release until the object's (mesh's) frame-to-frame
  /// change falls to its noise floor for good; NaN if it never does.
  double object_settle_s = NAN;
  double mesh_settle_s = NAN;
  double object_change_floor_px = 0.0;  ///< the object's quietest 9-frame median change
};

/// The pusher stopping: does the mesh keep going?
struct PushSummary {
  bool has_push = false;
  int peak_frame = -1;         ///< frame of the largest force (or deepest contact)
  double peak_force_n = 0.0;
  Vec2 push_axis{0.0, 1.0};    ///< unit, from the pusher into the object
  Vec2 contact_site_px{NAN, NAN};  ///< rest-shape point under the pusher at the peak
  /// Radius of the contact zone around it: max(contact_radius_px, a quarter
  /// of the rest shape's radius of gyration, 1.5 x the pusher's radius).
  double contact_zone_radius_px = 0.0;
  /// Push distance: pusher travel along push_axis while loaded, pixels.
  double push_distance_px = 0.0;
  /// Pearson correlation of |offset| with the push distance so far, over the
  /// loaded frames, and the slope (px of offset per px pushed).
  double offset_push_correlation = 0.0;
  double offset_per_push = 0.0;
  /// Offset along push_axis (mesh ahead of the object > 0), mean over
  /// loaded frames and at the last loaded frame.
  double mean_offset_along_push_px = NAN;
  /// Centroid displacement along push_axis from the first frame in which the
  /// pusher stands still while loaded to the end of that still period
  /// (and the released frames after it).
  double mesh_travel_after_stop_px = 0.0;
  double object_travel_after_stop_px = 0.0;
  int stopped_frames = 0;
  /// Relative change of |force| over the hold (end - start) / start; NaN
  /// without a hold of >= 3 frames.
  double hold_force_change = NAN;
  /// Offset side of the load: |contact site - rest centroid| along side_axis
  /// over half the rest shape's extent along it (0: central push).
  double load_eccentricity = 0.0;
  /// How the sensor's force grows with the pusher's travel into the object
  /// while it loads (model independent): the least-squares exponent p of
  /// F ~ travel^p over the loading frames up to the peak force with F at
  /// least a tenth of the peak, the travel counted from the contact (the
  /// last frame before the peak with F under 2 % of the peak). A linear
  /// material dented by a round pusher against a stop gives p ~ 1; one that
  /// stiffens with strain gives more, one that yields or slides less. NaN
  /// without a force sensor, a moving pusher or 6 such frames.
  double force_travel_exponent = NAN;
  int force_travel_frames = 0;
  double force_travel_correlation = 0.0;  ///< of log F with log travel
};

/// Residual against deformation.
struct StrainSummary {
  int num_frames = 0;  ///< frames used (loaded ones, or all without a push)
  /// Frames split into thirds by object deformation: mean deformation and
  /// mean XOR over each third.
  std::array<double, 3> deformation{0.0, 0.0, 0.0};
  std::array<double, 3> xor_px{0.0, 0.0, 0.0};
  /// Signed share (missed - extra) / (missed + extra) in each third.
  std::array<double, 3> signed_share{0.0, 0.0, 0.0};
  double correlation = 0.0;  ///< XOR against deformation
  /// (xor_high - xor_mid) / (xor_mid - xor_low) per unit deformation step:
  /// > 1 when the error grows faster at large deformation.
  double convexity = NAN;
  /// Least-squares exponent p of (XOR - floor) ~ deformation^p.
  double exponent = NAN;
};

/// Residual pixels by rest-shape region.
struct RegionSummary {
  /// Pixel-frames per region and phase group (0: all frames, 1: loaded,
  /// 2: released).
  std::array<std::array<RegionCounts, kNumRestRegions>, 3> counts{};
  std::array<double, kNumRestRegions> area_px{};  ///< rest-shape area of each region
  /// Density contrast of the signed residual (missed - extra per rest pixel)
  /// between side_neg and side_pos, over the mean unsigned density, loaded
  /// frames (all frames without a push); in [0, 2].
  double side_asymmetry = 0.0;
  /// |density(side_neg) - density(side_pos)| / sum, unsigned residual.
  double side_imbalance = 0.0;
  /// Same for near/far (loaded frames).
  double near_far_asymmetry = 0.0;
  /// Dipole of the signed residual over the rest shape (rest pixels,
  /// loaded frames or all without a push), normalised by the residual's
  /// total and the rest shape's radius of gyration; |dipole| in [0, ~1.5].
  Vec2 signed_dipole = Vec2::Zero();
  /// Its component along the push's side axis (across the push line):
  /// what a stiffer or softer side shows; along the push a dent alone gives
  /// a dipole.
  double side_dipole = 0.0;
};

/// Everything the analysis found for one recording and one parameter set.
struct ResidualAnalysis {
  std::string recording;  ///< a name for reports (the folder's name)
  double fps = 0.0;
  int num_frames = 0;       ///< frames in the recording
  int frames_analysed = 0;  ///< frames fed (fewer when the simulation failed)
  std::vector<std::string> obstacle_names;
  std::vector<double> obstacle_bands_px;
  Vec2 rest_centroid_px = Vec2::Zero();
  double rest_area_px = 0.0;
  double rest_perimeter_px = 0.0;
  double rest_radius_of_gyration_px = 0.0;

  int64_t xor_sum = 0;  ///< XOR pixels of the bit masks over the frames analysed
  double mean_xor_px = 0.0;
  double mean_iou = 0.0;
  double mean_aligned_xor_px = 0.0;
  /// Mean XOR over the rest perimeter: the residual's mean thickness
  /// (pixels); segmentation noise and rasterisation alone give ~0.5-1.
  double residual_thickness_px = 0.0;
  /// The same for the 90th percentile of the per-frame XOR (a residual that
  /// shows only in part of the recording).
  double p90_thickness_px = 0.0;
  /// Worst frames (largest XOR, at least 5 % of the recording apart), worst
  /// first, at most 5.
  std::vector<int> worst_frames;

  std::vector<ResidualFrame> frames;
  std::vector<PhaseSummary> phases;  ///< one per phase kind present, LoadPhase order
  /// Sums over all frames per obstacle and band (index o * bands + b).
  std::vector<int64_t> band_missed_px;
  std::vector<int64_t> band_extra_px;
  int64_t far_missed_px = 0;
  int64_t far_extra_px = 0;
  RestHeatMap heat_map;
  RegionSummary regions;
  MotionSummary motion;
  OscillationSummary oscillation;
  PersistenceSummary persistence;
  PushSummary push;
  StrainSummary strain;

  /// The summary of `phase`, or nullptr when no frame is in it.
  const PhaseSummary* Phase(LoadPhase phase) const;
  /// A few lines for logs.
  std::string BriefReport() const;
};

/// JSON of an analysis (per-frame records only with include_frames); NaN is
/// written as null. FromJson reads what ToJson writes (null -> NaN) and
/// throws std::invalid_argument naming the key on a malformed document.
nlohmann::json ToJson(const ResidualAnalysis& analysis, bool include_frames = true);
ResidualAnalysis ResidualAnalysisFromJson(const nlohmann::json& doc);

/// What the residual analysis knows about a recording before the pass: all
/// that depends on the recording and the options but not on the model or
/// its parameters. Computed once per recording (ComputeResidualFacts) and
/// shared read-only by any number of ResidualAnalysers.
struct RecordingResidualFacts {
  /// The parts it was computed from; not owned: they must outlive the facts
  /// and every analyser built on them.
  const Mesh* rest_mesh = nullptr;
  const Scene* scene = nullptr;
  const std::vector<BitMask>* object_masks = nullptr;
  std::vector<std::string> obstacle_names;  ///< one per scene obstacle
  std::string recording_name;
  ResidualOptions options;

  /// Per frame (scene.num_frames entries each).
  std::vector<LoadPhase> phases;
  std::vector<MaskMoments> object_moments;
  std::vector<double> force_n;             ///< |force| of the sensor, 0 without one
  std::vector<double> object_deformation;  ///< ResidualFrame::object_deformation
  std::vector<int64_t> object_change_px;   ///< ResidualFrame::object_change_px
  int pusher = -1;  ///< the force obstacle, else the obstacle that travels most; -1: none
  /// The push's model-independent fields (peak, axis, contact site and zone,
  /// distance, eccentricity); Finish fills in the rest.
  PushSummary push;
  Vec2 rest_centroid_px = Vec2::Zero();
  double rest_area_px = 0.0;
  double rest_perimeter_px = 0.0;
  double rest_radius_of_gyration_px = 0.0;
  Vec2 side_axis{1.0, 0.0};  ///< push_axis turned +90 degrees
  Vec2 side_origin_px = Vec2::Zero();  ///< the contact site, the rest centroid without a push
  /// The accumulators' starting state: the heat map's grid and rest areas
  /// (all sums 0) and the regions' rest areas (all counts 0).
  RestHeatMap heat_map;
  RegionSummary regions;
};

/// The facts of a recording given by its parts (which must outlive the
/// result): the rest mesh, the scene (obstacles, forces, frame time) and one
/// object mask per scene frame, all of one shape. Throws
/// std::invalid_argument for invalid options, mask count or shapes that do
/// not match, or obstacle names of the wrong count (empty: "obstacle_0",
/// ...).
RecordingResidualFacts ComputeResidualFacts(const Mesh& rest_mesh, const Scene& scene,
                                            const std::vector<BitMask>& object_masks,
                                            std::vector<std::string> obstacle_names,
                                            std::string recording_name,
                                            const ResidualOptions& options = {});
/// The facts of a prepared recording (which must outlive the result); the
/// recording's name is its folder's name, the obstacles' names its tracks'.
RecordingResidualFacts ComputeResidualFacts(const PreparedRecording& prepared,
                                            const ResidualOptions& options = {});

/// The one-pass analyser. See the top of this file.
class ResidualAnalyser {
 public:
  /// From a prepared recording (which must outlive the analyser); the
  /// recording's name is its folder's name. Computes the facts itself.
  explicit ResidualAnalyser(const PreparedRecording& prepared, const ResidualOptions& options = {});
  /// From the parts (which must outlive the analyser); see
  /// ComputeResidualFacts (the facts are computed here, the same exceptions
  /// thrown).
  ResidualAnalyser(const Mesh& rest_mesh, const Scene& scene, const std::vector<BitMask>& object_masks,
                   std::vector<std::string> obstacle_names, std::string recording_name,
                   const ResidualOptions& options = {});
  /// From facts computed before (shared, read only; the parts they point to
  /// must outlive the analyser), with the options they were computed with.
  /// Gives exactly the analysis the constructors above give. Throws
  /// std::invalid_argument for null facts.
  explicit ResidualAnalyser(std::shared_ptr<const RecordingResidualFacts> facts);

  /// Frame `frame` (0, 1, 2, ... in order; throws std::invalid_argument
  /// otherwise) with the mesh at `positions` (#N, frame pixels) and its
  /// rasterisation `mesh_mask` (the object masks' shape).
  void AddFrame(int frame, std::span<const Vec2> positions, const BitMask& mesh_mask);

  /// The on_frame callback of Evaluator::Evaluate.
  void operator()(int frame, const Simulator& simulator, const BitMask& mesh_mask,
                  const FrameScore& /*score*/) {
    AddFrame(frame, simulator.positions(), mesh_mask);
  }

  /// The analysis of the frames added so far (any number, also none).
  ResidualAnalysis Finish() const;

  const std::vector<LoadPhase>& phases() const { return facts_->phases; }
  const RecordingResidualFacts& facts() const { return *facts_; }

 private:
  struct RestPoint {
    Vec2 rest;
    bool missed;
  };
  void MapResidualToRest(std::span<const Vec2> positions, const BitMask& mesh_mask, int frame);
  void AccumulateRestPixel(const Vec2& rest, bool missed, LoadPhase phase);
  // The XOR of the object with the mesh at `positions` moved by the rigid
  // motion that lays it best onto the object (ResidualFrame::rigid_xor_px),
  // and that motion's turn.
  std::pair<int64_t, double> RigidXor(std::span<const Vec2> positions, const BitMask& object,
                                      const Vec2& mesh_centroid, const Vec2& object_centroid);
  Vec2 NearestBoundaryRestPoint(std::span<const Vec2> positions, const Vec2& p) const;

  // Known before the pass (shared; mesh_, scene_, object_masks_ and
  // options_ refer into it).
  std::shared_ptr<const RecordingResidualFacts> facts_;
  const Mesh& mesh_;
  const Scene& scene_;
  const std::vector<BitMask>& object_masks_;
  const ResidualOptions& options_;

  // Accumulated.
  std::vector<ResidualFrame> frames_;
  RestHeatMap heat_map_;
  RegionSummary regions_;
  Vec2 dipole_sum_ = Vec2::Zero();
  double dipole_weight_ = 0.0;
  BitMask claimed_;
  BitMask previous_mesh_;
  // Scratch of the rigid alignment.
  Rasterizer rasterizer_;
  BitMask moved_mask_;
  std::vector<Vec2> moved_;
};

/// Evaluates `params` (the base model) on `prepared` and analyses the
/// residual in the same pass. `result`, when not null, receives the
/// evaluation.
ResidualAnalysis AnalyseResidual(const PreparedRecording& prepared,
                                 const SimulationOptions& simulation, const ModelParameters& params,
                                 const ResidualOptions& options = {},
                                 EvaluationResult* result = nullptr);

/// As above for the base model plus the effects of `model`, with named
/// parameter values (Evaluator::Evaluate(ParameterValues): ParameterError
/// for bad values).
ResidualAnalysis AnalyseResidual(const PreparedRecording& prepared,
                                 const SimulationOptions& simulation, const ModelDefinition& model,
                                 const ParameterValues& values, const ResidualOptions& options = {},
                                 EvaluationResult* result = nullptr);

}  // namespace calib
