// The residual analysis over time: phases, motion, oscillation,
// persistence, the push and deformation (ResidualAnalyser::Finish).

#include "calib/discovery/residual.h"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

namespace calib {
namespace {

double Mean(const std::vector<double>& v) {
  double s = 0.0;
  int n = 0;
  for (double x : v) {
    if (std::isfinite(x)) {
      s += x;
      ++n;
    }
  }
  return n > 0 ? s / n : NAN;
}

// Least-squares slope of y against t (both finite pairs only).
double Slope(const std::vector<double>& t, const std::vector<double>& y) {
  double n = 0, st = 0, sy = 0, stt = 0, sty = 0;
  for (size_t i = 0; i < t.size(); ++i) {
    if (!std::isfinite(t[i]) || !std::isfinite(y[i])) continue;
    n += 1;
    st += t[i];
    sy += y[i];
    stt += t[i] * t[i];
    sty += t[i] * y[i];
  }
  if (n < 2) return 0.0;
  const double den = n * stt - st * st;
  return den > 1e-300 ? (n * sty - st * sy) / den : 0.0;
}

// How far the pusher moves into the object along `axis` from frame f - 1
// to f, px (0 when it backs off).
double PusherAdvance(const Scene& scene, int pusher, int f, const Vec2& axis) {
  return std::max(
      0.0, (scene.ObstaclesAt(f)[pusher].centre - scene.ObstaclesAt(f - 1)[pusher].centre).dot(axis));
}

// PushSummary::force_travel_exponent: log F against log travel over the
// loading frames up to the peak force (F >= 10 % of the peak), the travel
// along the push axis counted from the contact, the last frame before the
// peak with F under 2 % of it.
void MeasureForceAgainstTravel(const std::vector<ResidualFrame>& frames, const Scene& scene,
                               int pusher, PushSummary& push) {
  const int peak = push.peak_frame;
  if (pusher < 0 || peak <= 0 || !(push.peak_force_n > 0.0)) return;
  const double f_peak = push.peak_force_n;
  int contact = 0;
  for (int f = peak; f >= 0; --f) {
    if (frames[f].force_n < 0.02 * f_peak) {
      contact = f;
      break;
    }
  }
  std::vector<double> log_travel, log_force;
  double travel = 0.0;
  for (int f = contact + 1; f <= peak; ++f) {
    travel += PusherAdvance(scene, pusher, f, push.push_axis);
    if (frames[f].phase != LoadPhase::kLoading || frames[f].force_n < 0.1 * f_peak ||
        !(travel > 0.0)) {
      continue;
    }
    log_travel.push_back(std::log(travel));
    log_force.push_back(std::log(frames[f].force_n));
  }
  push.force_travel_frames = static_cast<int>(log_travel.size());
  if (log_travel.size() < 6) return;
  push.force_travel_exponent = Slope(log_travel, log_force);
  push.force_travel_correlation = Correlation(log_travel, log_force);
}

// Moving median of width 2h + 1.
std::vector<double> MovingMedian(const std::vector<double>& v, int h) {
  const int n = static_cast<int>(v.size());
  std::vector<double> out(n), window;
  for (int i = 0; i < n; ++i) {
    window.assign(v.begin() + std::max(0, i - h), v.begin() + std::min(n, i + h + 1));
    std::nth_element(window.begin(), window.begin() + window.size() / 2, window.end());
    out[i] = window[window.size() / 2];
  }
  return out;
}

// Moving average of the finite samples, width 2h + 1.
std::vector<Vec2> Smooth(const std::vector<Vec2>& v, int h) {
  const int n = static_cast<int>(v.size());
  std::vector<Vec2> out(n, Vec2(NAN, NAN));
  for (int i = 0; i < n; ++i) {
    Vec2 s = Vec2::Zero();
    int k = 0;
    for (int j = std::max(0, i - h); j < std::min(n, i + h + 1); ++j) {
      if (v[j].allFinite()) {
        s += v[j];
        ++k;
      }
    }
    if (k > 0) out[i] = s / k;
  }
  return out;
}

// Unit major axis of the scatter of the finite points (x axis when they do
// not spread).
Vec2 PrincipalAxis(const std::vector<Vec2>& points) {
  Vec2 mean = Vec2::Zero();
  int n = 0;
  for (const Vec2& p : points) {
    if (p.allFinite()) {
      mean += p;
      ++n;
    }
  }
  if (n < 2) return Vec2(1.0, 0.0);
  mean /= n;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const Vec2& p : points) {
    if (p.allFinite()) cov += (p - mean) * (p - mean).transpose();
  }
  if (cov.trace() < 1e-12) return Vec2(1.0, 0.0);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(cov);
  Vec2 axis = solver.eigenvectors().col(1);
  // A fixed sign convention: the larger component positive.
  if ((std::abs(axis.x()) >= std::abs(axis.y()) ? axis.x() : axis.y()) < 0.0) axis = -axis;
  return axis;
}

std::vector<double> Project(const std::vector<Vec2>& points, const Vec2& axis) {
  std::vector<double> out(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    out[i] = points[i].allFinite() ? points[i].dot(axis) : NAN;
  }
  return out;
}

double Rms(const std::vector<double>& v) {
  const double m = Mean(v);
  double s = 0.0;
  int n = 0;
  for (double x : v) {
    if (std::isfinite(x)) {
      s += (x - m) * (x - m);
      ++n;
    }
  }
  return n > 0 ? std::sqrt(s / n) : 0.0;
}

// Signed density contrast of two regions (see RegionSummary).
void Contrast(const RegionCounts& a, double area_a, const RegionCounts& b, double area_b,
              double* signed_contrast, double* unsigned_contrast) {
  *signed_contrast = 0.0;
  *unsigned_contrast = 0.0;
  if (area_a <= 0.0 || area_b <= 0.0) return;
  const double sa = (a.missed - a.extra) / area_a, sb = (b.missed - b.extra) / area_b;
  const double ua = (a.missed + a.extra) / area_a, ub = (b.missed + b.extra) / area_b;
  if (ua + ub <= 0.0) return;
  *signed_contrast = std::abs(sa - sb) / (0.5 * (ua + ub));
  *unsigned_contrast = std::abs(ua - ub) / (ua + ub);
}

// Seconds after `start` until `change` (smoothed) stays at or below
// `threshold` to the end; NaN if it never settles.
double SettleTime(const std::vector<double>& change, int start, double threshold, double fps) {
  const int n = static_cast<int>(change.size());
  if (start >= n) return NAN;
  const std::vector<double> smooth = MovingMedian(change, 2);
  int last_above = start - 1;
  for (int i = start; i < n; ++i) {
    if (smooth[i] > threshold) last_above = i;
  }
  if (last_above == n - 1) return NAN;
  return (last_above + 1 - start) / fps;
}

}  // namespace

