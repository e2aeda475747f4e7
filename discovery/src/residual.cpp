// The one-pass residual analyser: what is known before the pass
// (ComputeResidualFacts: phases, object moments, the push; once per
// recording) and the per-frame work (split, bands, mapping to
// the rest shape). The summaries over time are in residual_summary.cpp.

#include "calib/discovery/residual.h"

#include "calib/core/enum_names.h"

#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/rasterizer.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <tuple>
#include <utility>

namespace calib {
namespace {

constexpr auto kRegionNames = std::to_array<EnumName<RestRegion>>({
    {RestRegion::kNear, "near"},
    {RestRegion::kFar, "far"},
    {RestRegion::kSideNeg, "side_neg"},
    {RestRegion::kSidePos, "side_pos"},
    {RestRegion::kLeft, "left"},
    {RestRegion::kRight, "right"},
    {RestRegion::kTop, "top"},
    {RestRegion::kBottom, "bottom"},
    {RestRegion::kContact, "contact"},
    {RestRegion::kAll, "all"},
});
static_assert(kRegionNames.size() == kNumRestRegions);

// 1 where an object pixel lies within `reach` px of `centre` (pixel centres).
bool Touches(const BitMask& mask, const Vec2& centre, double reach) {
  const int x0 = std::max(0, static_cast<int>(std::floor(centre.x() - reach - mask.origin_x())));
  const int x1 = std::min(mask.width() - 1,
                          static_cast<int>(std::ceil(centre.x() + reach - mask.origin_x())));
  const int y0 = std::max(0, static_cast<int>(std::floor(centre.y() - reach - mask.origin_y())));
  const int y1 = std::min(mask.height() - 1,
                          static_cast<int>(std::ceil(centre.y() + reach - mask.origin_y())));
  const double r2 = reach * reach;
  for (int y = y0; y <= y1; ++y) {
    const double dy = mask.origin_y() + y + 0.5 - centre.y();
    for (int x = x0; x <= x1; ++x) {
      const double dx = mask.origin_x() + x + 0.5 - centre.x();
      if (dx * dx + dy * dy <= r2 && mask.Get(x, y)) return true;
    }
  }
  return false;
}

// Nearest point to p on segment [a, b]: its parameter in [0, 1].
double ProjectOnSegment(const Vec2& p, const Vec2& a, const Vec2& b, double* dist2) {
  const Vec2 ab = b - a;
  const double len2 = ab.squaredNorm();
  double t = len2 > 0.0 ? (p - a).dot(ab) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  *dist2 = (a + t * ab - p).squaredNorm();
  return t;
}

}  // namespace

std::string ToString(RestRegion region) { return EnumToString(kRegionNames, region); }

bool ResidualOptions::IsValid(std::string* error) const {
  auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return false;
  };
  if (obstacle_bands_px.empty()) {
    return fail("ResidualOptions::obstacle_bands_px is empty. Violated: at least one band.");
  }
  for (size_t i = 0; i < obstacle_bands_px.size(); ++i) {
    const double b = obstacle_bands_px[i];
    if (!(std::isfinite(b) && b > 0.0) || (i > 0 && !(b > obstacle_bands_px[i - 1]))) {
      return fail(fmt::format(
          "ResidualOptions::obstacle_bands_px[{}] = {}. Violated: finite, > 0 and increasing.", i,
          b));
    }
  }
  if (!(heat_map_cells >= 1 && heat_map_cells <= 100000)) {
    return fail(fmt::format(
        "ResidualOptions::heat_map_cells = {}. Violated: 1 <= heat_map_cells <= 100000.",
        heat_map_cells));
  }
  if (!(contact_radius_px > 0.0)) {
    return fail(fmt::format(
        "ResidualOptions::contact_radius_px = {}. Violated: contact_radius_px > 0.",
        contact_radius_px));
  }
  if (!(contact_margin_px >= 0.0)) {
    return fail(fmt::format(
        "ResidualOptions::contact_margin_px = {}. Violated: contact_margin_px >= 0.",
        contact_margin_px));
  }
  if (!(max_lag_s >= 0.0)) {
    return fail(fmt::format("ResidualOptions::max_lag_s = {}. Violated: max_lag_s >= 0.",
                            max_lag_s));
  }
  if (!(oscillation.min_period_frames >= 2.0 && oscillation.min_cycles >= 1.0 &&
        oscillation.min_strength >= 0.0 && oscillation.min_strength <= 1.0)) {
    return fail(fmt::format(
        "ResidualOptions::oscillation = {{min_period_frames {}, min_cycles {}, min_strength {}}}. "
        "Violated: min_period_frames >= 2, min_cycles >= 1, 0 <= min_strength <= 1.",
        oscillation.min_period_frames, oscillation.min_cycles, oscillation.min_strength));
  }
  return phases.IsValid(error);
}

