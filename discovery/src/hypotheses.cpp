// Tracing residual signatures to effects (hypotheses.h).
//
// Each effect's confidence is
//   significance x applicability x f(evidence supports),
// where significance says whether there is a residual worth explaining at
// all (its mean thickness over the rest perimeter, in pixels: segmentation
// noise and rasterisation alone leave ~0.5-1 px), applicability whether the
// recording could show the signature (a release, a hold, a push), and each
// support is a ramp of one dimensionless measurement. Supports combine as a
// weighted noisy-or, 1 - prod(1 - w_i s_i), where any one signature suffices,
// or as a product where all are needed.

#include "calib/discovery/hypotheses.h"

#include "calib/discovery/confidence_rates.h"

#include "calib/evaluator/json_number.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <stdexcept>

namespace calib {
namespace {

using nlohmann::json;

// 0 below lo, 1 above hi, linear between; 0 for NaN.
double Ramp(double x, double lo, double hi) {
  if (!std::isfinite(x)) return 0.0;
  return std::clamp((x - lo) / (hi - lo), 0.0, 1.0);
}

double NoisyOr(std::initializer_list<std::pair<double, double>> weighted) {
  double keep = 1.0;
  for (const auto& [w, s] : weighted) keep *= 1.0 - w * s;
  return 1.0 - keep;
}

double Deg(double rad) { return rad * 180.0 / std::numbers::pi; }

struct Builder {
  Hypothesis h;
  explicit Builder(std::string effect, const std::string& recording) {
    h.effect = std::move(effect);
    h.recordings = {recording};
  }
  double Add(std::string signature, double value, double support, std::string statement) {
    h.evidence.push_back({std::move(signature), value, support, std::move(statement)});
    return support;
  }
};

// Over the loaded phases: share of the error that a centroid alignment
// removes (placement error), NaN without loaded frames.
double LoadedPlacementShare(const ResidualAnalysis& a) {
  double x = 0, al = 0;
  for (const PhaseSummary& p : a.phases) {
    if (!IsLoaded(p.phase)) continue;
    x += p.mean_xor_px * p.num_frames;
    al += p.mean_aligned_xor_px * p.num_frames;
  }
  return x > 0.0 ? std::clamp(1.0 - al / x, 0.0, 1.0) : NAN;
}

// What the release shows, from the plasticity hypothesis's evidence: the
// support that a residual persists after the load is gone, that it lies at
// the contact, that it does not fade, and how far the release is watched
// long enough to tell.
struct Persistence {
  double persistent = 0.0;
  double at_contact = 0.0;
  double no_recovery = 0.0;
  double release_weight = 0.0;
};

// What every signature sees besides the analysis: the residual's
// significance, and the release evidence that plasticity's signature
// measures and the others weigh against.
struct TraceContext {
  double significance = 0.0;
  Persistence release;
};

Hypothesis TraceInertia(const ResidualAnalysis& a, const TraceContext& context) {
  const double significance = context.significance;
  Builder b("inertia", a.recording);
  const OscillationSummary& o = a.oscillation;
  const MotionSummary& m = a.motion;
  double s_offset = 0.0;
  if (o.offset.found) {
    s_offset = Ramp(o.offset.strength, 0.2, 0.6) * Ramp(o.offset.cycles, 2.5, 4.0) *
               Ramp(o.offset.amplitude, 0.5, 3.0);
  }
  b.Add("offset_oscillation", o.offset.found ? o.offset.period_s : NAN, s_offset,
        o.offset.found
            ? fmt::format("the centroid offset (mesh - object) oscillates with period {:.3f} s "
                          "({:.1f} frames), amplitude {:.1f} px, autocorrelation {:.2f} over "
                          "{:.1f} cycles, {} {:.2f}/s",
                          o.offset.period_s, o.offset.period_frames, o.offset.amplitude,
                          o.offset.strength, o.offset.cycles,
                          o.offset.decay_per_s >= 0 ? "decaying at" : "growing at",
                          std::abs(o.offset.decay_per_s))
            : "no oscillation of the centroid offset");
  double s_object = 0.0;
  if (o.object_motion.found) {
    const double mesh_share =
        o.mesh_motion.found && o.object_motion.amplitude > 0.0
            ? std::min(1.0, o.mesh_motion.amplitude / o.object_motion.amplitude)
            : 0.0;
    s_object = Ramp(o.object_motion.strength, 0.2, 0.6) * Ramp(o.object_motion.cycles, 2.5, 4.0) *
               Ramp(o.object_motion.amplitude, 0.5, 3.0) * (1.0 - Ramp(mesh_share, 0.5, 0.9));
    b.Add("object_oscillates", o.object_motion.period_s, s_object,
          fmt::format("the object swings with period {:.3f} s and amplitude {:.1f} px; the model's "
                      "mesh {}",
                      o.object_motion.period_s, o.object_motion.amplitude,
                      o.mesh_motion.found
                          ? fmt::format("swings with {:.0f}% of that amplitude", 100 * mesh_share)
                          : std::string("does not swing")));
  }
  double s_free = 0.0;
  if (!a.push.has_push) {
    const double ratio = m.object_motion_rms_px > 0.0 ? m.mesh_motion_rms_px / m.object_motion_rms_px : 1.0;
    s_free = Ramp(m.object_motion_rms_px, 1.0, 5.0) * (1.0 - Ramp(ratio, 0.3, 0.8));
    b.Add("moves_without_load", m.object_motion_rms_px, s_free,
          fmt::format("with no load the object's centroid moves {:.1f} px RMS (path {:.0f} px), "
                      "the mesh's {:.1f} px RMS (path {:.0f} px)",
                      m.object_motion_rms_px, m.object_path_px, m.mesh_motion_rms_px,
                      m.mesh_path_px));
  }
  // A consistent offset across the push direction (or any, without a push).
  double s_sag = 0.0;
  if (m.mean_offset_px.allFinite()) {
    const double mag = m.mean_offset_px.norm();
    const double across =
        a.push.has_push && mag > 0.0
            ? 1.0 - std::abs(m.mean_offset_px.dot(a.push.push_axis)) / mag
            : 1.0;
    s_sag = Ramp(m.offset_consistency, 0.5, 0.9) * Ramp(mag, 1.0, 4.0) * across;
    const double dir = Deg(std::atan2(-m.mean_offset_px.y(), -m.mean_offset_px.x()));
    b.Add("mesh_lags_one_way", mag, s_sag,
          fmt::format("the object sits {:.1f} px from the mesh on average towards {:.0f} deg "
                      "(image axes, 90 = down), consistency {:.2f} (mesh offset ({:.1f}, {:.1f}) px)",
                      mag, dir, m.offset_consistency, m.mean_offset_px.x(), m.mean_offset_px.y()));
  }
  // A lag alone also says "the first-order model is too slow", which its
  // own parameters may fix; it counts for inertia only where the object
  // moves by itself (no push) or swings.
  const double gain = m.lag_correlation - m.lag_correlation0;
  const double free_or_swinging = !a.push.has_push || o.object_motion.found ? 1.0 : 0.0;
  const double s_lag = m.lag_frames > 0 ? Ramp(gain, 0.02, 0.2) * Ramp(m.lag_frames, 1.0, 3.0) *
                                              free_or_swinging
                                        : 0.0;
  b.Add("mesh_lags_in_time", m.lag_s, s_lag,
        fmt::format("the mesh's motion best matches the object's {} frames ({:.3f} s) {} "
                    "(correlation {:.2f} against {:.2f} at no lag)",
                    std::abs(m.lag_frames), std::abs(m.lag_s), m.lag_frames >= 0 ? "later" : "earlier",
                    m.lag_correlation, m.lag_correlation0));
  b.h.applicability = 1.0;
  b.h.confidence = significance * NoisyOr({{0.9, s_offset}, {0.8, s_object}, {0.7, s_free},
                                           {0.5, s_sag}, {0.3, s_lag}});
  b.h.summary =
      "the object moves by itself (swings, sags, keeps moving) where the first-order model only "
      "follows its load: inertia with gravity";
  return b.h;
}

Hypothesis TraceTableFriction(const ResidualAnalysis& a, const TraceContext& context) {
  const double significance = context.significance;
  const Persistence& persistence = context.release;
  Builder b("table_friction", a.recording);
  const PushSummary& p = a.push;
  b.h.applicability = p.has_push ? 1.0 : 0.0;
  if (!p.has_push) {
    b.Add("push", 0.0, 0.0, "no push in this recording: friction with a table cannot show");
    b.h.summary = "no push";
    return b.h;
  }
  const double placement = LoadedPlacementShare(a);
  const double s_place = b.Add(
      "placement_share", placement, Ramp(placement, 0.2, 0.6),
      fmt::format("{:.0f}% of the loaded residual goes away when the mesh is shifted onto the "
                  "object's centroid (the error is placement more than shape)",
                  100 * placement));
  const double s_grow = b.Add(
      "offset_grows_with_push", p.offset_push_correlation,
      Ramp(p.offset_push_correlation, 0.3, 0.8) * Ramp(a.motion.max_abs_offset_px, 1.0, 4.0),
      fmt::format("the centroid offset grows with the push distance (correlation {:.2f} over "
                  "{:.0f} px pushed, {:.3f} px of offset per px, up to {:.1f} px)",
                  p.offset_push_correlation, p.push_distance_px, p.offset_per_push,
                  a.motion.max_abs_offset_px));
  const double s_rot = b.Add(
      "rotation_difference", Deg(a.motion.max_abs_angle_diff_rad),
      Ramp(Deg(a.motion.max_abs_angle_diff_rad), 1.0, 5.0) * Ramp(a.motion.mean_anisotropy, 0.1, 0.3),
      fmt::format("object and mesh orientations differ by up to {:.1f} deg (mean {:.1f} deg; "
                  "object anisotropy {:.2f})",
                  Deg(a.motion.max_abs_angle_diff_rad), Deg(a.motion.mean_angle_diff_rad),
                  a.motion.mean_anisotropy));
  const double s_ahead = b.Add(
      "mesh_ahead_along_push", p.mean_offset_along_push_px,
      Ramp(p.mean_offset_along_push_px, 0.5, 3.0),
      fmt::format("while loaded the mesh is {:.1f} px {} the object along the push",
                  std::abs(p.mean_offset_along_push_px),
                  p.mean_offset_along_push_px >= 0 ? "ahead of" : "behind"));
  // After the release the table holds what the springs would undo: the
  // residual persists without fading (a relaxing one is viscoelastic),
  // spread over the body (a permanent set sits at the contact: plasticity).
  const double held = persistence.persistent * persistence.no_recovery *
                      (1.0 - persistence.at_contact);
  const double s_hold = b.Add(
      "held_after_release", held, held * persistence.release_weight,
      fmt::format("after release the residual persists (support {:.2f}), does not fade (support "
                  "{:.2f}) and lies {} the contact (support {:.2f} that it is at the contact)",
                  persistence.persistent, persistence.no_recovery,
                  persistence.at_contact > 0.5 ? "at" : "away from", persistence.at_contact));
  b.h.confidence = significance * NoisyOr({{0.9, s_place * s_grow},
                                           {0.6, s_rot * s_place},
                                           {0.6, s_ahead * s_grow},
                                           {0.7, s_hold}});
  b.h.summary =
      "the object's placement drifts from the mesh as the push goes on, or its deformation stays "
      "after the release away from the contact: friction with the table";
  return b.h;
}

Hypothesis TracePushRelaxation(const ResidualAnalysis& a, const TraceContext& context) {
  const double significance = context.significance;
  Builder b("push_relaxation", a.recording);
  const PushSummary& p = a.push;
  b.h.applicability = p.has_push && p.stopped_frames >= 3 ? 1.0 : 0.0;
  if (b.h.applicability == 0.0) {
    b.Add("pusher_stops", 0.0, 0.0, "the pusher never stands still while loaded");
    b.h.summary = "no still pusher";
    return b.h;
  }
  const double excess = p.mesh_travel_after_stop_px - p.object_travel_after_stop_px;
  const double s_move = b.Add(
      "mesh_moves_after_stop", excess, Ramp(excess, 0.5, 3.0),
      fmt::format("over the {} frames the pusher stands still the mesh moves on {:+.1f} px along "
                  "the push while the object moves {:+.1f} px",
                  p.stopped_frames, p.mesh_travel_after_stop_px, p.object_travel_after_stop_px));
  const PhaseSummary* hold = a.Phase(LoadPhase::kHold);
  double growth = NAN, change_ratio = NAN;
  if (hold != nullptr) {
    growth = hold->offset_slope_px_per_s * hold->num_frames / a.fps;
    change_ratio = hold->mean_mesh_change_px / std::max(1.0, hold->mean_object_change_px);
  }
  const double s_grow = b.Add(
      "offset_grows_in_hold", growth, Ramp(growth, 0.5, 3.0),
      fmt::format("during the hold the centroid offset changes by {:+.1f} px", growth));
  const double s_change = b.Add(
      "mesh_changes_in_hold", change_ratio, Ramp(change_ratio, 1.5, 4.0),
      fmt::format("during the hold the mesh mask changes {:.1f} times as much per frame as the "
                  "object's",
                  change_ratio));
  b.h.confidence = significance * NoisyOr({{0.9, s_move}, {0.6, s_grow * s_change}, {0.3, s_change}});
  b.h.summary =
      "the model keeps translating after the pusher stops while the object stands: the "
      "translation term's push outlives the finger";
  return b.h;
}

// The plasticity signature; `persistence` receives the release evidence
// (TraceContext::release).
Hypothesis TracePlasticity(const ResidualAnalysis& a, double significance, Persistence* persistence) {
  Builder b("plasticity", a.recording);
  const PersistenceSummary& ps = a.persistence;
  *persistence = {};
  // A few frames after release cannot tell a permanent set from a slow
  // recovery.
  b.h.applicability = ps.released ? Ramp(ps.released_frames, 5.0, 15.0) : 0.0;
  if (b.h.applicability == 0.0) {
    b.Add("release", ps.released_frames, 0.0,
          "no release (or too short) to watch for a permanent set");
    b.h.summary = "no release";
    return b.h;
  }
  // How much of the loaded error stays after the release, counted on the
  // shape's own error (the mesh laid rigidly onto the object) where the
  // analysis has it: a pose left wrong after the release (the body turned
  // or slid otherwise than the object during the push) is no permanent set
  // and no deformation held. Whether what stays is more than noise: the
  // residual's excess thickness over the pre-load floor, as measured.
  const bool shape = std::isfinite(ps.shape_persistent_ratio);
  const double ratio = shape ? ps.shape_persistent_ratio : ps.persistent_ratio;
  const double floor = std::isfinite(ps.before_xor_px) ? ps.before_xor_px : 0.0;
  const double excess_thickness =
      a.rest_perimeter_px > 0 ? (ps.released_late_xor_px - floor) / a.rest_perimeter_px : 0.0;
  const double s_persist = b.Add(
      "persistent_ratio", ratio, Ramp(ratio, 0.15, 0.5) * Ramp(excess_thickness, 0.3, 1.0),
      shape ? fmt::format("after release the shape error (the mesh laid rigidly onto the object) "
                          "stays at {:.0f} px/frame (late third) = {:.0f}% of the loaded {:.0f} "
                          "px/frame above the pre-load floor {:.0f} px/frame; the whole residual "
                          "at {:.0f} px/frame, {:.2f} px thicker than that floor",
                          ps.released_late_rigid_xor_px, 100 * ratio, ps.loaded_rigid_xor_px,
                          std::isfinite(ps.before_rigid_xor_px) ? ps.before_rigid_xor_px : 0.0,
                          ps.released_late_xor_px, excess_thickness)
            : fmt::format("after release the residual stays at {:.0f} px/frame (late third) = "
                          "{:.0f}% of the loaded residual {:.0f} px/frame above the pre-load "
                          "floor {:.0f} px/frame",
                          ps.released_late_xor_px, 100 * ratio, ps.loaded_xor_px, floor));
  const double s_contact = b.Add(
      "contact_concentration", ps.contact_concentration,
      Ramp(ps.contact_concentration, 1.2, 3.0) * Ramp(ps.contact_fraction, 0.1, 0.4),
      fmt::format("{:.0f}% of it lies within {:.0f} px of the contact site on the rest shape, "
                  "{:.1f} times that zone's share of the area",
                  100 * ps.contact_fraction, a.push.contact_zone_radius_px,
                  ps.contact_concentration));
  const double keep = ps.released_early_xor_px > 0 ? ps.released_late_xor_px / ps.released_early_xor_px : NAN;
  const double s_keep = b.Add(
      "does_not_recover", keep, Ramp(keep, 0.5, 0.9),
      fmt::format("late / early released residual = {:.2f} (1: no recovery)", keep));
  *persistence = {s_persist, s_contact, s_keep, b.h.applicability};
  b.h.confidence = significance * b.h.applicability * s_persist * (0.6 + 0.4 * s_contact) *
                   (0.5 + 0.5 * s_keep);
  b.h.summary = "the residual stays after the load is gone, at the contact: a permanent dent";
  return b.h;
}

Hypothesis TracePlasticityInContext(const ResidualAnalysis& a, const TraceContext& context) {
  Persistence unused;
  return TracePlasticity(a, context.significance, &unused);
}

Hypothesis TraceViscoelastic(const ResidualAnalysis& a, const TraceContext& context) {
  const double significance = context.significance;
  Builder b("viscoelastic", a.recording);
  const PersistenceSummary& ps = a.persistence;
  const PushSummary& p = a.push;
  const double release_weight = ps.released ? Ramp(ps.released_frames, 5.0, 15.0) : 0.0;
  const bool released = release_weight > 0.0;
  const bool hold = p.has_push && std::isfinite(p.hold_force_change);
  b.h.applicability = std::max(release_weight, hold ? 1.0 : 0.0);
  if (b.h.applicability == 0.0) {
    b.Add("release_or_hold", 0.0, 0.0, "neither a release nor a hold to watch relaxation in");
    b.h.summary = "no release or hold";
    return b.h;
  }
  double s_fade = 0.0, s_settle = 0.0;
  if (released) {
    const double tau_frames = ps.recovery.tau_s * a.fps;
    const double observable = ps.recovery.tau_s < 2.0 * ps.released_frames / a.fps ? 1.0 : 0.3;
    s_fade = b.Add(
        "slow_recovery", ps.recovery.tau_s,
        Ramp(ps.fading_ratio, 0.1, 0.4) * Ramp(tau_frames, 3.0, 10.0) * Ramp(ps.recovery.r2, 0.3, 0.8) *
            observable * release_weight,
        fmt::format("after release the residual fades by {:.0f}% of the loaded residual with time "
                    "constant {:.2f} s ({:.0f} frames, fit r2 {:.2f}); the model recovers at once",
                    100 * ps.fading_ratio, ps.recovery.tau_s, tau_frames, ps.recovery.r2));
    double lag_frames = NAN;
    if (std::isfinite(ps.object_settle_s) && std::isfinite(ps.mesh_settle_s)) {
      lag_frames = (ps.object_settle_s - ps.mesh_settle_s) * a.fps;
      s_settle = Ramp(lag_frames, 3.0, 15.0);
    } else if (!std::isfinite(ps.object_settle_s) && std::isfinite(ps.mesh_settle_s)) {
      // The object still moves at the end: telling only after a while.
      s_settle = 0.7 * Ramp(ps.released_frames, 10.0, 30.0);
    }
    s_settle *= release_weight;
    b.Add("object_settles_later", lag_frames, s_settle,
          fmt::format("after release the object settles in {:.2f} s, the mesh in {:.2f} s",
                      ps.object_settle_s, ps.mesh_settle_s));
  }
  double s_relax = 0.0;
  if (hold) {
    s_relax = b.Add("force_relaxes_in_hold", p.hold_force_change,
                    Ramp(-p.hold_force_change, 0.05, 0.25),
                    fmt::format("while the pusher stands still for {} frames the measured force "
                                "changes by {:+.0f}%",
                                p.stopped_frames, 100 * p.hold_force_change));
  }
  b.h.confidence = significance * NoisyOr({{0.9, s_fade}, {0.5, s_settle}, {0.6, s_relax}});
  b.h.summary =
      "the object relaxes with a time constant (force decays at a still pusher, slow recovery "
      "after release) that the elastic model lacks";
  return b.h;
}

Hypothesis TraceUnevenStiffness(const ResidualAnalysis& a, const TraceContext& context) {
  const double significance = context.significance;
  const double persistent_support = context.release.persistent;
  Builder b("uneven_stiffness", a.recording);
  const RegionSummary& r = a.regions;
  b.h.applicability = a.push.has_push ? 1.0 : 0.6;
  const double eccentric = Ramp(a.push.load_eccentricity, 0.2, 0.6);
  const double s_side = b.Add(
      "side_asymmetry", r.side_asymmetry, Ramp(r.side_asymmetry, 0.15, 0.6) * (1.0 - 0.5 * eccentric),
      fmt::format("missed and extra pixels differ across the rest shape: signed density contrast "
                  "{:.2f} between the two sides of the {} (unsigned imbalance {:.2f}; load "
                  "eccentricity {:.2f})",
                  r.side_asymmetry, a.push.has_push ? "push line" : "centre line",
                  r.side_imbalance, a.push.load_eccentricity));
  // Across the push line only: along it, a dent by itself makes a dipole.
  const double dipole = a.push.has_push ? std::abs(r.side_dipole) : r.signed_dipole.norm();
  const double s_dipole = b.Add(
      "signed_dipole", dipole,
      Ramp(dipole, 0.1, 0.4) * (1.0 - 0.5 * eccentric) * (a.push.has_push ? 1.0 : 0.5),
      fmt::format("the signed residual (missed - extra) over the rest shape has a dipole of "
                  "{:.2f} {} (whole dipole ({:.2f}, {:.2f})): one side over-deforms, the other "
                  "under-deforms",
                  dipole, a.push.has_push ? "across the push line" : "",
                  r.signed_dipole.x(), r.signed_dipole.y()));
  const double elastic = 1.0 - persistent_support;
  // A shifted mesh is lopsided too (missed on one side, extra on the
  // other): discount by the share of the residual that shifting the mesh
  // onto the object's centroid removes, measured (loaded frames where there
  // are some). Comparing the offset's size with the residual's thickness
  // instead would discount the uneven field's own signature: a soft side
  // that dents deeper moves the object's centroid as well, by about as much
  // as the residual is thick, while the shifted mesh misses as much as ever.
  double shift_share = LoadedPlacementShare(a);
  if (!std::isfinite(shift_share) && a.mean_xor_px > 0.0) {
    shift_share = std::clamp(1.0 - a.mean_aligned_xor_px / a.mean_xor_px, 0.0, 1.0);
  }
  const double not_shift = 1.0 - Ramp(shift_share, 0.2, 0.6);
  b.Add("not_a_shift", shift_share, not_shift,
        fmt::format("{:.0f}% of the residual goes away when the mesh is shifted onto the "
                    "object's centroid (offset {:.1f} px on average; residual {:.2f} px thick)",
                    100 * shift_share, a.motion.mean_abs_offset_px, a.residual_thickness_px));
  b.h.confidence = significance * b.h.applicability * NoisyOr({{0.8, s_side}, {0.6, s_dipole}}) *
                   elastic * not_shift;
  b.h.summary = "the residual is lopsided over the rest shape and elastic: uneven stiffness";
  return b.h;
}

Hypothesis TraceStrainStiffening(const ResidualAnalysis& a, const TraceContext& context) {
  const double significance = context.significance;
  const double persistent_support = context.release.persistent;
  Builder b("strain_stiffening", a.recording);
  const StrainSummary& s = a.strain;
  b.h.applicability = s.num_frames >= 6 ? 1.0 : 0.0;
  if (b.h.applicability == 0.0) {
    b.Add("frames", s.num_frames, 0.0, "too few frames to relate error to deformation");
    b.h.summary = "too few frames";
    return b.h;
  }
  const double s_grow = b.Add(
      "error_grows_superlinearly", s.exponent,
      Ramp(s.correlation, 0.3, 0.8) * Ramp(s.exponent, 1.2, 2.0),
      fmt::format("the residual grows with the object's deformation (correlation {:.2f}) as "
                  "deformation^{:.2f}: {:.0f} / {:.0f} / {:.0f} px at deformation {:.3f} / {:.3f} "
                  "/ {:.3f}",
                  s.correlation, s.exponent, s.xor_px[0], s.xor_px[1], s.xor_px[2],
                  s.deformation[0], s.deformation[1], s.deformation[2]));
  const double s_convex = b.Add(
      "convexity", s.convexity, Ramp(s.convexity, 1.2, 3.0) * Ramp(s.correlation, 0.2, 0.5),
      fmt::format("the residual rises {:.1f} times faster per unit deformation in the largest "
                  "third than in the middle one",
                  s.convexity));
  const double flip = 0.5 * std::abs(s.signed_share[2] - s.signed_share[0]);
  const double s_flip = b.Add(
      "sign_flip", flip, Ramp(flip, 0.15, 0.5),
      fmt::format("the balance (missed - extra) / XOR goes from {:+.2f} at small deformation to "
                  "{:+.2f} at large: too stiff at small strain, too soft at large",
                  s.signed_share[0], s.signed_share[2]));
  // The sensor's force against the pusher's travel: where the pixels show
  // little (a stiff base fit absorbs a stiffening material's shape), the
  // force still says how the material answers a deeper dent. It is read off
  // the sensor, not the residual, so it does not need the thick residual
  // that makes the pixel signatures above reliable: only one thicker than
  // what the base model leaves where it is the truth's match (0.5-0.6 px
  // on the bundled no-effect pair).
  const PushSummary& p = a.push;
  const bool measured = std::isfinite(p.force_travel_exponent);
  const double thickness = std::max(a.residual_thickness_px, a.p90_thickness_px);
  const double residual_left = Ramp(thickness, 0.4, 0.7);
  const double s_force = b.Add(
      "force_stiffens", p.force_travel_exponent,
      measured ? Ramp(p.force_travel_exponent, 1.25, 1.5) *
                     Ramp(p.force_travel_correlation, 0.8, 0.95)
               : 0.0,
      measured ? fmt::format("the sensor's force grows as the pusher's travel^{:.2f} over {} "
                             "loading frames (r {:.2f}): the deeper the dent, the stiffer the "
                             "object (a linear material dented against a stop gives about 1); "
                             "weighed by the residual left, {:.2f} px thick ({:.2f} over "
                             "0.4-0.7 px)",
                             p.force_travel_exponent, p.force_travel_frames,
                             p.force_travel_correlation, thickness, residual_left)
               : "no force against travel to read (no sensor, no moving pusher or under 6 "
                 "loading frames)");
  const double pixels =
      significance * NoisyOr({{0.8, s_grow}, {0.5, s_convex}, {0.6, s_flip}});
  // Either suffices: a noisy-or of the two, written out so that without
  // the force's support the confidence is the pixels' to the bit.
  b.h.confidence = (1.0 - persistent_support) *
                   (pixels + (1.0 - pixels) * 0.9 * residual_left * s_force);
  b.h.summary = "good at small deformation, bad at large: strain stiffening";
  return b.h;
}

// The residual signatures, one per effect of core's EffectTermCatalogue(),
// in its order (which breaks ties of confidence). A new effect's signature
// is a Trace function above and a row here.
using TraceFunction = Hypothesis (*)(const ResidualAnalysis&, const TraceContext&);
struct Signature {
  const char* effect;
  TraceFunction trace;
};
constexpr Signature kSignatures[] = {
    {"inertia", &TraceInertia},
    {"table_friction", &TraceTableFriction},
    {"plasticity", &TracePlasticityInContext},
    {"uneven_stiffness", &TraceUnevenStiffness},
    {"strain_stiffening", &TraceStrainStiffening},
    {"viscoelastic", &TraceViscoelastic},
    {"push_relaxation", &TracePushRelaxation},
};

bool Ranked(const Hypothesis& x, const Hypothesis& y, const std::vector<std::string>& catalogue) {
  if (x.confidence != y.confidence) return x.confidence > y.confidence;
  return std::find(catalogue.begin(), catalogue.end(), x.effect) <
         std::find(catalogue.begin(), catalogue.end(), y.effect);
}

[[noreturn]] void BadHypothesisKey(const std::string& key, const std::string& what) {
  throw std::invalid_argument(fmt::format("hypothesis JSON: key '{}': {}", key, what));
}

}  // namespace

const std::vector<std::string>& TracedEffects() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const Signature& signature : kSignatures) out.emplace_back(signature.effect);
    return out;
  }();
  return names;
}

