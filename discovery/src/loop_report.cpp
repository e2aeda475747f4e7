// report.json of the closed loop (loop_report.h).

#include "calib/discovery/loop_report.h"

#include "calib/core/enum_names.h"
#include "calib/evaluator/json_number.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numeric>
#include <sstream>
#include <stdexcept>

namespace calib {
namespace {

using nlohmann::json;

[[noreturn]] void BadReportKey(const std::string& key, const std::string& what) {
  throw std::invalid_argument(fmt::format("loop report JSON: key '{}': {}", key, what));
}

// Typed access that names the key path on failure.
class In {
 public:
  In(const json& j, std::string path) : j_(j), path_(std::move(path)) {
    if (!j_.is_object()) BadReportKey(path_, "expected an object");
  }
  const json& Raw(const char* key) const {
    if (!j_.contains(key)) BadReportKey(Path(key), "missing");
    return j_.at(key);
  }
  std::string Path(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }
  std::string Text(const char* key) const {
    const json& v = Raw(key);
    if (!v.is_string()) BadReportKey(Path(key), "expected a string");
    return v.get<std::string>();
  }
  double Num(const char* key) const {
    const json& v = Raw(key);
    if (v.is_null()) return NAN;
    if (!v.is_number()) BadReportKey(Path(key), "expected a number");
    return v.get<double>();
  }
  int64_t Int(const char* key) const {
    const json& v = Raw(key);
    if (!v.is_number_integer()) BadReportKey(Path(key), "expected an integer");
    return v.get<int64_t>();
  }
  bool Bool(const char* key) const {
    const json& v = Raw(key);
    if (!v.is_boolean()) BadReportKey(Path(key), "expected true or false");
    return v.get<bool>();
  }
  uint64_t UInt(const char* key) const {
    const json& v = Raw(key);
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0)) {
      BadReportKey(Path(key), "expected a non-negative integer");
    }
    return v.get<uint64_t>();
  }
  const json& Array(const char* key) const {
    const json& v = Raw(key);
    if (!v.is_array()) BadReportKey(Path(key), "expected an array");
    return v;
  }
  std::vector<std::string> Texts(const char* key) const {
    std::vector<std::string> out;
    for (const json& e : Array(key)) {
      if (!e.is_string()) BadReportKey(Path(key), "expected strings");
      out.push_back(e.get<std::string>());
    }
    return out;
  }

 private:
  const json& j_;
  std::string path_;
};

json Numbers(const std::vector<double>& values) {
  json out = json::array();
  for (double v : values) out.push_back(JsonNumber(v));
  return out;
}

// An optional array of numbers (null for NaN) at key `key` of `in`'s object.
std::vector<double> OptionalNumbers(const In& in, const json& j, const std::string& key) {
  std::vector<double> out;
  if (!j.contains(key)) return out;
  for (const json& v : in.Array(key.c_str())) {
    if (!v.is_number() && !v.is_null()) BadReportKey(in.Path(key), "expected numbers");
    out.push_back(v.is_null() ? NAN : v.get<double>());
  }
  return out;
}

json ToJson(const RecordingScore& e) {
  json j = {{"recording", e.recording}, {"status", e.status},   {"xor_sum", e.xor_sum},
            {"mean_iou", JsonNumber(e.mean_iou)}, {"frame_xor", e.frame_xor},
            {"frame_iou", Numbers(e.frame_iou)}};
  if (e.failure_frame >= 0) {
    j["failure_frame"] = e.failure_frame;
    j["failure_reason"] = e.failure_reason;
  }
  if (!e.tip_x_px.empty()) {
    j["tip_x_px"] = Numbers(e.tip_x_px);
    j["tip_y_px"] = Numbers(e.tip_y_px);
    j["median_tip_distance_px"] = JsonNumber(e.median_tip_distance_px);
  }
  return j;
}