RecordingResidualFacts ComputeResidualFacts(const PreparedRecording& prepared,
                                            const ResidualOptions& options) {
  std::vector<std::string> obstacle_names;
  for (const ObstacleTrack& t : prepared.recording.obstacles) obstacle_names.push_back(t.name);
  std::string recording_name = RecordingDisplayName(prepared.recording.folder);
  return ComputeResidualFacts(prepared.mesh, prepared.scene, prepared.object_masks,
                              std::move(obstacle_names), std::move(recording_name), options);
}

RecordingResidualFacts ComputeResidualFacts(const Mesh& rest_mesh, const Scene& scene,
                                            const std::vector<BitMask>& object_masks,
                                            std::vector<std::string> obstacle_names,
                                            std::string recording_name,
                                            const ResidualOptions& options) {
  RecordingResidualFacts facts;
  facts.rest_mesh = &rest_mesh;
  facts.scene = &scene;
  facts.object_masks = &object_masks;
  facts.obstacle_names = std::move(obstacle_names);
  facts.recording_name = std::move(recording_name);
  facts.options = options;
  const Mesh& mesh = rest_mesh;

  std::string error;
  if (!options.IsValid(&error)) throw std::invalid_argument(error);
  const int n = scene.num_frames;
  if (n < 1 || static_cast<int>(object_masks.size()) != n) {
    throw std::invalid_argument(fmt::format(
        "ResidualAnalyser: {} object masks for a scene of {} frames", object_masks.size(), n));
  }
  for (int f = 1; f < n; ++f) {
    if (!object_masks[f].SameShape(object_masks[0])) {
      throw std::invalid_argument(
          fmt::format("ResidualAnalyser: object mask {} differs in shape from mask 0", f));
    }
  }
  if (facts.obstacle_names.empty()) {
    for (int o = 0; o < scene.num_obstacles; ++o) {
      facts.obstacle_names.push_back(fmt::format("obstacle_{}", o));
    }
  }
  if (static_cast<int>(facts.obstacle_names.size()) != scene.num_obstacles) {
    throw std::invalid_argument(fmt::format("ResidualAnalyser: {} obstacle names for {} obstacles",
                                            facts.obstacle_names.size(), scene.num_obstacles));
  }
  if (mesh.NumNodes() < 3 || mesh.NumTriangles() < 1) {
    throw std::invalid_argument("ResidualAnalyser: the rest mesh has no triangle");
  }
  const double fps = 1.0 / scene.frame_time_s;

  // Rest shape: area, centroid, perimeter; its pixels (for areas and the
  // radius of gyration).
  Vec2 weighted = Vec2::Zero();
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto& tri = mesh.triangles[t];
    const double a = mesh.rest_area_px2[t];
    facts.rest_area_px += a;
    weighted += a * (mesh.rest_positions[tri[0]] + mesh.rest_positions[tri[1]] +
                     mesh.rest_positions[tri[2]]) / 3.0;
  }
  const Vec2 rest_centroid = weighted / facts.rest_area_px;
  facts.rest_centroid_px = rest_centroid;
  for (const auto& loop : mesh.boundary_loops) {
    for (size_t i = 0; i < loop.size(); ++i) {
      facts.rest_perimeter_px +=
          (mesh.rest_positions[loop[(i + 1) % loop.size()]] - mesh.rest_positions[loop[i]]).norm();
    }
  }
  BitMask rest_mask(object_masks[0].width(), object_masks[0].height(),
                    object_masks[0].origin_x(), object_masks[0].origin_y());
  Rasterizer rasterizer;
  rasterizer.RasterizeTriangles(mesh, mesh.rest_positions, rest_mask);

  // Object masks: moments, change, deformation.
  std::vector<MaskMoments>& moments = facts.object_moments;
  moments.resize(n);
  facts.object_change_px.assign(n, 0);
  facts.object_deformation.assign(n, 0.0);
  for (int f = 0; f < n; ++f) moments[f] = ComputeMoments(object_masks[f]);
  const double area0 = std::max<double>(1.0, moments[0].area_px);
  for (int f = 0; f < n; ++f) {
    if (f > 0) facts.object_change_px[f] = CountXorShifted(object_masks[f], object_masks[f - 1], 0, 0);
    const Vec2 d = moments[f].centroid_px - moments[0].centroid_px;
    if (d.allFinite()) {
      facts.object_deformation[f] =
          CountXorShifted(object_masks[f], object_masks[0], static_cast<int>(std::lround(d.x())),
                          static_cast<int>(std::lround(d.y()))) /
          area0;
    }
  }

  // The pusher: the force obstacle, else the obstacle that travels most
  // (at least 1 px).
  std::vector<double>& force_n = facts.force_n;
  int& pusher = facts.pusher;
  force_n.assign(n, 0.0);
  if (scene.force_obstacle >= 0 && static_cast<int>(scene.forces.size()) == n) {
    for (int f = 0; f < n; ++f) force_n[f] = scene.forces[f].norm();
    pusher = scene.force_obstacle;
  } else {
    double best = 1.0;
    for (int o = 0; o < scene.num_obstacles; ++o) {
      double path = 0.0;
      for (int f = 1; f < n; ++f) {
        path += (scene.ObstaclesAt(f)[o].centre - scene.ObstaclesAt(f - 1)[o].centre).norm();
      }
      if (path > best) {
        best = path;
        pusher = o;
      }
    }
  }
  LoadTrack track;
  track.num_frames = n;
  track.fps = fps;
  if (scene.force_obstacle >= 0) track.force_n = force_n;
  if (pusher >= 0) {
    track.pusher_centre.resize(n);
    track.contact.resize(n);
    for (int f = 0; f < n; ++f) {
      const Disc& d = scene.ObstaclesAt(f)[pusher];
      track.pusher_centre[f] = d.centre;
      track.contact[f] =
          Touches(object_masks[f], d.centre, d.radius_px + options.contact_margin_px);
    }
    track.object_centre.resize(n);
    for (int f = 0; f < n; ++f) {
      track.object_centre[f] = moments[f].centroid_px.allFinite()
                                   ? moments[f].centroid_px
                                   : rest_centroid;
    }
  }
  facts.phases = DetectLoadPhases(track, options.phases);
  const std::vector<LoadPhase>& phases = facts.phases;

  // The push: peak, axis, contact site, eccentricity.
  PushSummary& push = facts.push;
  push = PushSummary();
  push.has_push = std::any_of(phases.begin(), phases.end(), IsLoaded) && pusher >= 0;
  if (push.has_push) {
    int peak = -1;
    double best = -std::numeric_limits<double>::infinity();
    for (int f = 0; f < n; ++f) {
      if (!IsLoaded(phases[f])) continue;
      const double score =
          scene.force_obstacle >= 0
              ? force_n[f]
              : -(track.pusher_centre[f] - track.object_centre[f]).norm();
      if (score > best) {
        best = score;
        peak = f;
      }
    }
    push.peak_frame = peak;
    push.peak_force_n = force_n[peak];
    const Vec2 pusher_centre = scene.ObstaclesAt(peak)[pusher].centre;
    const Vec2 axis = rest_centroid - pusher_centre;
    push.push_axis = axis.norm() > 1e-9 ? Vec2(axis / axis.norm()) : Vec2(0.0, 1.0);
    // Contact site: the rest boundary point nearest the pusher at the peak.
    double best_d2 = std::numeric_limits<double>::infinity();
    for (const auto& loop : mesh.boundary_loops) {
      for (size_t i = 0; i < loop.size(); ++i) {
        const Vec2& a = mesh.rest_positions[loop[i]];
        const Vec2& b = mesh.rest_positions[loop[(i + 1) % loop.size()]];
        double d2 = 0.0;
        const double t = ProjectOnSegment(pusher_centre, a, b, &d2);
        if (d2 < best_d2) {
          best_d2 = d2;
          push.contact_site_px = a + t * (b - a);
        }
      }
    }
    // Push distance so far, per frame (pusher travel into the object while
    // loaded).
    double pushed = 0.0;
    for (int f = 1; f < n; ++f) {
      if (IsLoaded(phases[f])) {
        pushed += std::max(0.0, (track.pusher_centre[f] - track.pusher_centre[f - 1])
                                    .dot(push.push_axis));
      }
    }
    push.push_distance_px = pushed;
  }
  const Vec2 a = push.push_axis;
  const Vec2 side_axis(-a.y(), a.x());
  const Vec2 side_origin = push.has_push ? push.contact_site_px : rest_centroid;
  facts.side_axis = side_axis;
  facts.side_origin_px = side_origin;
  double half_extent = 0.0;
  for (const Vec2& p : mesh.rest_positions) {
    half_extent = std::max(half_extent, std::abs((p - rest_centroid).dot(side_axis)));
  }
  if (push.has_push && half_extent > 0.0) {
    push.load_eccentricity = std::abs((side_origin - rest_centroid).dot(side_axis)) / half_extent;
  }

  // Heat map grid over the rest shape's bounding box.
  Vec2 lo = mesh.rest_positions[0], hi = lo;
  for (const Vec2& p : mesh.rest_positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Vec2 size = (hi - lo).cwiseMax(Vec2(1.0, 1.0));
  RestHeatMap& heat_map = facts.heat_map;
  heat_map = RestHeatMap();
  heat_map.origin_px = lo;
  heat_map.cell_px = std::sqrt(size.x() * size.y() / options.heat_map_cells);
  heat_map.cols = std::max(1, static_cast<int>(std::ceil(size.x() / heat_map.cell_px)));
  heat_map.rows = std::max(1, static_cast<int>(std::ceil(size.y() / heat_map.cell_px)));
  const size_t cells = static_cast<size_t>(heat_map.cols) * heat_map.rows;
  for (auto* v : {&heat_map.area_px, &heat_map.missed, &heat_map.extra,
                  &heat_map.loaded_missed, &heat_map.loaded_extra, &heat_map.released_missed,
                  &heat_map.released_extra}) {
    v->assign(cells, 0.0);
  }

  // Radius of gyration, then areas of cells and regions, from the rest
  // pixels. The contact zone scales with the object (a quarter of the
  // radius of gyration) and the pusher (1.5 radii) but is never smaller
  // than contact_radius_px.
  double gyration2 = 0.0, count = 0.0;
  for (int y = 0; y < rest_mask.height(); ++y) {
    for (int x = 0; x < rest_mask.width(); ++x) {
      if (!rest_mask.Get(x, y)) continue;
      const Vec2 p(rest_mask.origin_x() + x + 0.5, rest_mask.origin_y() + y + 0.5);
      gyration2 += (p - rest_centroid).squaredNorm();
      count += 1.0;
    }
  }
  facts.rest_radius_of_gyration_px = count > 0 ? std::sqrt(gyration2 / count) : 0.0;
  push.contact_zone_radius_px =
      std::max(options.contact_radius_px, 0.25 * facts.rest_radius_of_gyration_px);
  if (push.has_push) {
    // A dent is about as wide as the pusher.
    push.contact_zone_radius_px = std::max(
        push.contact_zone_radius_px, 1.5 * scene.ObstaclesAt(push.peak_frame)[pusher].radius_px);
  }
  RegionSummary& regions = facts.regions;
  regions = RegionSummary();
  for (int y = 0; y < rest_mask.height(); ++y) {
    for (int x = 0; x < rest_mask.width(); ++x) {
      if (!rest_mask.Get(x, y)) continue;
      const Vec2 p(rest_mask.origin_x() + x + 0.5, rest_mask.origin_y() + y + 0.5);
      const int cx = std::clamp(static_cast<int>((p.x() - lo.x()) / heat_map.cell_px), 0,
                                heat_map.cols - 1);
      const int cy = std::clamp(static_cast<int>((p.y() - lo.y()) / heat_map.cell_px), 0,
                                heat_map.rows - 1);
      heat_map.area_px[static_cast<size_t>(cy) * heat_map.cols + cx] += 1.0;
      const Vec2 d = p - rest_centroid;
      const bool near = d.dot(a) < 0.0;
      regions.area_px[static_cast<int>(near ? RestRegion::kNear : RestRegion::kFar)] += 1;
      const bool neg = (p - side_origin).dot(side_axis) < 0.0;
      regions.area_px[static_cast<int>(neg ? RestRegion::kSideNeg : RestRegion::kSidePos)] += 1;
      regions.area_px[static_cast<int>(d.x() < 0 ? RestRegion::kLeft : RestRegion::kRight)] += 1;
      regions.area_px[static_cast<int>(d.y() < 0 ? RestRegion::kTop : RestRegion::kBottom)] += 1;
      if (push.has_push && (p - push.contact_site_px).norm() < push.contact_zone_radius_px) {
        regions.area_px[static_cast<int>(RestRegion::kContact)] += 1;
      }
      regions.area_px[static_cast<int>(RestRegion::kAll)] += 1;
    }
  }
  return facts;
}

