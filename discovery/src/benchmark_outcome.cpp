// One object's outcome in the loop benchmark (benchmark_outcome.h).

#include "calib/discovery/benchmark_outcome.h"

#include "calib/evaluator/json_number.h"
#include "json_io.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>

namespace calib {
namespace {

using json_io::Keys;
using nlohmann::json;

// The XOR sum of `stage` over the recordings of `role`; NaN when there are
// none or one is not scored. Read as double: the report's sums may be
// integers or sub-pixel scores.
double SumOver(const LoopReport& report, const ReportStage* stage, const std::string& role) {
  if (stage == nullptr) return NAN;
  double sum = 0.0;
  int recordings = 0;
  for (const ReportRecording& rec : report.recordings) {
    if (rec.role != role) continue;
    const RecordingScore* e = stage->ErrorOn(rec.name);
    if (e == nullptr) return NAN;
    sum += static_cast<double>(e->xor_sum);
    ++recordings;
  }
  return recordings > 0 ? sum : NAN;
}

bool Contains(const std::vector<std::string>& list, const std::string& name) {
  return std::find(list.begin(), list.end(), name) != list.end();
}

// ---- the field list, once for writing and reading --------------------------

template <class S, class F>
void VisitOutcome(S& o, F& f) {
  f.Nullable("id", o.id);
  f.Nullable("cell", o.cell);
  f.Nullable("effect", o.effect);
  f.Nullable("loop_effect", o.loop_effect);
  f.Nullable("magnitude", o.magnitude);
  f.Nullable("confusable_with", o.confusable_with);
  f("status", o.status);
  f("error", o.error);
  f("resumed", o.resumed);
  f("effects_kept", o.effects_kept);
  f("first_round", o.first_round);
  f("train_xor_before", o.train_xor_before);
  f("train_xor_after", o.train_xor_after);
  f("holdout_xor_before", o.holdout_xor_before);
  f("holdout_xor_after", o.holdout_xor_after);
  f("base_sensitivity_px", o.base_sensitivity_px);
  f("final_sensitivity_px", o.final_sensitivity_px);
  f("kept_changes", o.kept_changes);
  f("run_time_s", o.run_time_s);
}

struct Writer {
  json& out;
  void Nullable(const char* key, const std::string& v) {
    out[key] = v.empty() ? json(nullptr) : json(v);
  }
  void operator()(const char* key, const std::string& v) { out[key] = v; }
  void operator()(const char* key, bool v) { out[key] = v; }
  void operator()(const char* key, double v) { out[key] = JsonNumber(v); }
  void operator()(const char* key, const std::vector<std::string>& v) { out[key] = v; }
  void operator()(const char* key, const std::vector<HypothesisConfidence>& v) {
    json list = json::array();
    for (const HypothesisConfidence& h : v) {
      list.push_back({{"effect", h.effect}, {"confidence", JsonNumber(h.confidence)}});
    }
    out[key] = list;
  }
  void operator()(const char* key, const std::vector<KeptEffectChange>& v) {
    json list = json::array();
    for (const KeptEffectChange& c : v) {
      list.push_back({{"effect", c.effect},
                      {"holdout_xor_before", JsonNumber(c.holdout_xor_before)},
                      {"holdout_xor_after", JsonNumber(c.holdout_xor_after)}});
    }
    out[key] = list;
  }
};

struct Reader {
  const Keys& in;
  void Nullable(const char* key, std::string& v) { v = in.TextOrNull(key); }
  void operator()(const char* key, std::string& v) { v = in.Text(key); }
  void operator()(const char* key, bool& v) { v = in.Bool(key); }
  void operator()(const char* key, double& v) { v = in.Number(key); }
  void operator()(const char* key, std::vector<std::string>& v) { v = in.Texts(key); }
  void operator()(const char* key, std::vector<HypothesisConfidence>& v) {
    v.resize(in.Array(key).size());
    for (size_t i = 0; i < v.size(); ++i) {
      const Keys h = in.Child(key, static_cast<int>(i));
      v[i] = {h.Text("effect"), h.Number("confidence")};
    }
  }
  void operator()(const char* key, std::vector<KeptEffectChange>& v) {
    v.resize(in.Array(key).size());
    for (size_t i = 0; i < v.size(); ++i) {
      const Keys c = in.Child(key, static_cast<int>(i));
      v[i] = {c.Text("effect"), c.Number("holdout_xor_before"), c.Number("holdout_xor_after")};
    }
  }
};

std::string CsvNumber(double v) { return std::isfinite(v) ? fmt::format("{}", v) : std::string(); }

std::string CsvFlag(const ObjectOutcome& o, bool v) {
  if (!o.ok()) return "";
  return v ? "1" : "0";
}

}  // namespace

double KeptEffectChange::Relative() const {
  return holdout_xor_before > 0.0 ? (holdout_xor_after - holdout_xor_before) / holdout_xor_before
                                  : NAN;
}

std::string ObjectOutcome::TopHypothesis() const {
  return first_round.empty() ? std::string() : first_round.front().effect;
}

double ObjectOutcome::FirstRoundConfidence(const std::string& name) const {
  for (const HypothesisConfidence& h : first_round) {
    if (h.effect == name) return h.confidence;
  }
  return NAN;
}

bool ObjectOutcome::Detected() const {
  return !loop_effect.empty() && Contains(effects_kept, loop_effect);
}

bool ObjectOutcome::FalseDiscovery() const {
  return std::any_of(effects_kept.begin(), effects_kept.end(),
                     [&](const std::string& kept) { return kept != loop_effect; });
}

bool ObjectOutcome::ConfusableKept() const {
  return !confusable_with.empty() && Contains(effects_kept, confusable_with);
}

double ObjectOutcome::HoldoutChange() const {
  return KeptEffectChange{"", holdout_xor_before, holdout_xor_after}.Relative();
}

double ObjectOutcome::MaxSensitivityRelative() const {
  const auto relative = [](double sensitivity, double xor_sum) {
    return xor_sum > 0.0 ? sensitivity / xor_sum : NAN;
  };
  const double base = relative(base_sensitivity_px, holdout_xor_before);
  const double fin = relative(final_sensitivity_px, holdout_xor_after);
  if (std::isnan(base)) return fin;
  if (std::isnan(fin)) return base;
  return std::max(base, fin);
}

const KeptEffectChange* ObjectOutcome::ChangeOf(const std::string& name) const {
  for (const KeptEffectChange& c : kept_changes) {
    if (c.effect == name) return &c;
  }
  return nullptr;
}

namespace {

ObjectOutcome FromManifest(const FamilyObject& object) {
  ObjectOutcome o;
  o.id = object.id;
  o.cell = object.cell;
  o.effect = object.effect;
  o.loop_effect = object.loop_effect;
  o.magnitude = object.magnitude;
  o.confusable_with = object.confusable_with;
  return o;
}

}  // namespace

ObjectOutcome SummariseObject(const FamilyObject& object, const LoopReport& report) {
  ObjectOutcome o = FromManifest(object);
  o.effects_kept = report.effects_kept;
  if (!report.rounds.empty()) {
    for (const Hypothesis& h : report.rounds.front().hypotheses) {
      o.first_round.push_back({h.effect, h.confidence});
    }
  }
  const ReportStage* base = report.BaseStage();
  const ReportStage* fin = report.FinalStage();
  o.train_xor_before = SumOver(report, base, "train");
  o.train_xor_after = SumOver(report, fin, "train");
  o.holdout_xor_before = SumOver(report, base, "holdout");
  o.holdout_xor_after = SumOver(report, fin, "holdout");
  if (!std::isnan(o.holdout_xor_before)) {
    o.base_sensitivity_px = base->holdout_sensitivity_px;
    o.final_sensitivity_px = fin->holdout_sensitivity_px;
  }
  const ReportStage* previous = base;
  for (const ReportStage& stage : report.stages) {
    if (stage.decision != StageDecision::kAccepted) continue;
    o.kept_changes.push_back({stage.effect_tried, SumOver(report, previous, "holdout"),
                              SumOver(report, &stage, "holdout")});
    previous = &stage;
  }
  o.run_time_s = report.run_time_s;
  return o;
}

ObjectOutcome FailedObject(const FamilyObject& object, const std::string& message,
                           double run_time_s) {
  ObjectOutcome o = FromManifest(object);
  o.status = "error";
  o.error = message;
  o.run_time_s = run_time_s;
  return o;
}

ObjectOutcome NotMadeObject(const FamilyObject& object) {
  ObjectOutcome o = FromManifest(object);
  o.status = ObjectOutcome::kNotMadeStatus;
  o.error = object.not_made;
  return o;
}

json ToJson(const ObjectOutcome& outcome) {
  json j = json::object();
  Writer w{j};
  VisitOutcome(outcome, w);
  if (outcome.ok()) {
    j["top_hypothesis"] = outcome.TopHypothesis();
    j["detected"] = outcome.Detected();
    j["false_discovery"] = outcome.FalseDiscovery();
    j["confusable_kept"] = outcome.ConfusableKept();
  }
  j["holdout_change"] = JsonNumber(outcome.HoldoutChange());
  j["max_sensitivity_relative"] = JsonNumber(outcome.MaxSensitivityRelative());
  return j;
}

ObjectOutcome ObjectOutcomeFromJson(const json& doc, const std::string& source) {
  const Keys in(doc, source, "");
  ObjectOutcome o;
  Reader r{in};
  VisitOutcome(o, r);
  return o;
}

std::vector<std::string> OutcomeCsvHeader(const std::vector<std::string>& effects) {
  std::vector<std::string> h = {"id",
                                "cell",
                                "effect",
                                "loop_effect",
                                "magnitude",
                                "confusable_with",
                                "status",
                                "error",
                                "resumed",
                                "effects_kept",
                                "detected",
                                "false_discovery",
                                "confusable_kept",
                                "top_hypothesis",
                                "top_confidence",
                                "train_xor_before",
                                "train_xor_after",
                                "holdout_xor_before",
                                "holdout_xor_after",
                                "holdout_change",
                                "base_sensitivity_px",
                                "final_sensitivity_px",
                                "max_sensitivity_relative",
                                "run_time_s"};
  for (const std::string& e : effects) h.push_back("confidence:" + e);
  for (const std::string& e : effects) h.push_back("kept_change:" + e);
  return h;
}

std::vector<std::string> OutcomeCsvRow(const ObjectOutcome& o,
                                       const std::vector<std::string>& effects) {
  std::vector<std::string> row = {
      o.id,
      o.cell,
      o.effect,
      o.loop_effect,
      o.magnitude,
      o.confusable_with,
      o.status,
      o.error,
      o.resumed ? "1" : "0",
      fmt::format("{}", fmt::join(o.effects_kept, ";")),
      CsvFlag(o, o.Detected()),
      CsvFlag(o, o.FalseDiscovery()),
      CsvFlag(o, o.ConfusableKept()),
      o.TopHypothesis(),
      CsvNumber(o.first_round.empty() ? NAN : o.first_round.front().confidence),
      CsvNumber(o.train_xor_before),
      CsvNumber(o.train_xor_after),
      CsvNumber(o.holdout_xor_before),
      CsvNumber(o.holdout_xor_after),
      CsvNumber(o.HoldoutChange()),
      CsvNumber(o.base_sensitivity_px),
      CsvNumber(o.final_sensitivity_px),
      CsvNumber(o.MaxSensitivityRelative()),
      CsvNumber(o.run_time_s)};
  for (const std::string& e : effects) row.push_back(CsvNumber(o.FirstRoundConfidence(e)));
  for (const std::string& e : effects) {
    const KeptEffectChange* c = o.ChangeOf(e);
    row.push_back(c != nullptr ? CsvNumber(c->Relative()) : std::string());
  }
  return row;
}

}  // namespace calib
