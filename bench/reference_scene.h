#pragma once
// The reference scene of the benchmarks (and of evaluator tests that need a
// whole recording without a video): 330 frames of 640 x 480 pixels, a
// rectangular sponge of 400 x 256 px pushed by a finger disc against a pencil
// disc, meshed at 20 px edges, simulated with 10 substeps per frame. The
// object mask of every frame is the rest rectangle, which is all the
// benchmarks need: their cost does not depend on the mask's content.

#include "calib/evaluator/evaluation.h"

namespace calib::bench {

struct ReferenceSceneOptions {
  int num_frames = 330;
  int width = 640;
  int height = 480;
  double sponge_width_px = 400.0;
  double sponge_height_px = 256.0;
  double edge_length_px = 20.0;
};

/// A PreparedRecording with no video behind it.
PreparedRecording MakeReferenceScene(const ReferenceSceneOptions& options = {});

/// The reference scene with the default options, built once per process
/// and shared read-only.
const PreparedRecording& ReferenceScene();

/// The first 60 frames of the reference scene, built once per process and
/// shared read-only (tests that need a real scene but not all of it).
const PreparedRecording& ShortReferenceScene();

/// Parameters under which the reference scene runs stably to the end.
ModelParameters ReferenceParameters();

}  // namespace calib::bench