RecordingScore ErrorFromJson(const json& j, const std::string& path) {
  const In in(j, path);
  RecordingScore e;
  e.recording = in.Text("recording");
  e.status = in.Text("status");
  e.xor_sum = in.Num("xor_sum");
  e.mean_iou = in.Num("mean_iou");
  for (const json& v : in.Array("frame_xor")) {
    if (!v.is_number()) BadReportKey(in.Path("frame_xor"), "expected numbers");
    e.frame_xor.push_back(v.get<double>());
  }
  for (const json& v : in.Array("frame_iou")) {
    e.frame_iou.push_back(v.is_null() ? NAN : v.get<double>());
  }
  if (j.contains("failure_frame")) {  // optional: failed simulations only
    e.failure_frame = static_cast<int>(in.Int("failure_frame"));
    e.failure_reason = in.Text("failure_reason");
  }
  // Optional: objects held by clamps only.
  e.tip_x_px = OptionalNumbers(in, j, "tip_x_px");
  e.tip_y_px = OptionalNumbers(in, j, "tip_y_px");
  if (e.tip_x_px.size() != e.tip_y_px.size()) BadReportKey(in.Path("tip_y_px"), "expected as many as tip_x_px");
  if (j.contains("median_tip_distance_px") && !j["median_tip_distance_px"].is_null()) {
    e.median_tip_distance_px = in.Num("median_tip_distance_px");
  }
  return e;
}

json ToJson(const ParameterValues& values) {
  json j = json::object();
  for (const auto& [name, v] : values) j[name] = JsonNumber(v);
  return j;
}

json ToJson(const ReportStage& s) {
  json errors = json::array();
  for (const RecordingScore& e : s.errors) errors.push_back(ToJson(e));
  json j = {{"name", s.name},
          {"effect_tried", s.effect_tried},
          {"decision", ToString(s.decision)},
          {"effects", s.effects},
          {"parameters", ToJson(s.parameters)},
          {"errors", errors},
          {"criterion", s.criterion},
          {"criterion_value", JsonNumber(s.criterion_value)},
          {"reason", s.reason},
          {"calibration_time_s", JsonNumber(s.calibration_time_s)},
          {"evaluations", s.evaluations}};
  if (s.equally_good.fits > 0) {
    const EquallyGoodFits& g = s.equally_good;
    j["equally_good"] = {{"fits", g.fits},
                         {"training_tolerance_px", JsonNumber(g.training_tolerance_px)},
                         {"holdout_xor_min", JsonNumber(g.holdout_xor_min)},
                         {"holdout_xor_max", JsonNumber(g.holdout_xor_max)},
                         {"holdout_xor_median", JsonNumber(g.holdout_xor_median)},
                         {"holdout_iou_at_min", JsonNumber(g.holdout_iou_at_min)}};
  }
  if (s.holdout_sensitivity_px > 0.0) {
    j["holdout_sensitivity_px"] = JsonNumber(s.holdout_sensitivity_px);
    j["holdout_sensitivity_parameter"] = s.holdout_sensitivity_parameter;
  }
  if (s.test.frames > 0) {
    const StageTest& t = s.test;
    j["test"] = {{"frames", t.frames},           {"blocks", t.blocks},
                 {"drop", JsonNumber(t.drop)},   {"drop_low", JsonNumber(t.drop_low)},
                 {"drop_high", JsonNumber(t.drop_high)}, {"p_value", JsonNumber(t.p_value)},
                 {"hypotheses", t.hypotheses},   {"significant", t.significant}};
  }
  if (!s.restart_training_xor.empty()) {
    json restarts = json::array();
    for (double x : s.restart_training_xor) restarts.push_back(JsonNumber(x));
    j["restart_training_xor"] = restarts;
  }
  if (s.restart > 0) j["restart"] = s.restart;
  if (s.uninformative) j["uninformative"] = true;
  if (!s.at_bounds.empty()) j["at_bounds"] = s.at_bounds;
  return j;
}

