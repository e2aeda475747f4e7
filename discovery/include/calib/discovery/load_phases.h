#pragma once
// Load phases of a recording: what the pusher does to the object in each
// frame (from the force track and the pusher's motion). Part of the
// residual analysis (residual.h); model-independent.

#include "calib/core/types.h"

#include <cstdint>
#include <string>
#include <vector>

namespace calib {

/// What the pusher does to the object in a frame.
///   kFree:       the recording has no push at all (no force sensor and no
///                moving obstacle touching the object): free motion.
///   kBeforeLoad: before the first loaded frame.
///   kLoading:    loaded and the pusher moves towards the object (or, with a
///                static pusher, the force rises).
///   kHold:       loaded, pusher still and force steady.
///   kUnloading:  loaded and the pusher moves away (or the force falls).
///   kReleased:   not loaded any more after having been loaded.
enum class LoadPhase { kFree, kBeforeLoad, kLoading, kHold, kUnloading, kReleased };
inline constexpr int kNumLoadPhases = 6;

std::string ToString(LoadPhase phase);  ///< "free", "before_load", "loading", "hold", ...
/// Inverse of ToString; throws std::invalid_argument naming the text.
LoadPhase LoadPhaseFromString(const std::string& text);
/// kLoading, kHold or kUnloading.
bool IsLoaded(LoadPhase phase);

/// The per-frame signals phase detection reads. Every vector is empty or
/// holds one entry per frame.
struct LoadTrack {
  int num_frames = 0;  ///< at least the longest vector's size
  double fps = 30.0;
  /// |force| on the object by the force obstacle, newtons; empty: no sensor.
  std::vector<double> force_n;
  /// 1 where the pusher touches the object; used when force_n is empty.
  std::vector<uint8_t> contact;
  /// Centre of the pusher (the force obstacle, else the obstacle that moves
  /// most), pixels; empty: no pusher.
  std::vector<Vec2> pusher_centre;
  /// A point of the object (its centroid) per frame: "towards the object".
  std::vector<Vec2> object_centre;
};

/// Phase detection options (part of ResidualOptions).
struct PhaseOptions {
  /// Loaded when |force| exceeds this share of the largest |force| ...
  double load_on_fraction = 0.10;
  /// ... and stays loaded until it falls below this share (hysteresis).
  double load_off_fraction = 0.05;
  /// The pusher moves when its speed exceeds this share of its largest
  /// speed while loaded (and 0.01 px/frame).
  double moving_fraction = 0.10;
  /// With a pusher that never moves: the force rises (falls) when it changes
  /// by more than this share of its largest value per second.
  double force_rate_fraction_per_s = 0.05;

  bool IsValid(std::string* error) const;
};

/// One phase per frame (see LoadPhase). A recording whose force never
/// exceeds 1e-9 N and with no contact is all kFree.
std::vector<LoadPhase> DetectLoadPhases(const LoadTrack& track, const PhaseOptions& options);

}  // namespace calib
