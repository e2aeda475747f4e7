#pragma once
// Scoring a candidate: simulate the whole recording with one parameter set
// and compare the mesh with the segmented object in every frame: per frame
// the XOR of pixel areas, with the mesh's sub-pixel coverage (scoring.h).
//
// PrepareRecording does everything that does not depend on the candidate
// once (segmentation, mesh, scene); an Evaluator holds one thread's
// preallocated simulation and rasterisation buffers and evaluates candidates
// without allocating per frame.

#include "calib/core/mesher.h"
#include "calib/core/simulator.h"
#include "calib/evaluator/bit_mask.h"
#include "calib/evaluator/rasterizer.h"
#include "calib/evaluator/recording.h"
#include "calib/evaluator/scoring.h"
#include "calib/evaluator/segmentation.h"

#include <filesystem>
#include <limits>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace calib {

struct PreparationOptions {
  SegmentationOptions segmentation;
  MesherOptions mesher;
  /// Tolerance of the outline simplification (cv::approxPolyDP), pixels.
  double outline_tolerance_px = 1.5;
  /// For an object that moves by itself (clamps, no obstacles): track the
  /// mesh through the first `motion_window_s` seconds of the video
  /// (shape_tracking.h) and start a model with inertia from every node's
  /// observed velocity, resting at the tracked shape at no motion
  /// (TrackObservedMotion). Off: the estimate from the centroid's motion.
  bool track_motion = true;
  /// 20 s: the whole of a recording of a swing that dies down. The rest
  /// shape needs cycles of different energies (NodeMotion::rest_shape_px):
  /// over the first second alone the real strips' rest shapes came out 2 px
  /// long and their areas 3-5 % large, stretched by the swing.
  double motion_window_s = 20.0;
  /// Only the first `max_frames` frames of the recording are simulated and
  /// scored (a calibration on a short horizon); 0: every frame. The
  /// observed motion is estimated before the cut, as without it.
  int max_frames = 0;
  /// Where segmentations are cached; empty: no disk cache.
  std::filesystem::path cache_dir = DefaultSegmentationCacheDir();

  bool IsValid(std::string* error) const;
};

/// What a recording gives every candidate, computed once.
struct PreparedRecording {
  Recording recording;
  std::vector<BitMask> object_masks;  ///< one per frame, over the roi
  std::vector<Vec2> outline;          ///< frame-0 object outline, pixels
  Mesh mesh;                          ///< rest shape = frame-0 object
  MeshQuality mesh_quality;
  Scene scene;
  /// The camera's motion blur, in frames (EstimateMotionBlur): the mesh is
  /// scored with each outline node moved outwards by this times its speed
  /// across the outline (px a frame). 0: none.
  double motion_blur_frames = 0.0;
  /// For an object that moves by itself, tracked (TrackObservedMotion): per
  /// tracked frame, the IoU (area coverage, as scored) of the mesh
  /// registered to that frame's outline: how well this mesh can cover the
  /// object at all, whatever moves it. A model's frame far below it misses
  /// the motion; a frame where it is low, the mesh or the segmentation
  /// cannot follow. Empty when not tracked.
  std::vector<double> registered_iou;
};

/// How far a moving object's mask reaches beyond the object, per pixel a
/// frame of its speed across its outline: motion blur. Over the shutter's
/// time a moving edge covers a band of pixels part of the time, and the
/// segmentation takes those covered long enough; the mask of an object
/// moving at v across its outline is wider by b v on each side, its area
/// larger by b times the area its outline sweeps in a frame. Estimated
/// from the masks alone: each frame's area against half the pixels that
/// differ between the frames before and after it (the area swept in one
/// frame), fitted by least squares over frames [1, n - 1); b is the slope.
/// 0 where the sweep explains less than kMotionBlurMinR2 of the areas'
/// variance (a still object, or blur the segmentation does not show) or
/// the slope is under kMotionBlurMinFrames (a widening of a quarter pixel
/// at 5 px a frame, under what the pixels show); at most
/// kMotionBlurMaxFrames (a shutter open the whole frame and every pixel
/// the object crossed taken). The real strips give 0.20-0.25 (r^2 0.5-0.6); the
/// project's synthetic hanging strips 0.02.
double EstimateMotionBlur(std::span<const BitMask> masks);
inline constexpr double kMotionBlurMinR2 = 0.25;
inline constexpr double kMotionBlurMinFrames = 0.05;
inline constexpr double kMotionBlurMaxFrames = 0.5;

/// The scene (obstacles, push, clamps, frame time) of a recording.
Scene BuildScene(const Recording& recording);

/// The object's observed motion (Scene::ObservedMotion) from its masks, one
/// per frame: known for a recording with clamps and no obstacles (an object
/// that hangs and swings freely), unknown otherwise. The equilibrium offset
/// is the mean over the frames of the object's centroid minus frame 0's; the
/// initial velocity is the slope at frame 0 of a least-squares quadratic
/// through the centroids of the first five frames (a line through two).
/// Frames without object pixels are skipped.
Scene::ObservedMotion EstimateObservedMotion(const Recording& recording,
                                             std::span<const BitMask> masks);

