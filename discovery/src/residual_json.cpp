// JSON of a ResidualAnalysis. Each struct lists its fields once (Visit);
// the same list writes and reads, so the two cannot drift apart.

#include "calib/discovery/residual.h"

#include "calib/evaluator/json_number.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <stdexcept>
#include <type_traits>

namespace calib {
namespace {

using nlohmann::json;

// ---- field lists (S is the struct, const or not) --------------------------

template <class S, class F>
void VisitOscillation(S& o, F& f) {
  f("found", o.found);
  f("period_frames", o.period_frames);
  f("period_s", o.period_s);
  f("strength", o.strength);
  f("amplitude", o.amplitude);
  f("decay_per_s", o.decay_per_s);
  f("cycles", o.cycles);
}

template <class S, class F>
void VisitFit(S& o, F& f) {
  f("ok", o.ok);
  f("floor", o.floor);
  f("amplitude", o.amplitude);
  f("tau_s", o.tau_s);
  f("r2", o.r2);
}

template <class S, class F>
void VisitFrame(S& r, F& f) {
  f("frame", r.frame);
  f("time_s", r.time_s);
  f("phase", r.phase);
  f("missed_px", r.missed_px);
  f("extra_px", r.extra_px);
  f("object_px", r.object_px);
  f("mesh_px", r.mesh_px);
  f("iou", r.iou);
  f("aligned_xor_px", r.aligned_xor_px);
  f("rigid_xor_px", r.rigid_xor_px);
  f("rigid_turn_rad", r.rigid_turn_rad);
  f("object_centroid_px", r.object_centroid_px);
  f("mesh_centroid_px", r.mesh_centroid_px);
  f("offset_px", r.offset_px);
  f("object_angle_rad", r.object_angle_rad);
  f("mesh_angle_rad", r.mesh_angle_rad);
  f("angle_diff_rad", r.angle_diff_rad);
  f("force_n", r.force_n);
  f("object_deformation", r.object_deformation);
  f("mesh_mean_strain", r.mesh_mean_strain);
  f("mesh_max_strain", r.mesh_max_strain);
  f("object_change_px", r.object_change_px);
  f("mesh_change_px", r.mesh_change_px);
  f("band_missed_px", r.band_missed_px);
  f("band_extra_px", r.band_extra_px);
  f("far_missed_px", r.far_missed_px);
  f("far_extra_px", r.far_extra_px);
}

template <class S, class F>
void VisitHeatMap(S& h, F& f) {
  f("origin_px", h.origin_px);
  f("cell_px", h.cell_px);
  f("cols", h.cols);
  f("rows", h.rows);
  f("area_px", h.area_px);
  f("missed", h.missed);
  f("extra", h.extra);
  f("loaded_missed", h.loaded_missed);
  f("loaded_extra", h.loaded_extra);
  f("released_missed", h.released_missed);
  f("released_extra", h.released_extra);
}

template <class S, class F>
void VisitPhase(S& p, F& f) {
  f("phase", p.phase);
  f("num_frames", p.num_frames);
  f("first_frame", p.first_frame);
  f("last_frame", p.last_frame);
  f("mean_xor_px", p.mean_xor_px);
  f("mean_missed_px", p.mean_missed_px);
  f("mean_extra_px", p.mean_extra_px);
  f("mean_aligned_xor_px", p.mean_aligned_xor_px);
  f("mean_iou", p.mean_iou);
  f("mean_offset_px", p.mean_offset_px);
  f("xor_slope_px_per_s", p.xor_slope_px_per_s);
  f("offset_slope_px_per_s", p.offset_slope_px_per_s);
  f("mean_object_change_px", p.mean_object_change_px);
  f("mean_mesh_change_px", p.mean_mesh_change_px);
  f("mean_force_n", p.mean_force_n);
  f("object_travel_px", p.object_travel_px);
  f("mesh_travel_px", p.mesh_travel_px);
}

template <class S, class F>
void VisitMotion(S& m, F& f) {
  f("mean_offset_px", m.mean_offset_px);
  f("mean_abs_offset_px", m.mean_abs_offset_px);
  f("max_abs_offset_px", m.max_abs_offset_px);
  f("offset_consistency", m.offset_consistency);
  f("offset_slope_px_per_s", m.offset_slope_px_per_s);
  f("mean_angle_diff_rad", m.mean_angle_diff_rad);
  f("max_abs_angle_diff_rad", m.max_abs_angle_diff_rad);
  f("mean_anisotropy", m.mean_anisotropy);
  f("motion_axis", m.motion_axis);
  f("object_motion_rms_px", m.object_motion_rms_px);
  f("mesh_motion_rms_px", m.mesh_motion_rms_px);
  f("lag_frames", m.lag_frames);
  f("lag_s", m.lag_s);
  f("lag_correlation", m.lag_correlation);
  f("lag_correlation0", m.lag_correlation0);
  f("object_displacement_px", m.object_displacement_px);
  f("mesh_displacement_px", m.mesh_displacement_px);
  f("object_path_px", m.object_path_px);
  f("mesh_path_px", m.mesh_path_px);
  f("mean_offset_down_px", m.mean_offset_down_px);
}

template <class S, class F>
void VisitOscillations(S& o, F& f) {
  f("offset", o.offset);
  f("object_motion", o.object_motion);
  f("mesh_motion", o.mesh_motion);
  f("xor_px", o.xor_px);
  f("angle_diff", o.angle_diff);
}

template <class S, class F>
void VisitPersistence(S& p, F& f) {
  f("released", p.released);
  f("release_frame", p.release_frame);
  f("released_frames", p.released_frames);
  f("before_xor_px", p.before_xor_px);
  f("loaded_xor_px", p.loaded_xor_px);
  f("peak_loaded_xor_px", p.peak_loaded_xor_px);
  f("released_xor_px", p.released_xor_px);
  f("released_early_xor_px", p.released_early_xor_px);
  f("released_late_xor_px", p.released_late_xor_px);
  f("persistent_ratio", p.persistent_ratio);
  f("before_rigid_xor_px", p.before_rigid_xor_px);
  f("loaded_rigid_xor_px", p.loaded_rigid_xor_px);
  f("released_late_rigid_xor_px", p.released_late_rigid_xor_px);
  f("shape_persistent_ratio", p.shape_persistent_ratio);
  f("fading_ratio", p.fading_ratio);
  f("contact_fraction", p.contact_fraction);
  f("contact_concentration", p.contact_concentration);
  f("recovery", p.recovery);
  f("object_settle_s", p.object_settle_s);
  f("mesh_settle_s", p.mesh_settle_s);
  f("object_change_floor_px", p.object_change_floor_px);
}

template <class S, class F>
void VisitPush(S& p, F& f) {
  f("has_push", p.has_push);
  f("peak_frame", p.peak_frame);
  f("peak_force_n", p.peak_force_n);
  f("push_axis", p.push_axis);
  f("contact_site_px", p.contact_site_px);
  f("contact_zone_radius_px", p.contact_zone_radius_px);
  f("push_distance_px", p.push_distance_px);
  f("offset_push_correlation", p.offset_push_correlation);
  f("offset_per_push", p.offset_per_push);
  f("mean_offset_along_push_px", p.mean_offset_along_push_px);
  f("mesh_travel_after_stop_px", p.mesh_travel_after_stop_px);
  f("object_travel_after_stop_px", p.object_travel_after_stop_px);
  f("stopped_frames", p.stopped_frames);
  f("hold_force_change", p.hold_force_change);
  f("load_eccentricity", p.load_eccentricity);
  f("force_travel_exponent", p.force_travel_exponent);
  f("force_travel_frames", p.force_travel_frames);
  f("force_travel_correlation", p.force_travel_correlation);
}

template <class S, class F>
void VisitStrain(S& s, F& f) {
  f("num_frames", s.num_frames);
  f("deformation", s.deformation);
  f("xor_px", s.xor_px);
  f("signed_share", s.signed_share);
  f("correlation", s.correlation);
  f("convexity", s.convexity);
  f("exponent", s.exponent);
}

template <class S, class F>
void VisitRegionCounts(S& c, F& f) {
  f("missed", c.missed);
  f("extra", c.extra);
}

template <class S, class F>
void VisitAnalysis(S& a, F& f) {
  f("recording", a.recording);
  f("fps", a.fps);
  f("num_frames", a.num_frames);
  f("frames_analysed", a.frames_analysed);
  f("obstacle_names", a.obstacle_names);
  f("obstacle_bands_px", a.obstacle_bands_px);
  f("rest_centroid_px", a.rest_centroid_px);
  f("rest_area_px", a.rest_area_px);
  f("rest_perimeter_px", a.rest_perimeter_px);
  f("rest_radius_of_gyration_px", a.rest_radius_of_gyration_px);
  f("xor_sum", a.xor_sum);
  f("mean_xor_px", a.mean_xor_px);
  f("mean_iou", a.mean_iou);
  f("mean_aligned_xor_px", a.mean_aligned_xor_px);
  f("residual_thickness_px", a.residual_thickness_px);
  f("p90_thickness_px", a.p90_thickness_px);
  f("worst_frames", a.worst_frames);
  f("phases", a.phases);
  f("band_missed_px", a.band_missed_px);
  f("band_extra_px", a.band_extra_px);
  f("far_missed_px", a.far_missed_px);
  f("far_extra_px", a.far_extra_px);
  f("heat_map", a.heat_map);
  f("regions", a.regions);
  f("motion", a.motion);
  f("oscillation", a.oscillation);
  f("persistence", a.persistence);
  f("push", a.push);
  f("strain", a.strain);
}

// ---- encoding -------------------------------------------------------------

json Encode(double v) { return JsonNumber(v); }
json Encode(int v) { return v; }
json Encode(int64_t v) { return v; }
json Encode(bool v) { return v; }
json Encode(const std::string& v) { return v; }
json Encode(const Vec2& v) { return json::array({Encode(v.x()), Encode(v.y())}); }
json Encode(LoadPhase v) { return ToString(v); }
json Encode(const Oscillation& v);
json Encode(const ExponentialFit& v);
json Encode(const ResidualFrame& v);
json Encode(const RestHeatMap& v);
json Encode(const PhaseSummary& v);
json Encode(const MotionSummary& v);
json Encode(const OscillationSummary& v);
json Encode(const PersistenceSummary& v);
json Encode(const PushSummary& v);
json Encode(const StrainSummary& v);
json Encode(const RegionCounts& v);
json Encode(const RegionSummary& v);
template <class T>
json Encode(const std::vector<T>& v) {
  json a = json::array();
  for (const T& x : v) a.push_back(Encode(x));
  return a;
}
template <class T, size_t N>
json Encode(const std::array<T, N>& v) {
  json a = json::array();
  for (const T& x : v) a.push_back(Encode(x));
  return a;
}

struct Writer {
  json& out;
  template <class T>
  void operator()(const char* key, const T& value) {
    out[key] = Encode(value);
  }
};

template <class S, void (*V)(const S&, Writer&)>
json EncodeWith(const S& s) {
  json j = json::object();
  Writer w{j};
  V(s, w);
  return j;
}

json Encode(const Oscillation& v) { return EncodeWith<Oscillation, VisitOscillation<const Oscillation, Writer>>(v); }
json Encode(const ExponentialFit& v) { return EncodeWith<ExponentialFit, VisitFit<const ExponentialFit, Writer>>(v); }
json Encode(const ResidualFrame& v) { return EncodeWith<ResidualFrame, VisitFrame<const ResidualFrame, Writer>>(v); }
json Encode(const RestHeatMap& v) { return EncodeWith<RestHeatMap, VisitHeatMap<const RestHeatMap, Writer>>(v); }
json Encode(const PhaseSummary& v) { return EncodeWith<PhaseSummary, VisitPhase<const PhaseSummary, Writer>>(v); }
json Encode(const MotionSummary& v) { return EncodeWith<MotionSummary, VisitMotion<const MotionSummary, Writer>>(v); }
json Encode(const OscillationSummary& v) { return EncodeWith<OscillationSummary, VisitOscillations<const OscillationSummary, Writer>>(v); }
json Encode(const PersistenceSummary& v) { return EncodeWith<PersistenceSummary, VisitPersistence<const PersistenceSummary, Writer>>(v); }
json Encode(const PushSummary& v) { return EncodeWith<PushSummary, VisitPush<const PushSummary, Writer>>(v); }
json Encode(const StrainSummary& v) { return EncodeWith<StrainSummary, VisitStrain<const StrainSummary, Writer>>(v); }
json Encode(const RegionCounts& v) { return EncodeWith<RegionCounts, VisitRegionCounts<const RegionCounts, Writer>>(v); }

json Encode(const RegionSummary& v) {
  json j = json::object();
  const char* groups[3] = {"all", "loaded", "released"};
  json counts = json::object();
  for (int g = 0; g < 3; ++g) {
    json c = json::object();
    for (int r = 0; r < kNumRestRegions; ++r) c[ToString(static_cast<RestRegion>(r))] = Encode(v.counts[g][r]);
    counts[groups[g]] = c;
  }
  j["counts"] = counts;
  json area = json::object();
  for (int r = 0; r < kNumRestRegions; ++r) area[ToString(static_cast<RestRegion>(r))] = v.area_px[r];
  j["area_px"] = area;
  j["side_asymmetry"] = Encode(v.side_asymmetry);
  j["side_imbalance"] = Encode(v.side_imbalance);
  j["near_far_asymmetry"] = Encode(v.near_far_asymmetry);
  j["signed_dipole"] = Encode(v.signed_dipole);
  j["side_dipole"] = Encode(v.side_dipole);
  return j;
}

// ---- decoding -------------------------------------------------------------

[[noreturn]] void BadResidualKey(const std::string& key, const std::string& what) {
  throw std::invalid_argument(fmt::format("residual analysis JSON: key '{}': {}", key, what));
}

void Decode(const json& j, double& v, const std::string& key) {
  if (j.is_null()) {
    v = NAN;
  } else if (j.is_number()) {
    v = j.get<double>();
  } else {
    BadResidualKey(key, "expected a number or null");
  }
}
void Decode(const json& j, int& v, const std::string& key) {
  if (!j.is_number_integer()) BadResidualKey(key, "expected an integer");
  v = j.get<int>();
}
void Decode(const json& j, int64_t& v, const std::string& key) {
  if (!j.is_number_integer()) BadResidualKey(key, "expected an integer");
  v = j.get<int64_t>();
}
void Decode(const json& j, bool& v, const std::string& key) {
  if (!j.is_boolean()) BadResidualKey(key, "expected true or false");
  v = j.get<bool>();
}
void Decode(const json& j, std::string& v, const std::string& key) {
  if (!j.is_string()) BadResidualKey(key, "expected a string");
  v = j.get<std::string>();
}
void Decode(const json& j, Vec2& v, const std::string& key) {
  if (!j.is_array() || j.size() != 2) BadResidualKey(key, "expected [x, y]");
  Decode(j[0], v.x(), key);
  Decode(j[1], v.y(), key);
}
void Decode(const json& j, LoadPhase& v, const std::string& key) {
  if (!j.is_string()) BadResidualKey(key, "expected a phase name");
  try {
    v = LoadPhaseFromString(j.get<std::string>());
  } catch (const std::invalid_argument& e) {
    BadResidualKey(key, e.what());
  }
}
void Decode(const json& j, Oscillation& v, const std::string& key);
void Decode(const json& j, ExponentialFit& v, const std::string& key);
void Decode(const json& j, ResidualFrame& v, const std::string& key);
void Decode(const json& j, RestHeatMap& v, const std::string& key);
void Decode(const json& j, PhaseSummary& v, const std::string& key);
void Decode(const json& j, MotionSummary& v, const std::string& key);
void Decode(const json& j, OscillationSummary& v, const std::string& key);
void Decode(const json& j, PersistenceSummary& v, const std::string& key);
void Decode(const json& j, PushSummary& v, const std::string& key);
void Decode(const json& j, StrainSummary& v, const std::string& key);
void Decode(const json& j, RegionCounts& v, const std::string& key);
void Decode(const json& j, RegionSummary& v, const std::string& key);
template <class T>
void Decode(const json& j, std::vector<T>& v, const std::string& key) {
  if (!j.is_array()) BadResidualKey(key, "expected an array");
  v.resize(j.size());
  for (size_t i = 0; i < j.size(); ++i) Decode(j[i], v[i], fmt::format("{}[{}]", key, i));
}
template <class T, size_t N>
void Decode(const json& j, std::array<T, N>& v, const std::string& key) {
  if (!j.is_array() || j.size() != N) BadResidualKey(key, fmt::format("expected an array of {}", N));
  for (size_t i = 0; i < N; ++i) Decode(j[i], v[i], fmt::format("{}[{}]", key, i));
}

struct Reader {
  const json& in;
  const std::string& prefix;
  template <class T>
  void operator()(const char* key, T& value) {
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    if (!in.is_object() || !in.contains(key)) BadResidualKey(path, "missing");
    Decode(in.at(key), value, path);
  }
};

template <class S, void (*V)(S&, Reader&)>
void DecodeWith(const json& j, S& s, const std::string& key) {
  if (!j.is_object()) BadResidualKey(key, "expected an object");
  Reader r{j, key};
  V(s, r);
}

void Decode(const json& j, Oscillation& v, const std::string& k) { DecodeWith<Oscillation, VisitOscillation<Oscillation, Reader>>(j, v, k); }
void Decode(const json& j, ExponentialFit& v, const std::string& k) { DecodeWith<ExponentialFit, VisitFit<ExponentialFit, Reader>>(j, v, k); }
void Decode(const json& j, ResidualFrame& v, const std::string& k) { DecodeWith<ResidualFrame, VisitFrame<ResidualFrame, Reader>>(j, v, k); }
void Decode(const json& j, RestHeatMap& v, const std::string& k) { DecodeWith<RestHeatMap, VisitHeatMap<RestHeatMap, Reader>>(j, v, k); }
void Decode(const json& j, PhaseSummary& v, const std::string& k) { DecodeWith<PhaseSummary, VisitPhase<PhaseSummary, Reader>>(j, v, k); }
void Decode(const json& j, MotionSummary& v, const std::string& k) { DecodeWith<MotionSummary, VisitMotion<MotionSummary, Reader>>(j, v, k); }
void Decode(const json& j, OscillationSummary& v, const std::string& k) { DecodeWith<OscillationSummary, VisitOscillations<OscillationSummary, Reader>>(j, v, k); }
void Decode(const json& j, PersistenceSummary& v, const std::string& k) { DecodeWith<PersistenceSummary, VisitPersistence<PersistenceSummary, Reader>>(j, v, k); }
void Decode(const json& j, PushSummary& v, const std::string& k) { DecodeWith<PushSummary, VisitPush<PushSummary, Reader>>(j, v, k); }
void Decode(const json& j, StrainSummary& v, const std::string& k) { DecodeWith<StrainSummary, VisitStrain<StrainSummary, Reader>>(j, v, k); }
void Decode(const json& j, RegionCounts& v, const std::string& k) { DecodeWith<RegionCounts, VisitRegionCounts<RegionCounts, Reader>>(j, v, k); }

void Decode(const json& j, RegionSummary& v, const std::string& key) {
  if (!j.is_object()) BadResidualKey(key, "expected an object");
  const char* groups[3] = {"all", "loaded", "released"};
  for (int g = 0; g < 3; ++g) {
    for (int r = 0; r < kNumRestRegions; ++r) {
      const std::string name = ToString(static_cast<RestRegion>(r));
      const std::string path = fmt::format("{}.counts.{}.{}", key, groups[g], name);
      if (!j.contains("counts") || !j["counts"].contains(groups[g]) ||
          !j["counts"][groups[g]].contains(name)) {
        BadResidualKey(path, "missing");
      }
      Decode(j["counts"][groups[g]][name], v.counts[g][r], path);
    }
  }
  for (int r = 0; r < kNumRestRegions; ++r) {
    const std::string name = ToString(static_cast<RestRegion>(r));
    if (!j.contains("area_px") || !j["area_px"].contains(name)) BadResidualKey(key + ".area_px." + name, "missing");
    Decode(j["area_px"][name], v.area_px[r], key + ".area_px." + name);
  }
  Reader reader{j, key};
  reader("side_asymmetry", v.side_asymmetry);
  reader("side_imbalance", v.side_imbalance);
  reader("near_far_asymmetry", v.near_far_asymmetry);
  reader("signed_dipole", v.signed_dipole);
  reader("side_dipole", v.side_dipole);
}

}  // namespace

nlohmann::json ToJson(const ResidualAnalysis& analysis, bool include_frames) {
  json j = json::object();
  Writer w{j};
  VisitAnalysis(analysis, w);
  if (include_frames) j["frames"] = Encode(analysis.frames);
  return j;
}

ResidualAnalysis ResidualAnalysisFromJson(const nlohmann::json& doc) {
  ResidualAnalysis a;
  if (!doc.is_object()) BadResidualKey("(root)", "expected an object");
  const std::string root;
  Reader r{doc, root};
  VisitAnalysis(a, r);
  if (doc.contains("frames")) Decode(doc["frames"], a.frames, "frames");
  return a;
}

}  // namespace calib