namespace {

std::shared_ptr<const RecordingResidualFacts> CheckedFacts(
    std::shared_ptr<const RecordingResidualFacts> facts) {
  if (facts == nullptr || facts->rest_mesh == nullptr || facts->scene == nullptr ||
      facts->object_masks == nullptr) {
    throw std::invalid_argument(
        "ResidualAnalyser: no facts (null, or without rest mesh, scene or object masks)");
  }
  return facts;
}

}  // namespace

ResidualAnalyser::ResidualAnalyser(const PreparedRecording& prepared,
                                   const ResidualOptions& options)
    : ResidualAnalyser(
          std::make_shared<const RecordingResidualFacts>(ComputeResidualFacts(prepared, options))) {}

ResidualAnalyser::ResidualAnalyser(const Mesh& rest_mesh, const Scene& scene,
                                   const std::vector<BitMask>& object_masks,
                                   std::vector<std::string> obstacle_names,
                                   std::string recording_name, const ResidualOptions& options)
    : ResidualAnalyser(std::make_shared<const RecordingResidualFacts>(
          ComputeResidualFacts(rest_mesh, scene, object_masks, std::move(obstacle_names),
                               std::move(recording_name), options))) {}

ResidualAnalyser::ResidualAnalyser(std::shared_ptr<const RecordingResidualFacts> facts)
    : facts_(CheckedFacts(std::move(facts))),
      mesh_(*facts_->rest_mesh),
      scene_(*facts_->scene),
      object_masks_(*facts_->object_masks),
      options_(facts_->options),
      heat_map_(facts_->heat_map),
      regions_(facts_->regions) {
  frames_.reserve(scene_.num_frames);
  claimed_ = BitMask(object_masks_[0].width(), object_masks_[0].height(),
                     object_masks_[0].origin_x(), object_masks_[0].origin_y());
  previous_mesh_ = claimed_;
  moved_mask_ = claimed_;
}