ReportStage StageFromJson(const json& j, const std::string& path) {
  const In in(j, path);
  ReportStage s;
  s.name = in.Text("name");
  s.effect_tried = in.Text("effect_tried");
  try {
    s.decision = StageDecisionFromString(in.Text("decision"));
  } catch (const std::invalid_argument& e) {
    BadReportKey(in.Path("decision"), e.what());
  }
  s.effects = in.Texts("effects");
  const json& params = in.Raw("parameters");
  if (!params.is_object()) BadReportKey(in.Path("parameters"), "expected an object");
  for (const auto& [name, v] : params.items()) {
    if (!v.is_number() && !v.is_null()) BadReportKey(in.Path("parameters." + name), "expected a number");
    s.parameters[name] = v.is_null() ? NAN : v.get<double>();
  }
  const json& errors = in.Array("errors");
  for (size_t i = 0; i < errors.size(); ++i) {
    s.errors.push_back(ErrorFromJson(errors[i], fmt::format("{}[{}]", in.Path("errors"), i)));
  }
  s.criterion = in.Text("criterion");
  s.criterion_value = in.Num("criterion_value");
  s.reason = in.Text("reason");
  s.calibration_time_s = in.Num("calibration_time_s");
  s.evaluations = static_cast<int>(in.Int("evaluations"));
  if (j.contains("restart")) {  // optional: the first calibration of a hypothesis has none
    s.restart = static_cast<int>(in.Int("restart"));
    if (s.restart < 1) BadReportKey(in.Path("restart"), "expected at least 1");
  }
  if (j.contains("equally_good")) {  // optional: measured only for kept models
    const In g(in.Raw("equally_good"), in.Path("equally_good"));
    s.equally_good.fits = static_cast<int>(g.Int("fits"));
    if (s.equally_good.fits < 1) BadReportKey(g.Path("fits"), "expected at least 1");
    s.equally_good.training_tolerance_px = g.Num("training_tolerance_px");
    s.equally_good.holdout_xor_min = g.Num("holdout_xor_min");
    s.equally_good.holdout_xor_max = g.Num("holdout_xor_max");
    s.equally_good.holdout_xor_median = g.Num("holdout_xor_median");
    s.equally_good.holdout_iou_at_min = g.Num("holdout_iou_at_min");
  }
  if (j.contains("holdout_sensitivity_px")) {  // optional: measured with held-out recordings
    s.holdout_sensitivity_px = in.Num("holdout_sensitivity_px");
    if (!(s.holdout_sensitivity_px >= 0.0)) {
      BadReportKey(in.Path("holdout_sensitivity_px"), "expected a number >= 0");
    }
    if (j.contains("holdout_sensitivity_parameter")) {
      s.holdout_sensitivity_parameter = in.Text("holdout_sensitivity_parameter");
    }
  }
  if (j.contains("test")) {  // optional: tried stages only
    const In t(in.Raw("test"), in.Path("test"));
    s.test.frames = static_cast<int>(t.Int("frames"));
    if (s.test.frames < 1) BadReportKey(t.Path("frames"), "expected at least 1");
    s.test.blocks = static_cast<int>(t.Int("blocks"));
    s.test.drop = t.Num("drop");
    s.test.drop_low = t.Num("drop_low");
    s.test.drop_high = t.Num("drop_high");
    s.test.p_value = t.Num("p_value");
    if (!(s.test.p_value >= 0.0 && s.test.p_value <= 1.0)) BadReportKey(t.Path("p_value"), "expected a number in [0, 1]");
    s.test.hypotheses = static_cast<int>(t.Int("hypotheses"));
    s.test.significant = t.Bool("significant");
  }
  if (j.contains("restart_training_xor")) {  // optional: calibrations from scratch only
    const json& restarts = in.Array("restart_training_xor");
    for (size_t i = 0; i < restarts.size(); ++i) {
      if (!restarts[i].is_number() && !restarts[i].is_null()) {
        BadReportKey(fmt::format("{}[{}]", in.Path("restart_training_xor"), i), "expected a number");
      }
      s.restart_training_xor.push_back(restarts[i].is_null() ? NAN : restarts[i].get<double>());
    }
  }
  if (j.contains("uninformative")) s.uninformative = in.Bool("uninformative");  // optional
  if (j.contains("at_bounds")) {  // optional
    const json& bounds = in.Array("at_bounds");
    for (size_t i = 0; i < bounds.size(); ++i) {
      if (!bounds[i].is_string()) BadReportKey(fmt::format("{}[{}]", in.Path("at_bounds"), i), "expected a string");
      s.at_bounds.push_back(bounds[i].get<std::string>());
    }
  }
  return s;
}

}  // namespace

RecordingScore RecordingScore::FromEvaluation(const std::string& recording,
                                              const EvaluationResult& result) {
  RecordingScore e;
  e.recording = recording;
  e.status = ToString(result.status);
  e.failure_frame = result.ok() ? -1 : result.failure_frame;
  e.failure_reason = result.ok() ? std::string() : result.failure_reason;
  e.xor_sum = result.xor_sum;
  e.mean_iou = result.mean_iou;
  for (const FrameScore& f : result.frames) {
    e.frame_xor.push_back(f.xor_px);
    e.frame_iou.push_back(f.iou);
  }
  return e;
}

namespace {

constexpr auto kStageDecisionNames = std::to_array<EnumName<StageDecision>>({
    {StageDecision::kBase, "base"},
    {StageDecision::kAccepted, "accepted"},
    {StageDecision::kRejected, "rejected"},
});

}  // namespace

std::string ToString(StageDecision decision) { return EnumToString(kStageDecisionNames, decision); }