const PhaseSummary* ResidualAnalysis::Phase(LoadPhase phase) const {
  for (const PhaseSummary& p : phases) {
    if (p.phase == phase) return &p;
  }
  return nullptr;
}

ResidualAnalysis ResidualAnalyser::Finish() const {
  ResidualAnalysis out;
  out.recording = facts_->recording_name;
  out.fps = 1.0 / scene_.frame_time_s;
  out.num_frames = scene_.num_frames;
  out.frames_analysed = static_cast<int>(frames_.size());
  out.obstacle_names = facts_->obstacle_names;
  out.obstacle_bands_px = options_.obstacle_bands_px;
  out.rest_centroid_px = facts_->rest_centroid_px;
  out.rest_area_px = facts_->rest_area_px;
  out.rest_perimeter_px = facts_->rest_perimeter_px;
  out.rest_radius_of_gyration_px = facts_->rest_radius_of_gyration_px;
  out.frames = frames_;
  out.heat_map = heat_map_;
  out.regions = regions_;
  out.push = facts_->push;
  const int n = out.frames_analysed;
  const double fps = out.fps;
  const size_t bands = static_cast<size_t>(scene_.num_obstacles) * options_.obstacle_bands_px.size();
  out.band_missed_px.assign(bands, 0);
  out.band_extra_px.assign(bands, 0);
  if (n == 0) return out;

  // Per-frame series.
  std::vector<double> t(n), xor_px(n), aligned(n), abs_offset(n), angle(n), object_change(n),
      mesh_change(n);
  std::vector<Vec2> object_c(n), mesh_c(n), offset(n);
  double iou_sum = 0.0;
  for (int f = 0; f < n; ++f) {
    const ResidualFrame& r = frames_[f];
    t[f] = r.time_s;
    xor_px[f] = static_cast<double>(r.missed_px + r.extra_px);
    aligned[f] = static_cast<double>(r.aligned_xor_px);
    offset[f] = r.offset_px;
    abs_offset[f] = r.offset_px.allFinite() ? r.offset_px.norm() : NAN;
    angle[f] = r.angle_diff_rad;
    object_c[f] = r.object_centroid_px;
    mesh_c[f] = r.mesh_centroid_px;
    object_change[f] = static_cast<double>(r.object_change_px);
    mesh_change[f] = static_cast<double>(r.mesh_change_px);
    out.xor_sum += r.missed_px + r.extra_px;
    iou_sum += r.iou;
    for (size_t b = 0; b < bands; ++b) {
      out.band_missed_px[b] += r.band_missed_px[b];
      out.band_extra_px[b] += r.band_extra_px[b];
    }
    out.far_missed_px += r.far_missed_px;
    out.far_extra_px += r.far_extra_px;
  }
  out.mean_xor_px = static_cast<double>(out.xor_sum) / n;
  out.mean_iou = iou_sum / n;
  out.mean_aligned_xor_px = Mean(aligned);
  const double perimeter = facts_->rest_perimeter_px;
  out.residual_thickness_px = perimeter > 0.0 ? out.mean_xor_px / perimeter : 0.0;
  {
    std::vector<double> sorted = xor_px;
    const size_t k = std::min(sorted.size() - 1, static_cast<size_t>(0.9 * sorted.size()));
    std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
    out.p90_thickness_px = perimeter > 0.0 ? sorted[k] / perimeter : 0.0;
  }

  // Worst frames, at least 5 % of the recording apart.
  {
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return xor_px[a] > xor_px[b]; });
    const int gap = std::max(1, static_cast<int>(std::lround(0.05 * n)));
    for (int f : order) {
      if (out.worst_frames.size() >= 5) break;
      bool far_enough = true;
      for (int w : out.worst_frames) far_enough &= std::abs(w - f) >= gap;
      if (far_enough) out.worst_frames.push_back(f);
    }
  }

  // Phases.
  for (int p = 0; p < kNumLoadPhases; ++p) {
    const LoadPhase phase = static_cast<LoadPhase>(p);
    PhaseSummary s;
    s.phase = phase;
    std::vector<double> pt, px, po;
    double missed = 0, extra = 0, al = 0, iou = 0, off = 0, oc = 0, mc = 0, force = 0;
    int off_n = 0;
    for (int f = 0; f < n; ++f) {
      const ResidualFrame& r = frames_[f];
      if (r.phase != phase) continue;
      if (s.num_frames == 0) {
        s.first_frame = f;
        s.object_travel_px = 0.0;
      }
      // Travel over the phase's first run.
      if (s.num_frames == 0 || s.last_frame == f - 1) {
        const ResidualFrame& first = frames_[s.first_frame];
        const Vec2 dob = r.object_centroid_px - first.object_centroid_px;
        const Vec2 dme = r.mesh_centroid_px - first.mesh_centroid_px;
        if (dob.allFinite()) s.object_travel_px = dob.norm();
        if (dme.allFinite()) s.mesh_travel_px = dme.norm();
        s.last_frame = f;
      }
      ++s.num_frames;
      pt.push_back(t[f]);
      px.push_back(xor_px[f]);
      po.push_back(abs_offset[f]);
      missed += r.missed_px;
      extra += r.extra_px;
      al += r.aligned_xor_px;
      iou += r.iou;
      if (std::isfinite(abs_offset[f])) {
        off += abs_offset[f];
        ++off_n;
      }
      oc += r.object_change_px;
      mc += r.mesh_change_px;
      force += r.force_n;
    }
    if (s.num_frames == 0) continue;
    // last_frame: the last frame of the phase overall.
    for (int f = n - 1; f >= 0; --f) {
      if (frames_[f].phase == phase) {
        s.last_frame = f;
        break;
      }
    }
    const double k = s.num_frames;
    s.mean_missed_px = missed / k;
    s.mean_extra_px = extra / k;
    s.mean_xor_px = (missed + extra) / k;
    s.mean_aligned_xor_px = al / k;
    s.mean_iou = iou / k;
    s.mean_offset_px = off_n > 0 ? off / off_n : NAN;
    s.xor_slope_px_per_s = Slope(pt, px);
    s.offset_slope_px_per_s = Slope(pt, po);
    s.mean_object_change_px = oc / k;
    s.mean_mesh_change_px = mc / k;
    s.mean_force_n = force / k;
    out.phases.push_back(s);
  }

  // Motion.
  MotionSummary& m = out.motion;
  {
    Vec2 sum = Vec2::Zero();
    double abs_sum = 0.0, abs_max = 0.0, down = 0.0, angle_sum = 0.0, angle_max = 0.0, aniso = 0.0;
    int k = 0, ka = 0;
    for (int f = 0; f < n; ++f) {
      if (offset[f].allFinite()) {
        sum += offset[f];
        abs_sum += abs_offset[f];
        abs_max = std::max(abs_max, abs_offset[f]);
        down += offset[f].y();
        ++k;
      }
      if (std::isfinite(angle[f])) {
        angle_sum += angle[f];
        angle_max = std::max(angle_max, std::abs(angle[f]));
        ++ka;
      }
    }
    for (int f = 0; f < n; ++f) aniso += facts_->object_moments[f].anisotropy;
    m.mean_anisotropy = aniso / n;
    if (k > 0) {
      m.mean_offset_px = sum / k;
      m.mean_abs_offset_px = abs_sum / k;
      m.max_abs_offset_px = abs_max;
      m.offset_consistency = abs_sum > 0.0 ? m.mean_offset_px.norm() / m.mean_abs_offset_px : 0.0;
      m.mean_offset_down_px = down / k;
    }
    if (ka > 0) {
      m.mean_angle_diff_rad = angle_sum / ka;
      m.max_abs_angle_diff_rad = angle_max;
    }
    m.offset_slope_px_per_s = Slope(t, abs_offset);
    m.motion_axis = PrincipalAxis(object_c);
    const std::vector<double> ob = Project(object_c, m.motion_axis);
    const std::vector<double> me = Project(mesh_c, m.motion_axis);
    m.object_motion_rms_px = Rms(ob);
    m.mesh_motion_rms_px = Rms(me);
    // Lag: correlation of object[t] with mesh[t + lag].
    const int max_lag = std::min(static_cast<int>(std::lround(options_.max_lag_s * fps)), n / 4);
    m.lag_correlation0 = Correlation(ob, me);
    m.lag_correlation = m.lag_correlation0;
    m.lag_frames = 0;
    for (int lag = -max_lag; lag <= max_lag; ++lag) {
      const int a0 = std::max(0, -lag), len = n - std::abs(lag);
      if (len < 8) continue;
      const double c = Correlation(std::span<const double>(ob).subspan(a0, len),
                                   std::span<const double>(me).subspan(a0 + lag, len));
      if (c > m.lag_correlation + 1e-12) {
        m.lag_correlation = c;
        m.lag_frames = lag;
      }
    }
    m.lag_s = m.lag_frames / fps;
    // Displacement and path.
    auto first_finite = [&](const std::vector<Vec2>& v, bool from_end) {
      for (int i = 0; i < n; ++i) {
        const Vec2& p = v[from_end ? n - 1 - i : i];
        if (p.allFinite()) return p;
      }
      return Vec2(Vec2::Zero());
    };
    m.object_displacement_px = first_finite(object_c, true) - first_finite(object_c, false);
    m.mesh_displacement_px = first_finite(mesh_c, true) - first_finite(mesh_c, false);
    const std::vector<Vec2> so = Smooth(object_c, 2), sm = Smooth(mesh_c, 2);
    for (int f = 1; f < n; ++f) {
      if (so[f].allFinite() && so[f - 1].allFinite()) m.object_path_px += (so[f] - so[f - 1]).norm();
      if (sm[f].allFinite() && sm[f - 1].allFinite()) m.mesh_path_px += (sm[f] - sm[f - 1]).norm();
    }

    OscillationSummary& o = out.oscillation;
    const Vec2 offset_axis = PrincipalAxis(offset);
    o.offset = DetectOscillation(Project(offset, offset_axis), fps, options_.oscillation);
    o.object_motion = DetectOscillation(ob, fps, options_.oscillation);
    o.mesh_motion = DetectOscillation(me, fps, options_.oscillation);
    o.xor_px = DetectOscillation(xor_px, fps, options_.oscillation);
    o.angle_diff = DetectOscillation(angle, fps, options_.oscillation);
  }

  // Persistence after release.
  PersistenceSummary& ps = out.persistence;
  {
    std::vector<double> before, loaded, released;
    std::vector<double> before_rigid, loaded_rigid, released_rigid;
    std::vector<std::pair<double, double>> loaded_by_force;
    int release = -1;
    for (int f = 0; f < n; ++f) {
      const LoadPhase p = frames_[f].phase;
      const auto rigid = static_cast<double>(frames_[f].rigid_xor_px);
      if (p == LoadPhase::kBeforeLoad) {
        before.push_back(xor_px[f]);
        before_rigid.push_back(rigid);
      }
      if (IsLoaded(p)) {
        loaded.push_back(xor_px[f]);
        loaded_rigid.push_back(rigid);
        loaded_by_force.push_back({frames_[f].force_n, xor_px[f]});
      }
      if (p == LoadPhase::kReleased) {
        if (release < 0) release = f;
        released.push_back(xor_px[f]);
        released_rigid.push_back(rigid);
      }
    }
    // Floor of the change signals: the quietest 9-frame median.
    std::vector<double> oc_tail(object_change.begin() + std::min(1, n), object_change.end());
    if (!oc_tail.empty()) {
      const std::vector<double> med = MovingMedian(oc_tail, 4);
      ps.object_change_floor_px = *std::min_element(med.begin(), med.end());
    }
    if (!before.empty()) ps.before_xor_px = Mean(before);
    if (!loaded.empty()) {
      ps.loaded_xor_px = Mean(loaded);
      std::stable_sort(loaded_by_force.begin(), loaded_by_force.end(),
                       [](const auto& a, const auto& b) { return a.first > b.first; });
      const size_t third = std::max<size_t>(1, loaded_by_force.size() / 3);
      double s = 0.0;
      for (size_t i = 0; i < third; ++i) s += loaded_by_force[i].second;
      ps.peak_loaded_xor_px = s / third;
    }
    ps.released = release >= 0 && !loaded.empty();
    if (ps.released) {
      ps.release_frame = release;
      ps.released_frames = static_cast<int>(released.size());
      ps.released_xor_px = Mean(released);
      const size_t third = std::max<size_t>(1, released.size() / 3);
      ps.released_early_xor_px =
          Mean(std::vector<double>(released.begin(), released.begin() + third));
      ps.released_late_xor_px = Mean(std::vector<double>(released.end() - third, released.end()));
      const double floor = std::isfinite(ps.before_xor_px) ? ps.before_xor_px : 0.0;
      const double span = std::max(ps.loaded_xor_px - floor, 1.0);
      ps.persistent_ratio = std::max(0.0, ps.released_late_xor_px - floor) / span;
      ps.fading_ratio = std::max(0.0, ps.released_early_xor_px - ps.released_late_xor_px) / span;
      // The same for the shape's own error (a pose left wrong not counted).
      if (!before_rigid.empty()) ps.before_rigid_xor_px = Mean(before_rigid);
      ps.loaded_rigid_xor_px = Mean(loaded_rigid);
      ps.released_late_rigid_xor_px =
          Mean(std::vector<double>(released_rigid.end() - third, released_rigid.end()));
      const double rigid_floor = std::isfinite(ps.before_rigid_xor_px) ? ps.before_rigid_xor_px : 0.0;
      ps.shape_persistent_ratio = std::max(0.0, ps.released_late_rigid_xor_px - rigid_floor) /
                                  std::max(ps.loaded_rigid_xor_px - rigid_floor, 1.0);
      const auto& rel = regions_.counts[2];
      const RegionCounts& all = rel[static_cast<int>(RestRegion::kAll)];
      const RegionCounts& contact = rel[static_cast<int>(RestRegion::kContact)];
      const double total = static_cast<double>(all.missed + all.extra);
      const double area_all = regions_.area_px[static_cast<int>(RestRegion::kAll)];
      const double area_contact = regions_.area_px[static_cast<int>(RestRegion::kContact)];
      if (total > 0.0) {
        ps.contact_fraction = (contact.missed + contact.extra) / total;
        if (area_contact > 0.0 && area_all > 0.0) {
          ps.contact_concentration = ps.contact_fraction / (area_contact / area_all);
        }
      }
      // The first released run.
      std::vector<double> run;
      for (int f = release; f < n && frames_[f].phase == LoadPhase::kReleased; ++f) {
        run.push_back(xor_px[f]);
      }
      ps.recovery = FitExponentialDecay(run, 1.0 / fps);
      ps.object_settle_s =
          SettleTime(object_change, release, 1.5 * ps.object_change_floor_px + 2.0, fps);
      std::vector<double> mc_tail(mesh_change.begin() + std::min(1, n), mesh_change.end());
      double mesh_floor = 0.0;
      if (!mc_tail.empty()) {
        const std::vector<double> med = MovingMedian(mc_tail, 4);
        mesh_floor = *std::min_element(med.begin(), med.end());
      }
      ps.mesh_settle_s = SettleTime(mesh_change, release, 1.5 * mesh_floor + 2.0, fps);
    }
  }

  // The push.
  PushSummary& push = out.push;
  if (push.has_push) {
    const Vec2 a = push.push_axis;
    std::vector<double> pushed, off_abs, along;
    double so_far = 0.0;
    for (int f = 0; f < n; ++f) {
      const LoadPhase p = frames_[f].phase;
      if (f > 0 && IsLoaded(p) && facts_->pusher >= 0) {
        so_far += PusherAdvance(scene_, facts_->pusher, f, a);
      }
      if (!IsLoaded(p)) continue;
      pushed.push_back(so_far);
      off_abs.push_back(abs_offset[f]);
      along.push_back(offset[f].allFinite() ? offset[f].dot(a) : NAN);
    }
    push.offset_push_correlation = Correlation(pushed, off_abs);
    push.offset_per_push = Slope(pushed, off_abs);
    push.mean_offset_along_push_px = Mean(along);
    // The first run of frames in which the pusher stands still while loaded.
    int start = -1, end = -1;
    for (int f = 0; f < n; ++f) {
      if (frames_[f].phase == LoadPhase::kHold) {
        if (start < 0) start = f;
        end = f;
      } else if (start >= 0) {
        break;
      }
    }
    if (start >= 0) {
      push.stopped_frames = end - start + 1;
      const Vec2 dm = mesh_c[end] - mesh_c[start], dob = object_c[end] - object_c[start];
      if (dm.allFinite()) push.mesh_travel_after_stop_px = dm.dot(a);
      if (dob.allFinite()) push.object_travel_after_stop_px = dob.dot(a);
      if (push.stopped_frames >= 3 && frames_[start].force_n > 0.0) {
        push.hold_force_change =
            (frames_[end].force_n - frames_[start].force_n) / frames_[start].force_n;
      }
    }
    MeasureForceAgainstTravel(frames_, scene_, facts_->pusher, push);
  }

  // Residual against deformation.
  StrainSummary& st = out.strain;
  {
    std::vector<int> used;
    for (int f = 0; f < n; ++f) {
      if (!push.has_push || IsLoaded(frames_[f].phase)) used.push_back(f);
    }
    st.num_frames = static_cast<int>(used.size());
    if (used.size() >= 6) {
      std::stable_sort(used.begin(), used.end(), [&](int a, int b) {
        return frames_[a].object_deformation < frames_[b].object_deformation;
      });
      const size_t k = used.size();
      for (int third = 0; third < 3; ++third) {
        const size_t b = k * third / 3, e = k * (third + 1) / 3;
        double d = 0, x = 0, mi = 0, ex = 0;
        for (size_t i = b; i < e; ++i) {
          const ResidualFrame& r = frames_[used[i]];
          d += r.object_deformation;
          x += r.missed_px + r.extra_px;
          mi += r.missed_px;
          ex += r.extra_px;
        }
        st.deformation[third] = d / (e - b);
        st.xor_px[third] = x / (e - b);
        st.signed_share[third] = mi + ex > 0 ? (mi - ex) / (mi + ex) : 0.0;
      }
      std::vector<double> def, err;
      for (int f : used) {
        def.push_back(frames_[f].object_deformation);
        err.push_back(xor_px[f]);
      }
      st.correlation = Correlation(def, err);
      const double d1 = st.deformation[1] - st.deformation[0];
      const double d2 = st.deformation[2] - st.deformation[1];
      const double s1 = d1 > 1e-6 ? (st.xor_px[1] - st.xor_px[0]) / d1 : NAN;
      const double s2 = d2 > 1e-6 ? (st.xor_px[2] - st.xor_px[1]) / d2 : NAN;
      if (std::isfinite(s1) && std::isfinite(s2) && std::abs(s1) > 1e-9) {
        st.convexity = std::clamp(s2 / s1, -10.0, 10.0);
      }
      const double floor =
          std::isfinite(out.persistence.before_xor_px) ? out.persistence.before_xor_px : 0.0;
      std::vector<double> ld, le;
      for (size_t i = 0; i < def.size(); ++i) {
        if (def[i] > 1e-3 && err[i] - floor > 1.0) {
          ld.push_back(std::log(def[i]));
          le.push_back(std::log(err[i] - floor));
        }
      }
      if (ld.size() >= 6) st.exponent = Slope(ld, le);
    }
  }

  // Regions.
  RegionSummary& rg = out.regions;
  {
    const int group = push.has_push ? 1 : 0;
    const auto& c = rg.counts[group];
    auto at = [](RestRegion r) { return static_cast<int>(r); };
    double unused = 0.0;
    Contrast(c[at(RestRegion::kSideNeg)], rg.area_px[at(RestRegion::kSideNeg)],
             c[at(RestRegion::kSidePos)], rg.area_px[at(RestRegion::kSidePos)], &rg.side_asymmetry,
             &rg.side_imbalance);
    Contrast(c[at(RestRegion::kNear)], rg.area_px[at(RestRegion::kNear)],
             c[at(RestRegion::kFar)], rg.area_px[at(RestRegion::kFar)], &rg.near_far_asymmetry,
             &unused);
    if (dipole_weight_ > 0.0 && facts_->rest_radius_of_gyration_px > 0.0) {
      rg.signed_dipole = dipole_sum_ / (dipole_weight_ * facts_->rest_radius_of_gyration_px);
      rg.side_dipole = rg.signed_dipole.dot(facts_->side_axis);
    }
  }
  return out;
}