/// `prepared` cut to its first `frames` frames (1 <= frames; more than it
/// has: all of them): masks, scene (obstacles, forces) and the recording's
/// frame count and tracks, and the registered mesh's IoU. The mesh and the
/// observed motion stay.
PreparedRecording FirstFrames(const PreparedRecording& prepared, int frames);

/// Tracks prepared.mesh through the first `window_s` seconds of
/// prepared.object_masks (at least two frames, at most all) and sets the
/// per-node fields of prepared.scene.motion: the rest shape at no motion
/// (NodeMotion::rest_shape_px), each node's velocity the slope at frame 0
/// of a quadratic through its first five tracked positions.
/// PrepareRecording then measures the motion blur (EstimateMotionBlur) and
/// sets the start pose (SetStartPose).
void TrackObservedMotion(PreparedRecording& prepared, double window_s);

/// The outline's weight (ShapeTrackingOptions::outline_weight) in the
/// start pose's registration (SetStartPose): a sixteenth of the tracking's,
/// so that the triangles keep their rest shapes and the outline only poses
/// them.
inline constexpr double kStartPoseOutlineWeight = 0.25;

/// Sets prepared.scene.motion.node_start_px, where a model started from
/// the tracked shape starts in frame 0: the rest shape (node_rest_px)
/// registered onto frame 0's outline from the mesh's positions, each
/// triangle held to its rest shape, turned (RegisterMesh with
/// kStartPoseOutlineWeight). The mesh itself fits frame 0's outline, which
/// motion blur widens on a moving object: started there, the springs start
/// stretched (by 4-7 % of the area on the real strips) and ring at their own
/// high frequencies all through the swing. Where the masks show no motion
/// blur (motion_blur_frames 0) frame 0's outline is the object's and the
/// mesh fitted to it is the start: node_start_px is cleared, as where the
/// rest shape was not tracked.
void SetStartPose(PreparedRecording& prepared);

/// Segments (or reads the cached segmentation of) every frame, meshes the
/// frame-0 object and builds the scene (with the observed motion). Throws RecordingError for an
/// unreadable video, std::invalid_argument when no object can be meshed.
PreparedRecording PrepareRecording(const Recording& recording, const PreparationOptions& options);

/// PrepareRecording after its segmentation: meshes frame 0 of `masks` (one
/// per frame of `recording`, over its roi) and builds the scene and the
/// observed motion from them. options.segmentation and options.cache_dir
/// are not used. Throws std::invalid_argument naming the recording where
/// the masks do not match it (count, size, origin) or frame 0 is empty.
PreparedRecording PrepareSegmented(const Recording& recording, std::vector<BitMask> masks,
                                   const PreparationOptions& options);

/// kStopped: stopped early by a ScoreCutoff (EvaluateWithCutoff), every
/// frame simulated up to then scored.
enum class EvaluationStatus { kOk, kFailed, kStopped };
std::string ToString(EvaluationStatus status);  ///< "ok", "failed", "stopped"

/// Stopping a hopeless candidate early (pruning, jobs/pruning.h): the
/// simulation stops after the first frame at which
/// `score_before + xor_sum` (xor_sum summed over this recording's frames so
/// far, in frame order) exceeds `stop_above`. `score_before` is what the
/// recordings scored before this one add (0 for the first), so that the
/// sum compared is the candidate's score so far over all its recordings.
/// The default never stops.
struct ScoreCutoff {
  double score_before = 0.0;
  double stop_above = std::numeric_limits<double>::infinity();
};

struct EvaluationResult {
  EvaluationStatus status = EvaluationStatus::kFailed;
  std::string failure_reason;  ///< empty unless kFailed
  int failure_frame = -1;      ///< first frame that could not be simulated
  /// Per-frame comparison for every frame simulated (all of them when kOk;
  /// frames [0, failure_frame) when kFailed; up to and including the frame
  /// the cutoff was passed at when kStopped).
  std::vector<FrameScore> frames;
  int num_frames = 0;     ///< frames in the recording
  /// The score: the frames' XOR areas (FrameScore::xor_px, px^2) summed over
  /// `frames` in frame order.
  double xor_sum = 0.0;
  /// Over all num_frames frames, a frame not simulated (after a failure)
  /// counting 0: a candidate that failed at frame 1 of 330 must not look
  /// good (when kOk, the mean over `frames`).
  double mean_iou = 0.0;

  bool ok() const { return status == EvaluationStatus::kOk; }
};

class Evaluator {
 public:
  /// `prepared` must outlive the evaluator; `options` must be valid.
  Evaluator(const PreparedRecording& prepared, const SimulationOptions& options);

  /// The base model plus the effects of `model` (Simulator's constructor:
  /// std::invalid_argument naming an unknown or repeated effect).
  Evaluator(const PreparedRecording& prepared, const SimulationOptions& options,
            const ModelDefinition& model);

  /// Simulates the whole recording with `params` and scores every frame.
  /// Never throws for a candidate that blows up: that is a kFailed result.
  /// The base model only: with effects, std::logic_error (use ParameterValues).
  EvaluationResult Evaluate(const ModelParameters& params) {
    return Evaluate(params, IgnoreFrames{});
  }