std::vector<Hypothesis> TraceHypotheses(const ResidualAnalysis& a,
                                        const std::vector<std::string>& already_in_model) {
  const double significance = Ramp(std::max(a.residual_thickness_px, a.p90_thickness_px), 0.8, 2.5);
  TraceContext context;
  context.significance = significance;
  (void)TracePlasticity(a, significance, &context.release);
  std::vector<Hypothesis> all;
  for (const Signature& signature : kSignatures) all.push_back(signature.trace(a, context));
  for (Hypothesis& h : all) {
    h.evidence.insert(h.evidence.begin(),
                      Evidence{"residual_thickness", a.p90_thickness_px, significance,
                               fmt::format("mean residual {:.0f} px/frame = {:.2f} px along the "
                                           "{:.0f} px rest outline ({:.2f} px in the worst "
                                           "tenth of the frames; mean IoU {:.4f})",
                                           a.mean_xor_px, a.residual_thickness_px,
                                           a.rest_perimeter_px, a.p90_thickness_px, a.mean_iou)});
  }
  std::vector<Hypothesis> out;
  for (Hypothesis& h : all) {
    if (std::find(already_in_model.begin(), already_in_model.end(), h.effect) ==
        already_in_model.end()) {
      out.push_back(std::move(h));
    }
  }
  const auto& catalogue = TracedEffects();
  std::stable_sort(out.begin(), out.end(),
                   [&](const Hypothesis& x, const Hypothesis& y) { return Ranked(x, y, catalogue); });
  return out;
}