StageDecision StageDecisionFromString(const std::string& text) {
  return EnumFromString(kStageDecisionNames, "stage decision", text);
}

const RecordingScore* ReportStage::ErrorOn(const std::string& recording) const {
  for (const RecordingScore& e : errors) {
    if (e.recording == recording) return &e;
  }
  return nullptr;
}

const ReportStage* LoopReport::BaseStage() const { return stages.empty() ? nullptr : &stages[0]; }

const ReportStage* LoopReport::FinalStage() const {
  for (auto it = stages.rbegin(); it != stages.rend(); ++it) {
    if (it->decision == StageDecision::kAccepted) return &*it;
  }
  return BaseStage();
}

nlohmann::json ToJson(const LoopReport& r) {
  json j = json::object();
  j["format"] = "calib-loop-report/1";
  j["title"] = r.title;
  j["command"] = r.command;
  j["seed"] = r.seed;
  j["selection_rule"] = r.selection_rule;
  j["run_time_s"] = JsonNumber(r.run_time_s);
  json recordings = json::array();
  for (const ReportRecording& rec : r.recordings) {
    json entry = {{"name", rec.name},
                  {"path", rec.path},
                  {"role", rec.role},
                  {"num_frames", rec.num_frames},
                  {"fps", JsonNumber(rec.fps)}};
    if (!rec.tip_x_px.empty()) {
      entry["tip_x_px"] = Numbers(rec.tip_x_px);
      entry["tip_y_px"] = Numbers(rec.tip_y_px);
    }
    if (!rec.registered_iou.empty()) entry["registered_iou"] = Numbers(rec.registered_iou);
    recordings.push_back(std::move(entry));
  }
  j["recordings"] = recordings;
  json stages = json::array();
  for (const ReportStage& s : r.stages) stages.push_back(ToJson(s));
  j["stages"] = stages;
  json rounds = json::array();
  for (const HypothesisRound& round : r.rounds) {
    json hs = json::array();
    for (const Hypothesis& h : round.hypotheses) hs.push_back(ToJson(h));
    rounds.push_back({{"round", round.round}, {"stage", round.stage}, {"hypotheses", hs}});
  }
  j["rounds"] = rounds;
  json confusions = json::array();
  for (const ReportConfusion& c : r.confusions) {
    confusions.push_back({{"round", c.round},
                          {"effect", c.effect},
                          {"confused_with", c.confused_with},
                          {"separated", c.separated},
                          {"evidence", c.evidence},
                          {"proposal", c.proposal}});
  }
  j["confusions"] = confusions;
  j["effects_kept"] = r.effects_kept;
  json residuals = json::array();
  for (const ReportResidual& res : r.residuals) {
    residuals.push_back({{"recording", res.recording},
                         {"stage", res.stage},
                         {"analysis", ToJson(res.analysis, false)}});
  }
  j["residuals"] = residuals;
  json overlays = json::array();
  for (const ReportOverlay& o : r.overlays) {
    overlays.push_back({{"recording", o.recording},
                        {"stage", o.stage},
                        {"frame", o.frame},
                        {"xor_px", o.xor_px},
                        {"iou", JsonNumber(o.iou)},
                        {"png_file", o.png_file},
                        {"caption", o.caption}});
  }
  j["overlays"] = overlays;
  j["notes"] = r.notes;

  // Derived: the before / after table.
  const ReportStage* base = r.BaseStage();
  const ReportStage* final_stage = r.FinalStage();
  json table = json::array();
  for (const ReportRecording& rec : r.recordings) {
    json row = {{"recording", rec.name}, {"role", rec.role}};
    const RecordingScore* before = base != nullptr ? base->ErrorOn(rec.name) : nullptr;
    const RecordingScore* after = final_stage != nullptr ? final_stage->ErrorOn(rec.name) : nullptr;
    row["before"] = before != nullptr ? json{{"xor_sum", before->xor_sum},
                                             {"mean_iou", JsonNumber(before->mean_iou)},
                                             {"status", before->status}}
                                      : json(nullptr);
    row["after"] = after != nullptr ? json{{"xor_sum", after->xor_sum},
                                           {"mean_iou", JsonNumber(after->mean_iou)},
                                           {"status", after->status}}
                                    : json(nullptr);
    table.push_back(row);
  }
  j["error_table"] = table;
  j["final_model"] = final_stage != nullptr ? json(final_stage->name) : json(nullptr);
  j["final_parameters"] = final_stage != nullptr ? ToJson(final_stage->parameters) : json(nullptr);
  return j;
}