Vec2 ResidualAnalyser::NearestBoundaryRestPoint(std::span<const Vec2> positions,
                                                const Vec2& p) const {
  double best = std::numeric_limits<double>::infinity();
  Vec2 rest = facts_->rest_centroid_px;
  for (const auto& loop : mesh_.boundary_loops) {
    const size_t m = loop.size();
    for (size_t i = 0; i < m; ++i) {
      const int ia = loop[i], ib = loop[(i + 1) % m];
      double d2 = 0.0;
      const double t = ProjectOnSegment(p, positions[ia], positions[ib], &d2);
      if (d2 < best) {
        best = d2;
        rest = (1.0 - t) * mesh_.rest_positions[ia] + t * mesh_.rest_positions[ib];
      }
    }
  }
  return rest;
}

void ResidualAnalyser::AccumulateRestPixel(const Vec2& rest, bool missed, LoadPhase phase) {
  const int cx = std::clamp(
      static_cast<int>(std::floor((rest.x() - heat_map_.origin_px.x()) / heat_map_.cell_px)), 0,
      heat_map_.cols - 1);
  const int cy = std::clamp(
      static_cast<int>(std::floor((rest.y() - heat_map_.origin_px.y()) / heat_map_.cell_px)), 0,
      heat_map_.rows - 1);
  const size_t cell = static_cast<size_t>(cy) * heat_map_.cols + cx;
  const bool loaded = IsLoaded(phase);
  const bool released = phase == LoadPhase::kReleased;
  (missed ? heat_map_.missed : heat_map_.extra)[cell] += 1.0;
  if (loaded) (missed ? heat_map_.loaded_missed : heat_map_.loaded_extra)[cell] += 1.0;
  if (released) (missed ? heat_map_.released_missed : heat_map_.released_extra)[cell] += 1.0;

  const RecordingResidualFacts& facts = *facts_;
  const PushSummary& push = facts.push;
  const Vec2 d = rest - facts.rest_centroid_px;
  std::array<RestRegion, 5> in = {
      d.dot(push.push_axis) < 0.0 ? RestRegion::kNear : RestRegion::kFar,
      (rest - facts.side_origin_px).dot(facts.side_axis) < 0.0 ? RestRegion::kSideNeg : RestRegion::kSidePos,
      d.x() < 0 ? RestRegion::kLeft : RestRegion::kRight,
      d.y() < 0 ? RestRegion::kTop : RestRegion::kBottom, RestRegion::kAll};
  const bool contact = push.has_push &&
                       (rest - push.contact_site_px).norm() < push.contact_zone_radius_px;
  for (int g = 0; g < 3; ++g) {
    if ((g == 1 && !loaded) || (g == 2 && !released)) continue;
    auto& counts = regions_.counts[g];
    for (RestRegion r : in) (missed ? counts[static_cast<int>(r)].missed : counts[static_cast<int>(r)].extra) += 1;
    if (contact) {
      auto& c = counts[static_cast<int>(RestRegion::kContact)];
      (missed ? c.missed : c.extra) += 1;
    }
  }
  if (!push.has_push || loaded) {
    dipole_sum_ += (missed ? 1.0 : -1.0) * d;
    dipole_weight_ += 1.0;
  }
}