  /// As above, calling on_frame(frame, simulator, mesh_mask, score) after
  /// each frame is scored (for overlays and reports). `score` is the frame's
  /// score, from the mesh's sub-pixel coverage; `mesh_mask` is a bit mask
  /// (same shape as the object masks) of the pixels the mesh covers at
  /// least half: the wholly covered ones and those of the outline with
  /// coverage >= 0.5 (AddHalfCovered). Comparing it with the object mask
  /// (CompareMasks) gives pixel counts close to, not equal to, `score`.
  template <class OnFrame>
  EvaluationResult Evaluate(const ModelParameters& params, OnFrame&& on_frame);

  /// As Evaluate(ModelParameters) from named values: the base model's and
  /// every effect's parameters (simulator().parameter_specs()). Bad values
  /// (missing, unknown, not finite, out of bounds) throw ParameterError
  /// naming the parameter; a candidate that blows up is a kFailed result.
  /// Without effects the result is that of Evaluate(ModelParameters::FromValues(values)).
  EvaluationResult Evaluate(const ParameterValues& values) {
    return Evaluate(values, IgnoreFrames{});
  }

  template <class OnFrame>
  EvaluationResult Evaluate(const ParameterValues& values, OnFrame&& on_frame);

  /// As Evaluate(values), but stopped by `cutoff` (kStopped) once the score
  /// so far exceeds it; frames and xor_sum up to then are those of the
  /// uncut run bit for bit.
  EvaluationResult EvaluateWithCutoff(const ParameterValues& values, const ScoreCutoff& cutoff) {
    simulator_.Reset(values);
    return Run(IgnoreFrames{}, cutoff);
  }

  const Simulator& simulator() const { return simulator_; }

 private:
  // The callback of the overloads without one: Run then skips the bit mask.
  struct IgnoreFrames {
    void operator()(int, const Simulator&, const BitMask&, const FrameScore&) const {}
  };

  // Rasterises the current positions' coverage into mesh_mask_ (the
  // wholly covered pixels) and boundary_, and compares it with the frame's
  // object mask.
  FrameScore ScoreFrame(int frame);
  // The positions as the camera sees them (motion_blur_frames): outline
  // nodes moved outwards by the blur times their speed across the
  // outline, from the last frame's positions (frame 0: the initial
  // velocities).
  std::span<const Vec2> Blurred(int frame);
  /// Simulates and scores every frame from the state Reset left, up to
  /// the cutoff.
  template <class OnFrame>
  EvaluationResult Run(OnFrame&& on_frame, const ScoreCutoff& cutoff = {});

  const PreparedRecording& prepared_;
  Simulator simulator_;
  Rasterizer rasterizer_;
  BitMask mesh_mask_;
  std::vector<PixelCoverage> boundary_;  // the partly covered pixels
  // Each frame's object pixel count, counted at its first score (-1 before).
  std::vector<int64_t> object_px_;
  std::vector<Vec2> last_positions_;     // the last frame's (motion blur)
  std::vector<Vec2> seen_positions_;     // Blurred's
  std::vector<Vec2> outline_normal_;     // per node, the outline's outward sum
};

template <class OnFrame>
EvaluationResult Evaluator::Evaluate(const ModelParameters& params, OnFrame&& on_frame) {
  simulator_.Reset(params);
  return Run(std::forward<OnFrame>(on_frame));
}

template <class OnFrame>
EvaluationResult Evaluator::Evaluate(const ParameterValues& values, OnFrame&& on_frame) {
  simulator_.Reset(values);
  return Run(std::forward<OnFrame>(on_frame));
}

template <class OnFrame>
EvaluationResult Evaluator::Run(OnFrame&& on_frame, const ScoreCutoff& cutoff) {
  EvaluationResult result;
  const int num_frames = prepared_.scene.num_frames;
  result.num_frames = num_frames;
  result.frames.reserve(num_frames);
  double iou_sum = 0.0;
  bool stopped = false;
  for (int frame = 0; frame < num_frames && !stopped; ++frame) {
    if (frame > 0 && !simulator_.Advance()) break;
    const FrameScore score = ScoreFrame(frame);
    result.frames.push_back(score);
    result.xor_sum += score.xor_px;
    iou_sum += score.iou;
    if constexpr (!std::is_same_v<std::remove_cvref_t<OnFrame>, IgnoreFrames>) {
      AddHalfCovered(boundary_, mesh_mask_);
      on_frame(frame, simulator_, mesh_mask_, score);
    }
    // The score so far, summed as the candidate's score is (RecordingObjective).
    stopped = cutoff.score_before + result.xor_sum > cutoff.stop_above;
  }
  if (stopped) {
    result.status = EvaluationStatus::kStopped;
  } else if (simulator_.status() == SimulationStatus::kFailed) {
    result.status = EvaluationStatus::kFailed;
    result.failure_reason = simulator_.failure_reason();
    result.failure_frame = simulator_.failure_frame();
  } else {
    result.status = EvaluationStatus::kOk;
  }
  if (num_frames > 0) result.mean_iou = iou_sum / num_frames;
  return result;
}

}  // namespace calib