LoopReport LoopReportFromJson(const nlohmann::json& doc) {
  const In in(doc, "");
  if (in.Text("format") != "calib-loop-report/1") {
    BadReportKey("format", fmt::format("expected calib-loop-report/1, found {}", in.Text("format")));
  }
  LoopReport r;
  r.title = in.Text("title");
  r.command = in.Text("command");
  r.seed = in.UInt("seed");
  r.selection_rule = in.Text("selection_rule");
  r.run_time_s = in.Num("run_time_s");
  const json& recordings = in.Array("recordings");
  for (size_t i = 0; i < recordings.size(); ++i) {
    const In rec(recordings[i], fmt::format("recordings[{}]", i));
    r.recordings.push_back({rec.Text("name"), rec.Text("path"), rec.Text("role"),
                            static_cast<int>(rec.Int("num_frames")), rec.Num("fps"),
                            OptionalNumbers(rec, recordings[i], "tip_x_px"),
                            OptionalNumbers(rec, recordings[i], "tip_y_px"),
                            OptionalNumbers(rec, recordings[i], "registered_iou")});
  }
  const json& stages = in.Array("stages");
  for (size_t i = 0; i < stages.size(); ++i) {
    r.stages.push_back(StageFromJson(stages[i], fmt::format("stages[{}]", i)));
  }
  const json& rounds = in.Array("rounds");
  for (size_t i = 0; i < rounds.size(); ++i) {
    const In round(rounds[i], fmt::format("rounds[{}]", i));
    HypothesisRound h;
    h.round = static_cast<int>(round.Int("round"));
    h.stage = round.Text("stage");
    for (const json& hyp : round.Array("hypotheses")) h.hypotheses.push_back(HypothesisFromJson(hyp));
    r.rounds.push_back(std::move(h));
  }
  if (doc.contains("confusions")) {  // optional: reports before confusions were judged
    const json& confusions = in.Array("confusions");
    for (size_t i = 0; i < confusions.size(); ++i) {
      const In c(confusions[i], fmt::format("confusions[{}]", i));
      ReportConfusion out;
      out.round = static_cast<int>(c.Int("round"));
      out.effect = c.Text("effect");
      out.confused_with = c.Text("confused_with");
      out.separated = c.Bool("separated");
      out.evidence = c.Text("evidence");
      out.proposal = c.Text("proposal");
      r.confusions.push_back(std::move(out));
    }
  }
  r.effects_kept = in.Texts("effects_kept");
  const json& residuals = in.Array("residuals");
  for (size_t i = 0; i < residuals.size(); ++i) {
    const In res(residuals[i], fmt::format("residuals[{}]", i));
    r.residuals.push_back(
        {res.Text("recording"), res.Text("stage"), ResidualAnalysisFromJson(res.Raw("analysis"))});
  }
  const json& overlays = in.Array("overlays");
  for (size_t i = 0; i < overlays.size(); ++i) {
    const In o(overlays[i], fmt::format("overlays[{}]", i));
    r.overlays.push_back({o.Text("recording"), o.Text("stage"), static_cast<int>(o.Int("frame")),
                          o.Num("xor_px"), o.Num("iou"), o.Text("png_file"), o.Text("caption")});
  }
  r.notes = in.Texts("notes");
  return r;
}

void WriteLoopReportJson(const std::filesystem::path& path, const LoopReport& report) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(fmt::format("{}: cannot open for writing", path.string()));
  out << ToJson(report).dump(1) << '\n';
  if (!out) throw std::runtime_error(fmt::format("{}: write failed", path.string()));
}

LoopReport ReadLoopReportJson(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(fmt::format("{}: cannot open", path.string()));
  json doc;
  try {
    doc = json::parse(in);
  } catch (const json::parse_error& e) {
    throw std::invalid_argument(fmt::format("{}: invalid JSON: {}", path.string(), e.what()));
  }
  return LoopReportFromJson(doc);
}

std::vector<int> WorstFrames(const std::vector<double>& frame_xor, int count, int min_gap) {
  std::vector<int> order(frame_xor.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return frame_xor[a] > frame_xor[b]; });
  std::vector<int> out;
  for (int f : order) {
    if (static_cast<int>(out.size()) >= count) break;
    bool far_enough = true;
    for (int w : out) far_enough &= std::abs(w - f) >= min_gap;
    if (far_enough) out.push_back(f);
  }
  return out;
}

}  // namespace calib