void ResidualAnalyser::MapResidualToRest(std::span<const Vec2> positions, const BitMask& mesh_mask,
                                         int frame) {
  const BitMask& object = object_masks_[frame];
  ResidualFrame& record = frames_.back();
  const LoadPhase phase = facts_->phases[frame];
  const int num_bands = static_cast<int>(options_.obstacle_bands_px.size());
  const Disc* discs = scene_.ObstaclesAt(frame);
  const int ox = object.origin_x(), oy = object.origin_y();
  const int words = object.words_per_row();

  // Distance bands of one residual pixel centre.
  auto count_bands = [&](const Vec2& p, bool missed) {
    bool near_any = false;
    for (int o = 0; o < scene_.num_obstacles; ++o) {
      const double d = (p - discs[o].centre).norm() - discs[o].radius_px;
      const auto it = std::lower_bound(options_.obstacle_bands_px.begin(),
                                       options_.obstacle_bands_px.end(), d);
      if (it == options_.obstacle_bands_px.end()) continue;
      near_any = true;
      const size_t index = static_cast<size_t>(o) * num_bands + (it - options_.obstacle_bands_px.begin());
      (missed ? record.band_missed_px : record.band_extra_px)[index] += 1;
    }
    if (!near_any) (missed ? record.far_missed_px : record.far_extra_px) += 1;
  };

  // Extra pixels inside a simulated triangle: barycentric map to the rest.
  claimed_.Clear();
  for (const auto& tri : mesh_.triangles) {
    const Vec2& a = positions[tri[0]];
    const Vec2& b = positions[tri[1]];
    const Vec2& c = positions[tri[2]];
    const double area = Cross(b - a, c - a);
    if (!(std::abs(area) > 1e-12)) continue;
    const Vec2 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
    const int x0 = std::max(0, static_cast<int>(std::ceil(lo.x() - ox - 0.5)));
    const int x1 = std::min(object.width() - 1, static_cast<int>(std::floor(hi.x() - ox - 0.5)));
    const int y0 = std::max(0, static_cast<int>(std::ceil(lo.y() - oy - 0.5)));
    const int y1 = std::min(object.height() - 1, static_cast<int>(std::floor(hi.y() - oy - 0.5)));
    for (int y = y0; y <= y1; ++y) {
      const uint64_t* ro = object.Row(y);
      const uint64_t* rm = mesh_mask.Row(y);
      uint64_t* rc = claimed_.Row(y);
      for (int x = x0; x <= x1; ++x) {
        const int w = x >> 6;
        const uint64_t bit = uint64_t{1} << (x & 63);
        if (!(rm[w] & ~ro[w] & ~rc[w] & bit)) {
          // Skip the rest of an empty word quickly.
          if ((rm[w] & ~ro[w] & ~rc[w]) == 0) x = std::min(x1, (w << 6) + 63);
          continue;
        }
        const Vec2 p(ox + x + 0.5, oy + y + 0.5);
        const double l0 = Cross(b - p, c - p) / area;
        const double l1 = Cross(c - p, a - p) / area;
        const double l2 = 1.0 - l0 - l1;
        if (l0 < -1e-9 || l1 < -1e-9 || l2 < -1e-9) continue;
        rc[w] |= bit;
        const Vec2 rest = l0 * mesh_.rest_positions[tri[0]] + l1 * mesh_.rest_positions[tri[1]] +
                          l2 * mesh_.rest_positions[tri[2]];
        count_bands(p, false);
        AccumulateRestPixel(rest, false, phase);
      }
    }
  }

  // Missed pixels, and extra pixels no triangle claimed (folded parts):
  // nearest point of the simulated boundary.
  for (int y = 0; y < object.height(); ++y) {
    const uint64_t* ro = object.Row(y);
    const uint64_t* rm = mesh_mask.Row(y);
    const uint64_t* rc = claimed_.Row(y);
    for (int w = 0; w < words; ++w) {
      for (int kind = 0; kind < 2; ++kind) {
        const bool missed = kind == 0;
        uint64_t bits = missed ? (ro[w] & ~rm[w]) : (rm[w] & ~ro[w] & ~rc[w]);
        while (bits != 0) {
          const int b = std::countr_zero(bits);
          bits &= bits - 1;
          const Vec2 p(ox + w * 64 + b + 0.5, oy + y + 0.5);
          count_bands(p, missed);
          AccumulateRestPixel(NearestBoundaryRestPoint(positions, p), missed, phase);
        }
      }
    }
  }
}

