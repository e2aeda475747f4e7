#pragma once
// Stage calibrations of the closed loop (loop.h): what a calibration of the
// base model, or of the model with effects added, searches, where it starts,
// and the request the runner gets for it.
//
// The search boxes are the model's own: every base and effect parameter
// carries its box (ParameterSpec::search_box, core/parameters.h), sized on
// what the training recordings show (SearchScales), and every effect
// parameter the value that switches its effect off (ParameterSpec::neutral).
// Nothing here names a parameter or an effect.

#include "calib/core/mesh.h"
#include "calib/core/parameters.h"
#include "calib/core/scene.h"
#include "calib/core/simulator.h"
#include "calib/evaluator/evaluation.h"
#include "calib/jobs/calibration_request.h"

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace calib {

/// The first-order drag of one recording's mesh (SearchScales::drag_force):
/// its nodes x `mass` x the fastest obstacle's speed between two frames
/// (px/s); 0 without a moving obstacle.
double ModelDragForce(const Mesh& mesh, const Scene& scene, double mass);

/// The centre of a scene's clamps (the mean of their rectangles' centres),
/// from which a hanging object's tip is the farthest point; nullopt
/// without clamps.
std::optional<Vec2> ClampCentre(const Scene& scene);

/// The median over the frames both have of the distance between the
/// model's and the video's tips (px); NaN when they share no finite one.
double MedianTipDistance(const std::vector<Vec2>& model, const std::vector<Vec2>& video);

/// What a recording of an object swinging freely says about the stiffness
/// of a model with inertia (SearchScales::swing_stiffness).
struct SwingScale {
  bool found = false;     ///< a free motion with a detectable period
  double period_s = 0.0;  ///< of the object's centroid (x or y, the larger swing)
  double decay_per_s = 0.0;
  double mode_rate = 0.0;  ///< SlowestModeRate of the mesh at its tracked rest shape
  double stiffness = 0.0;  ///< SwingStiffness at the calibration mass
};

/// The swing scale of `prepared`: found when its scene's motion has the
/// tracked rest shape (TrackObservedMotion), the centroid of its masks
/// oscillates (DetectOscillation) and the clamps hold its mesh;
/// `area_weighted`: for the area-weighted model (SlowestModeRate).
SwingScale MeasureSwingScale(const PreparedRecording& prepared, bool area_weighted = false);

/// For a clamped object, the direction from the clamps' centre to the
/// object's centroid averaged over every frame (frame 0's plus the scene's
/// observed mean offset, EstimateObservedMotion), degrees in the image (0:
/// +x, 90: +y): the way it hangs (SearchScales::hanging_angle_deg). NaN
/// without clamps or an observed motion.
double HangingAngleDeg(const PreparedRecording& prepared);

/// The scales of the training recordings `training` (>= 1), combined as
/// SearchScales says, for a model simulated with `simulation` (the implicit
/// step reaches 100x stiffer); swing_stiffness and its period from the
/// first training recording (MeasureSwingScale), and hanging_angle_deg
/// (HangingAngleDeg), used by the stages with inertia.
SearchScales TrainingScales(const std::vector<std::shared_ptr<const PreparedRecording>>& training,
                            const SimulationOptions& simulation);

/// What a calibration of the base model plus `effects` searches: each
/// parameter's own search box at `scales` (scales.reference: the previous
/// fit's values). Throws std::invalid_argument naming an unknown effect.
std::vector<ParameterSetting> StageParameterSettings(const std::vector<std::string>& effects,
                                                     const SearchScales& scales);

/// Where independent search `restart` (>= 1) of a calibration from scratch
/// starts, in unit-box coordinates: each coordinate drawn from [0.1, 0.9]
/// by a generator seeded with (`seed`, `restart`), so that a restart is
/// the same at every thread count and after a resume. Restart 0 starts
/// at the centre (0.5).
std::vector<double> RestartStart(int dimension, uint64_t seed, int restart);

/// The value of `setting` that leaves the model (nearly) as it was without
/// its effect (ParameterSpec::NeutralIn of the parameter's spec; the fixed
/// value of a fixed setting): the warm start of a new effect. Throws
/// std::invalid_argument for a name no model term declares.
double NeutralValue(const ParameterSetting& setting);

/// The runner's request for one stage calibration: `settings` searched by
/// `optimizer` from `x0` (unit box; null: the optimiser's own start) with
/// initial step `step`, `budget` evaluations, `seed`, one checkpoint at
/// the end, the default failure policy. The optimiser's own knowledge of
/// starts and budgets comes from search/ (StartSettings, WithBudget).
CalibrationRequest StageRequest(const std::string& name, const std::vector<ParameterSetting>& settings,
                                const std::string& optimizer, const std::vector<double>* x0,
                                double step, int64_t budget, uint64_t seed);

}  // namespace calib