std::vector<Hypothesis> MergeHypotheses(const std::vector<std::vector<Hypothesis>>& per_recording) {
  std::map<std::string, Hypothesis> merged;
  std::map<std::string, double> weighted, weight;
  std::map<std::string, int> count;
  for (const auto& list : per_recording) {
    for (const Hypothesis& h : list) {
      auto [it, fresh] = merged.try_emplace(h.effect);
      Hypothesis& m = it->second;
      if (fresh) {
        m.effect = h.effect;
        m.summary = h.summary;
        m.recordings.clear();
      }
      const std::string from = h.recordings.empty() ? std::string("?") : h.recordings.front();
      for (const std::string& r : h.recordings) m.recordings.push_back(r);
      for (Evidence e : h.evidence) {
        e.statement = from + ": " + e.statement;
        m.evidence.push_back(std::move(e));
      }
      if (h.applicability > 0.0 && m.summary.size() < h.summary.size()) m.summary = h.summary;
      weighted[h.effect] += h.applicability * h.confidence;
      weight[h.effect] += h.applicability;
      m.applicability += h.applicability;
      ++count[h.effect];
    }
  }
  std::vector<Hypothesis> out;
  for (auto& [effect, h] : merged) {
    h.confidence = weight[effect] > 0.0 ? weighted[effect] / weight[effect] : 0.0;
    h.applicability /= count[effect];
    out.push_back(std::move(h));
  }
  const auto& catalogue = TracedEffects();
  std::stable_sort(out.begin(), out.end(),
                   [&](const Hypothesis& x, const Hypothesis& y) { return Ranked(x, y, catalogue); });
  return out;
}