std::pair<int64_t, double> ResidualAnalyser::RigidXor(std::span<const Vec2> positions,
                                                      const BitMask& object, const Vec2& mesh_centroid,
                                                      const Vec2& object_centroid) {
  moved_.resize(positions.size());
  const auto xor_at = [&](double turn_rad) {
    const double c = std::cos(turn_rad), s = std::sin(turn_rad);
    for (size_t i = 0; i < positions.size(); ++i) {
      const Vec2 d = positions[i] - mesh_centroid;
      moved_[i] = object_centroid + Vec2(c * d.x() - s * d.y(), s * d.x() + c * d.y());
    }
    rasterizer_.RasterizeMesh(mesh_, moved_.data(), moved_mask_);
    return CountXorShifted(object, moved_mask_, 0, 0);
  };
  const double degree = std::numbers::pi / 180.0;
  int64_t best = xor_at(0.0);
  double best_turn = 0.0;
  const auto consider = [&](double turn_rad) {
    const int64_t x = xor_at(turn_rad);
    // Ties go to the smaller turn: no turn unless one helps.
    if (x < best || (x == best && std::abs(turn_rad) < std::abs(best_turn))) {
      best = x;
      best_turn = turn_rad;
    }
  };
  const int coarse = static_cast<int>(std::lround(kRigidTurnSearchDeg / 2.0));
  for (int k = -coarse; k <= coarse; ++k) {
    if (k != 0) consider(2.0 * k * degree);
  }
  const double centre = best_turn;
  for (const double d : {-1.5, -1.0, -0.5, 0.5, 1.0, 1.5}) consider(centre + d * degree);
  return {best, best_turn};
}