std::string ResidualAnalysis::BriefReport() const {
  std::string s = fmt::format(
      "{}: {} of {} frames, mean XOR {:.0f} px/frame (thickness {:.2f} px, {:.0f}% shape after "
      "centroid alignment), mean IoU {:.4f}\n",
      recording, frames_analysed, num_frames, mean_xor_px, residual_thickness_px,
      mean_xor_px > 0 ? 100.0 * mean_aligned_xor_px / mean_xor_px : 0.0, mean_iou);
  for (const PhaseSummary& p : phases) {
    s += fmt::format("  {:<11} frames {:>4}..{:<4} XOR {:8.0f} px (missed {:.0f}, extra {:.0f}), "
                     "|offset| {:.2f} px, slope {:+.1f} px/s\n",
                     ToString(p.phase), p.first_frame, p.last_frame, p.mean_xor_px,
                     p.mean_missed_px, p.mean_extra_px, p.mean_offset_px, p.xor_slope_px_per_s);
  }
  s += fmt::format(
      "  offset: mean ({:.2f}, {:.2f}) px, mean |.| {:.2f}, max {:.2f}; angle diff mean {:.2f} "
      "deg; motion rms object {:.2f} px, mesh {:.2f} px; lag {} frames (r {:.2f}, r0 {:.2f})\n",
      motion.mean_offset_px.x(), motion.mean_offset_px.y(), motion.mean_abs_offset_px,
      motion.max_abs_offset_px, motion.mean_angle_diff_rad * 180.0 / std::numbers::pi,
      motion.object_motion_rms_px, motion.mesh_motion_rms_px, motion.lag_frames,
      motion.lag_correlation, motion.lag_correlation0);
  auto osc = [](const char* name, const Oscillation& o) {
    return o.found ? fmt::format("  oscillation of {}: period {:.3f} s, strength {:.2f}, amplitude "
                                 "{:.2f}, decay {:.2f}/s, {:.1f} cycles\n",
                                 name, o.period_s, o.strength, o.amplitude, o.decay_per_s, o.cycles)
                   : fmt::format("  oscillation of {}: none\n", name);
  };
  s += osc("offset", oscillation.offset);
  s += osc("object motion", oscillation.object_motion);
  s += osc("mesh motion", oscillation.mesh_motion);
  if (persistence.released) {
    s += fmt::format(
        "  after release (frame {}): XOR {:.0f} px, persistent {:.0f}%, fading {:.0f}%, contact "
        "concentration {:.2f}, recovery tau {:.2f} s (r2 {:.2f})\n",
        persistence.release_frame, persistence.released_xor_px,
        100.0 * persistence.persistent_ratio, 100.0 * persistence.fading_ratio,
        persistence.contact_concentration, persistence.recovery.tau_s, persistence.recovery.r2);
  }
  if (push.has_push) {
    s += fmt::format(
        "  push: peak frame {}, {:.2f} N, distance {:.1f} px; offset~push r {:.2f}; after stop "
        "mesh {:+.2f} px, object {:+.2f} px over {} frames; hold force change {:+.0f}%; force ~ "
        "travel^{:.2f} (r {:.2f}, {} frames)\n",
        push.peak_frame, push.peak_force_n, push.push_distance_px, push.offset_push_correlation,
        push.mesh_travel_after_stop_px, push.object_travel_after_stop_px, push.stopped_frames,
        100.0 * push.hold_force_change, push.force_travel_exponent, push.force_travel_correlation,
        push.force_travel_frames);
  }
  s += fmt::format(
      "  strain: XOR by deformation third {:.0f} / {:.0f} / {:.0f} px, r {:.2f}, exponent {:.2f}; "
      "side asymmetry {:.2f}, imbalance {:.2f}; dipole ({:.2f}, {:.2f})\n",
      strain.xor_px[0], strain.xor_px[1], strain.xor_px[2], strain.correlation, strain.exponent,
      regions.side_asymmetry, regions.side_imbalance, regions.signed_dipole.x(),
      regions.signed_dipole.y());
  return s;
}

}  // namespace calib
