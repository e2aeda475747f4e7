// Load phases of a recording from its force track and the pusher's motion.

#include "calib/discovery/load_phases.h"

#include "calib/core/enum_names.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace calib {
namespace {

constexpr auto kPhaseNames = std::to_array<EnumName<LoadPhase>>({
    {LoadPhase::kFree, "free"},
    {LoadPhase::kBeforeLoad, "before_load"},
    {LoadPhase::kLoading, "loading"},
    {LoadPhase::kHold, "hold"},
    {LoadPhase::kUnloading, "unloading"},
    {LoadPhase::kReleased, "released"},
});
static_assert(kPhaseNames.size() == kNumLoadPhases);

// Central difference of v over +-h samples (one-sided at the ends), per
// sample.
double Derivative(const std::vector<double>& v, int i, int h) {
  const int n = static_cast<int>(v.size());
  const int a = std::max(0, i - h), b = std::min(n - 1, i + h);
  return b > a ? (v[b] - v[a]) / (b - a) : 0.0;
}

}  // namespace

std::string ToString(LoadPhase phase) { return EnumToString(kPhaseNames, phase); }

LoadPhase LoadPhaseFromString(const std::string& text) {
  return EnumFromString(kPhaseNames, "load phase", text);
}

bool IsLoaded(LoadPhase phase) {
  return phase == LoadPhase::kLoading || phase == LoadPhase::kHold ||
         phase == LoadPhase::kUnloading;
}

bool PhaseOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (!(load_on_fraction > 0.0 && load_on_fraction < 1.0)) {
    return fail(fmt::format(
        "PhaseOptions::load_on_fraction = {}. Violated: 0 < load_on_fraction < 1.",
        load_on_fraction));
  }
  if (!(load_off_fraction > 0.0 && load_off_fraction <= load_on_fraction)) {
    return fail(fmt::format(
        "PhaseOptions::load_off_fraction = {}. Violated: 0 < load_off_fraction <= "
        "load_on_fraction ({}).",
        load_off_fraction, load_on_fraction));
  }
  if (!(moving_fraction > 0.0 && moving_fraction < 1.0)) {
    return fail(fmt::format(
        "PhaseOptions::moving_fraction = {}. Violated: 0 < moving_fraction < 1.",
        moving_fraction));
  }
  if (!(force_rate_fraction_per_s > 0.0)) {
    return fail(fmt::format(
        "PhaseOptions::force_rate_fraction_per_s = {}. Violated: force_rate_fraction_per_s > 0.",
        force_rate_fraction_per_s));
  }
  return true;
}

std::vector<LoadPhase> DetectLoadPhases(const LoadTrack& track, const PhaseOptions& options) {
  const int n = static_cast<int>(
      std::max({static_cast<size_t>(std::max(0, track.num_frames)), track.force_n.size(),
                track.contact.size(), track.pusher_centre.size(), track.object_centre.size()}));
  std::vector<LoadPhase> phases(n, LoadPhase::kFree);
  if (n == 0) return phases;

  // Loaded frames: force above the threshold with hysteresis, or contact.
  std::vector<uint8_t> loaded(n, 0);
  double max_force = 0.0;
  for (double f : track.force_n) max_force = std::max(max_force, f);
  const bool by_force = !track.force_n.empty() && max_force > 1e-9;
  if (by_force) {
    bool on = false;
    for (int i = 0; i < n; ++i) {
      const double f = i < static_cast<int>(track.force_n.size()) ? track.force_n[i] : 0.0;
      if (!on && f > options.load_on_fraction * max_force) on = true;
      if (on && f < options.load_off_fraction * max_force) on = false;
      loaded[i] = on;
    }
  } else if (!track.contact.empty()) {
    for (int i = 0; i < n && i < static_cast<int>(track.contact.size()); ++i) {
      loaded[i] = track.contact[i];
    }
  }
  const auto first = std::find(loaded.begin(), loaded.end(), 1);
  if (first == loaded.end()) return phases;  // all free
  const int first_loaded = static_cast<int>(first - loaded.begin());

  // Pusher speed (px/frame) and its approach rate towards the object.
  const bool has_pusher = static_cast<int>(track.pusher_centre.size()) == n;
  std::vector<double> speed(n, 0.0), approach(n, 0.0);
  double max_speed = 0.0;
  if (has_pusher) {
    for (int i = 0; i < n; ++i) {
      const int a = std::max(0, i - 1), b = std::min(n - 1, i + 1);
      if (b == a) continue;
      const Vec2 v = (track.pusher_centre[b] - track.pusher_centre[a]) / (b - a);
      speed[i] = v.norm();
      if (static_cast<int>(track.object_centre.size()) == n &&
          track.object_centre[i].allFinite()) {
        const Vec2 to_object = track.object_centre[i] - track.pusher_centre[i];
        const double d = to_object.norm();
        approach[i] = d > 0.0 ? v.dot(to_object) / d : 0.0;
      }
      if (loaded[i]) max_speed = std::max(max_speed, speed[i]);
    }
  }
  const double moving_speed = std::max(0.01, options.moving_fraction * max_speed);
  const bool pusher_moves = has_pusher && max_speed > 0.01;
  // Force trend per frame as a share of the largest force.
  const double rate = options.force_rate_fraction_per_s / std::max(track.fps, 1e-9);

  for (int i = 0; i < n; ++i) {
    if (i < first_loaded) {
      phases[i] = LoadPhase::kBeforeLoad;
    } else if (!loaded[i]) {
      phases[i] = LoadPhase::kReleased;
    } else if (pusher_moves) {
      if (speed[i] <= moving_speed) {
        phases[i] = LoadPhase::kHold;
      } else {
        phases[i] = approach[i] >= 0.0 ? LoadPhase::kLoading : LoadPhase::kUnloading;
      }
    } else if (by_force) {
      const double d = Derivative(track.force_n, i, 2) / max_force;
      phases[i] = d > rate ? LoadPhase::kLoading
                  : d < -rate ? LoadPhase::kUnloading
                              : LoadPhase::kHold;
    } else {
      phases[i] = LoadPhase::kHold;
    }
  }
  return phases;
}

}  // namespace calib