void ResidualAnalyser::AddFrame(int frame, std::span<const Vec2> positions,
                                const BitMask& mesh_mask) {
  if (frame != static_cast<int>(frames_.size()) || frame >= scene_.num_frames) {
    throw std::invalid_argument(fmt::format(
        "ResidualAnalyser::AddFrame: frame {} out of order (expected {} of {})", frame,
        frames_.size(), scene_.num_frames));
  }
  if (static_cast<int>(positions.size()) != mesh_.NumNodes() ||
      !mesh_mask.SameShape(object_masks_[0])) {
    throw std::invalid_argument(fmt::format(
        "ResidualAnalyser::AddFrame: {} positions for {} nodes, or a mesh mask of another shape",
        positions.size(), mesh_.NumNodes()));
  }
  const BitMask& object = object_masks_[frame];
  // Two bit masks (the mesh's pixels covered at least half): whole pixels.
  const FrameScore score = CompareMasks(object, mesh_mask);
  const auto px = [](double area) { return static_cast<int64_t>(area); };
  ResidualFrame r;
  r.frame = frame;
  r.time_s = frame * scene_.frame_time_s;
  r.phase = facts_->phases[frame];
  r.missed_px = px(score.missed_px);
  r.extra_px = px(score.extra_px);
  r.object_px = px(score.object_px);
  r.mesh_px = px(score.mesh_px);
  r.iou = score.iou;
  const MaskMoments& om = facts_->object_moments[frame];
  const MaskMoments mm = ComputeMoments(mesh_mask);
  r.object_centroid_px = om.centroid_px;
  r.mesh_centroid_px = mm.centroid_px;
  r.offset_px = mm.centroid_px - om.centroid_px;
  r.object_angle_rad = om.angle_rad;
  r.mesh_angle_rad = mm.angle_rad;
  r.angle_diff_rad = std::isfinite(om.angle_rad) && std::isfinite(mm.angle_rad)
                         ? AxisAngleDifference(mm.angle_rad, om.angle_rad)
                         : NAN;
  if (r.offset_px.allFinite()) {
    // Shift the mesh back onto the object; then lay it on rigidly.
    r.aligned_xor_px = CountXorShifted(object, mesh_mask, -static_cast<int>(std::lround(r.offset_px.x())),
                                       -static_cast<int>(std::lround(r.offset_px.y())));
    std::tie(r.rigid_xor_px, r.rigid_turn_rad) =
        RigidXor(positions, object, mm.centroid_px, om.centroid_px);
  } else {
    r.aligned_xor_px = px(score.xor_px);
    r.rigid_xor_px = r.aligned_xor_px;
  }
  r.force_n = facts_->force_n[frame];
  r.object_deformation = facts_->object_deformation[frame];
  double strain_sum = 0.0;
  for (int e = 0; e < mesh_.NumEdges(); ++e) {
    const auto& edge = mesh_.edges[e];
    const double l = (positions[edge[1]] - positions[edge[0]]).norm();
    const double s = std::abs(l / mesh_.rest_length_px[e] - 1.0);
    strain_sum += s;
    r.mesh_max_strain = std::max(r.mesh_max_strain, s);
  }
  r.mesh_mean_strain = mesh_.NumEdges() > 0 ? strain_sum / mesh_.NumEdges() : 0.0;
  r.object_change_px = facts_->object_change_px[frame];
  r.mesh_change_px = frame > 0 ? CountXorShifted(mesh_mask, previous_mesh_, 0, 0) : 0;
  previous_mesh_ = mesh_mask;
  const size_t bands = static_cast<size_t>(scene_.num_obstacles) * options_.obstacle_bands_px.size();
  r.band_missed_px.assign(bands, 0);
  r.band_extra_px.assign(bands, 0);
  frames_.push_back(std::move(r));
  MapResidualToRest(positions, mesh_mask, frame);
}

ResidualAnalysis AnalyseResidual(const PreparedRecording& prepared,
                                 const SimulationOptions& simulation, const ModelParameters& params,
                                 const ResidualOptions& options, EvaluationResult* result) {
  ResidualAnalyser analyser(prepared, options);
  Evaluator evaluator(prepared, simulation);
  EvaluationResult evaluation = evaluator.Evaluate(params, analyser);
  if (result != nullptr) *result = std::move(evaluation);
  return analyser.Finish();
}

ResidualAnalysis AnalyseResidual(const PreparedRecording& prepared,
                                 const SimulationOptions& simulation, const ModelDefinition& model,
                                 const ParameterValues& values, const ResidualOptions& options,
                                 EvaluationResult* result) {
  ResidualAnalyser analyser(prepared, options);
  Evaluator evaluator(prepared, simulation, model);
  EvaluationResult evaluation = evaluator.Evaluate(values, analyser);
  if (result != nullptr) *result = std::move(evaluation);
  return analyser.Finish();
}

}  // namespace calib
