#pragma once
// Another recording of the same object: its model carried over.
//
// A clamped object's recording is meshed from its own frame 0, and its rest
// shape is estimated from its own video (shape_tracking.h). Two
// recordings of one strip thus get two lattices and two rest shapes, and a
// lattice of springs is not the continuum: at one parameter set the two
// meshes swing at periods 1-4 % apart, which over a recording of many
// swings puts the prediction out of phase (docs/loop.md, "Measured case").
// The object's model is its mesh (lattice and element areas, which weight
// the masses and stiffnesses) and its rest shape as much as its material
// parameters, so a prediction of another recording of the same object
// carries all of them: CarryObjectModel registers the calibrated
// recording's mesh, in its rest shape, onto the new recording's frame-0
// outline (as-rigid-as-possible, the rest shape as the reference) and keeps
// only the start (frame-0 positions and velocities) from the new video.
//
// Whether it is the same object: the new recording must hold the object in
// the same clamps, its own rest-shape estimate must have the carried one's
// area (within kMaxCarriedRestAreaChange), and the carried mesh must reach
// its frame-0 outline within kMaxCarriedOutlineDistancePx on average with no
// triangle turned over. A strip of another outline keeps its own mesh.

#include "calib/evaluator/evaluation.h"

#include <string>

namespace calib {

struct ObjectTransfer {
  bool carried = false;
  /// Mean distance of the carried mesh's boundary nodes to the new
  /// recording's frame-0 outline after registration, px (-1: not
  /// registered).
  double outline_distance_px = -1.0;
  /// The new recording's own rest shape's area against the carried one's,
  /// less 1 (0 where not compared).
  double rest_area_change = 0.0;
  /// Why the model was carried, or why not: names both recordings.
  std::string reason;
};

/// The largest mean distance of the registered mesh's outline nodes to the
/// new frame-0 outline, px: a pixel, the resolution of the outline itself
/// (the tracker follows one object to 0.1-0.35 px in every frame).
inline constexpr double kMaxCarriedOutlineDistancePx = 1.0;
/// The largest relative difference between the areas of the two
/// recordings' own rest-shape estimates: 5 %, twice the spread of the
/// rest-area estimate between recordings of one object (motion blur widens a
/// swinging object by a few per cent).
inline constexpr double kMaxCarriedRestAreaChange = 0.05;

/// Carries the object model of `from` (a prepared recording whose motion
/// was tracked: Scene::ObservedMotion's node fields) to `to`, another
/// prepared recording with tracked motion: on success `to` gets `from`'s
/// lattice registered onto its frame 0 (its mesh, rest quantities at that
/// pose as every mesh's are), `from`'s rest shape and element areas (in
/// its scene's observed motion), and node velocities tracked from its own
/// first `motion_window_s` seconds. Otherwise `to` is left as it was.
/// Never throws for recordings that do not match; the result says why.
ObjectTransfer CarryObjectModel(const PreparedRecording& from, PreparedRecording& to,
                                double motion_window_s);

}  // namespace calib