std::vector<Hypothesis> RankedByRate(std::vector<Hypothesis> hypotheses, const ConfidenceRates& rates) {
  const auto& catalogue = TracedEffects();
  const auto rate = [&](const Hypothesis& h) {
    const double r = RankingRate(rates, h.effect, h.confidence);
    return std::isnan(r) ? -1.0 : r;
  };
  std::stable_sort(hypotheses.begin(), hypotheses.end(), [&](const Hypothesis& x, const Hypothesis& y) {
    const double rx = rate(x), ry = rate(y);
    if (rx != ry) return rx > ry;
    return Ranked(x, y, catalogue);
  });
  return hypotheses;
}

std::string HypothesesReport(const std::vector<Hypothesis>& hypotheses) {
  std::string s;
  int rank = 1;
  for (const Hypothesis& h : hypotheses) {
    s += fmt::format("{}. {:<18} confidence {:.2f}: {}\n", rank++, h.effect, h.confidence, h.summary);
    const ConfidenceRates& rates = TuningFamilyConfidenceRates();
    const std::string rate = RateText(rates, h.effect, h.confidence);
    const double ranking = RankingRate(rates, h.effect, h.confidence);
    if (!rate.empty()) {
      s += std::isnan(ranking) ? fmt::format("     ({})\n", rate)
                               : fmt::format("     (tuning-family rate {:.2f}: {})\n", ranking, rate);
    }
    // The two strongest pieces of evidence.
    std::vector<const Evidence*> top;
    for (const Evidence& e : h.evidence) top.push_back(&e);
    std::stable_sort(top.begin(), top.end(),
                     [](const Evidence* x, const Evidence* y) { return x->support > y->support; });
    for (size_t i = 0; i < top.size() && i < 2; ++i) {
      s += fmt::format("     [{:.2f}] {}\n", top[i]->support, top[i]->statement);
    }
  }
  return s;
}

json ToJson(const Hypothesis& h) {
  json evidence = json::array();
  for (const Evidence& e : h.evidence) {
    evidence.push_back({{"signature", e.signature},
                        {"value", JsonNumber(e.value)},
                        {"support", JsonNumber(e.support)},
                        {"statement", e.statement}});
  }
  json doc = {{"effect", h.effect},         {"confidence", JsonNumber(h.confidence)},
              {"applicability", JsonNumber(h.applicability)}, {"summary", h.summary},
              {"evidence", evidence},       {"recordings", h.recordings}};
  // What the confidence meant on the tuning family (derived; not read back).
  const ConfidenceRates& rates = TuningFamilyConfidenceRates();
  if (const ConfidenceBin* all = rates.Find(h.confidence)) {
    const ConfidenceBin* own = rates.Find(h.effect, h.confidence);
    doc["tuning_family_rate"] = {{"from", all->from},
                                 {"to", all->to},
                                 {"effect", own == nullptr ? json(nullptr) : ToJson(*own)},
                                 {"all", ToJson(*all)}};
    doc["tuning_family_rate"]["estimate"] = JsonNumber(RankingRate(rates, h.effect, h.confidence));
  }
  return doc;
}

Hypothesis HypothesisFromJson(const json& doc) {
  if (!doc.is_object()) BadHypothesisKey("(root)", "expected an object");
  auto need = [&](const json& j, const char* key) -> const json& {
    if (!j.contains(key)) BadHypothesisKey(key, "missing");
    return j.at(key);
  };
  auto number = [&](const json& j, const char* key) {
    const json& v = need(j, key);
    if (v.is_null()) return static_cast<double>(NAN);
    if (!v.is_number()) BadHypothesisKey(key, "expected a number");
    return v.get<double>();
  };
  auto text = [&](const json& j, const char* key) {
    const json& v = need(j, key);
    if (!v.is_string()) BadHypothesisKey(key, "expected a string");
    return v.get<std::string>();
  };
  Hypothesis h;
  h.effect = text(doc, "effect");
  h.confidence = number(doc, "confidence");
  h.applicability = number(doc, "applicability");
  h.summary = text(doc, "summary");
  const json& ev = need(doc, "evidence");
  if (!ev.is_array()) BadHypothesisKey("evidence", "expected an array");
  for (const json& e : ev) {
    h.evidence.push_back(
        {text(e, "signature"), number(e, "value"), number(e, "support"), text(e, "statement")});
  }
  const json& rec = need(doc, "recordings");
  if (!rec.is_array()) BadHypothesisKey("recordings", "expected an array");
  for (const json& r : rec) {
    if (!r.is_string()) BadHypothesisKey("recordings", "expected strings");
    h.recordings.push_back(r.get<std::string>());
  }
  return h;
}

}  // namespace calib
