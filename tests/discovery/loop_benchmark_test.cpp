// The loop benchmark without running a loop: per-object outcomes read off a
// report, the aggregate rates from hand-made outcomes, resuming (an
// injected runner counts what runs), a failing loop recorded, object
// selection, and the JSON / CSV round trip of the summary.

#include "calib/discovery/benchmark_html.h"
#include "calib/discovery/hypotheses.h"
#include "calib/discovery/loop_benchmark.h"

#include "support/csv_support.h"
#include "support/test_support.h"

#include "support/process_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <stdexcept>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

RecordingScore Score(const std::string& recording, int64_t xor_sum) {
  RecordingScore e;
  e.recording = recording;
  e.xor_sum = xor_sum;
  e.mean_iou = 0.95;
  return e;
}

ReportStage Stage(const std::string& name, StageDecision decision,
                  std::vector<RecordingScore> errors, double sensitivity_px) {
  ReportStage s;
  s.name = name;
  s.effect_tried = name == "base" ? "" : name.substr(name.rfind('+') + 1);
  s.decision = decision;
  s.errors = std::move(errors);
  s.holdout_sensitivity_px = sensitivity_px;
  return s;
}

// ---- an outcome read off a report ------------------------------------------

TEST(LoopBenchmark, SummarisesAnObjectFromItsReport) {
  LoopReport r;
  r.run_time_s = 42.5;
  r.recordings = {{"a", "/f/a", "train", 10, 30.0, {}, {}, {}},
                  {"b", "/f/b", "holdout", 10, 30.0, {}, {}, {}},
                  {"c", "/f/c", "holdout", 10, 30.0, {}, {}, {}}};
  r.stages = {Stage("base", StageDecision::kBase,
                    {Score("a", 1000), Score("b", 1200), Score("c", 800)}, 20.0),
              Stage("base+plasticity", StageDecision::kAccepted,
                    {Score("a", 700), Score("b", 700), Score("c", 500)}, 9.0),
              Stage("base+plasticity+table_friction", StageDecision::kRejected,
                    {Score("a", 600), Score("b", 800), Score("c", 500)}, 0.0),
              Stage("base+plasticity+viscoelastic", StageDecision::kAccepted,
                    {Score("a", 650), Score("b", 600), Score("c", 400)}, 5.0)};
  Hypothesis plastic, friction;
  plastic.effect = "plasticity";
  plastic.confidence = 0.8;
  friction.effect = "table_friction";
  friction.confidence = 0.3;
  r.rounds = {{1, "base", {plastic, friction}}, {2, "base+plasticity", {friction}}};
  r.effects_kept = {"plasticity", "viscoelastic"};

  FamilyObject object;
  object.id = "plasticity-clear-00";
  object.cell = "plasticity-clear";
  object.effect = "plasticity";
  object.loop_effect = "plasticity";
  object.magnitude = "clear";
  object.confusable_with = "table_friction";
  object.recordings = {"a", "b", "c"};
  const ObjectOutcome o = SummariseObject(object, r);

  EXPECT_EQ(o.id, "plasticity-clear-00");
  EXPECT_EQ(o.magnitude, "clear");
  EXPECT_TRUE(o.ok());
  EXPECT_EQ(o.effects_kept, (std::vector<std::string>{"plasticity", "viscoelastic"}));
  EXPECT_EQ(o.TopHypothesis(), "plasticity");
  ASSERT_EQ(o.first_round.size(), 2u);  // the first round only
  EXPECT_DOUBLE_EQ(o.FirstRoundConfidence("table_friction"), 0.3);
  EXPECT_TRUE(std::isnan(o.FirstRoundConfidence("inertia")));
  EXPECT_DOUBLE_EQ(o.train_xor_before, 1000.0);
  EXPECT_DOUBLE_EQ(o.train_xor_after, 650.0);  // the last accepted stage
  EXPECT_DOUBLE_EQ(o.holdout_xor_before, 2000.0);
  EXPECT_DOUBLE_EQ(o.holdout_xor_after, 1000.0);
  EXPECT_DOUBLE_EQ(o.HoldoutChange(), -0.5);
  EXPECT_DOUBLE_EQ(o.base_sensitivity_px, 20.0);
  EXPECT_DOUBLE_EQ(o.final_sensitivity_px, 5.0);
  EXPECT_DOUBLE_EQ(o.MaxSensitivityRelative(), 0.01);  // 20 / 2000 against 5 / 1000
  ASSERT_EQ(o.kept_changes.size(), 2u);
  EXPECT_EQ(o.kept_changes[0].effect, "plasticity");
  EXPECT_DOUBLE_EQ(o.kept_changes[0].holdout_xor_before, 2000.0);
  EXPECT_DOUBLE_EQ(o.kept_changes[0].holdout_xor_after, 1200.0);
  EXPECT_EQ(o.kept_changes[1].effect, "viscoelastic");
  EXPECT_DOUBLE_EQ(o.kept_changes[1].holdout_xor_before, 1200.0);  // from the model it was added to
  EXPECT_DOUBLE_EQ(o.kept_changes[1].Relative(), -1.0 / 6.0);
  EXPECT_TRUE(o.Detected());
  EXPECT_TRUE(o.FalseDiscovery());  // viscoelastic is not in the object
  EXPECT_FALSE(o.ConfusableKept());
  EXPECT_DOUBLE_EQ(o.run_time_s, 42.5);
}

TEST(LoopBenchmark, WithoutHeldOutRecordingsHeldOutValuesAreNaN) {
  LoopReport r;
  r.recordings = {{"a", "/f/a", "train", 10, 30.0, {}, {}, {}}};
  r.stages = {Stage("base", StageDecision::kBase, {Score("a", 1000)}, 0.0)};
  FamilyObject object;
  object.id = "x";
  object.cell = "none";
  object.recordings = {"a"};
  const ObjectOutcome o = SummariseObject(object, r);
  EXPECT_DOUBLE_EQ(o.train_xor_before, 1000.0);
  EXPECT_TRUE(std::isnan(o.holdout_xor_before));
  EXPECT_TRUE(std::isnan(o.HoldoutChange()));
  EXPECT_TRUE(std::isnan(o.MaxSensitivityRelative()));
  EXPECT_TRUE(o.first_round.empty());
  EXPECT_EQ(o.TopHypothesis(), "");
}

// ---- the aggregate from hand-made outcomes ---------------------------------

ObjectOutcome Made(const std::string& id, const std::string& cell, const std::string& effect,
                   const std::string& magnitude, const std::string& confusable,
                   std::vector<KeptEffectChange> kept, double run_time_s = 10.0) {
  ObjectOutcome o;
  o.id = id;
  o.cell = cell;
  o.effect = effect;
  o.loop_effect = effect;
  o.magnitude = magnitude;
  o.confusable_with = confusable;
  for (const KeptEffectChange& c : kept) o.effects_kept.push_back(c.effect);
  o.kept_changes = std::move(kept);
  o.holdout_xor_before = 1000.0;
  o.holdout_xor_after = o.kept_changes.empty() ? 1000.0 : o.kept_changes.back().holdout_xor_after;
  o.base_sensitivity_px = 10.0;
  o.final_sensitivity_px = 10.0;
  o.run_time_s = run_time_s;
  return o;
}

KeptEffectChange Kept(const std::string& effect, double relative) {
  return {effect, 1000.0, 1000.0 * (1.0 + relative)};
}

// 6 clear and 4 faint plasticity objects (confusable with table friction),
// 5 without an effect, and one whose loop failed.
std::vector<ObjectOutcome> HandMadeOutcomes() {
  std::vector<ObjectOutcome> out;
  const double clear_changes[5] = {-0.5, -0.4, -0.3, -0.2, -0.1};
  for (int i = 0; i < 5; ++i) {
    out.push_back(Made("pc" + std::to_string(i), "plasticity-clear", "plasticity", "clear",
                       "table_friction", {Kept("plasticity", clear_changes[i])}));
  }
  out.push_back(Made("pc5", "plasticity-clear", "plasticity", "clear", "table_friction",
                     {Kept("table_friction", 0.01)}));
  out.push_back(Made("pf0", "plasticity-faint", "plasticity", "faint", "table_friction",
                     {Kept("plasticity", -0.05)}));
  for (int i = 1; i < 4; ++i) {
    out.push_back(Made("pf" + std::to_string(i), "plasticity-faint", "plasticity", "faint",
                       "table_friction", {}));
  }
  for (int i = 0; i < 4; ++i)
    out.push_back(Made("n" + std::to_string(i), "none", "", "", "", {}, 20.0));
  out.push_back(Made("n4", "none", "", "", "", {Kept("push_relaxation", -0.02)}, 20.0));
  FamilyObject failed;
  failed.id = "n5";
  failed.cell = "none";
  out.push_back(FailedObject(failed, "n5: the loop threw", 3.0));
  return out;
}

void ExpectRate(const Proportion& p, int64_t k, int64_t n, const std::string& what) {
  EXPECT_EQ(p.successes, k) << what;
  EXPECT_EQ(p.trials, n) << what;
  const Proportion expected = WilsonInterval(k, n);
  EXPECT_DOUBLE_EQ(p.lower, expected.lower) << what;
  EXPECT_DOUBLE_EQ(p.upper, expected.upper) << what;
}

TEST(LoopBenchmarkAggregate, CountsTheConfusionTable) {
  const BenchmarkAggregate a = AggregateOutcomes(HandMadeOutcomes(), TracedEffects());
  EXPECT_EQ(a.objects, 16);
  EXPECT_EQ(a.failed, 1);
  const ConfusionTable& t = a.confusion;
  EXPECT_EQ(t.rows.back(), "none");
  EXPECT_EQ(t.columns.back(), "nothing");
  EXPECT_EQ(t.rows.size(), TracedEffects().size() + 1);
  EXPECT_EQ(t.At("plasticity", "plasticity"), 6);
  EXPECT_EQ(t.At("plasticity", "table_friction"), 1);
  EXPECT_EQ(t.At("plasticity", "nothing"), 3);
  EXPECT_EQ(t.At("none", "nothing"), 4);  // the failed object is left out
  EXPECT_EQ(t.At("none", "push_relaxation"), 1);
  EXPECT_EQ(t.At("table_friction", "nothing"), 0);
}

TEST(LoopBenchmarkAggregate, DetectionRatesPerEffectAndMagnitudeWithWilsonIntervals) {
  const BenchmarkAggregate a = AggregateOutcomes(HandMadeOutcomes(), TracedEffects());
  ASSERT_EQ(a.detection.size(), 2u);
  EXPECT_EQ(a.detection[0].effect, "plasticity");
  EXPECT_EQ(a.detection[0].magnitude, "faint");  // faint before clear
  ExpectRate(a.detection[0].detected, 1, 4, "plasticity faint");
  EXPECT_EQ(a.detection[1].magnitude, "clear");
  ExpectRate(a.detection[1].detected, 5, 6, "plasticity clear");
  EXPECT_NEAR(a.detection[1].detected.lower, 0.4365, 5e-5);
  EXPECT_NEAR(a.detection[1].detected.upper, 0.9699, 5e-5);
}

TEST(LoopBenchmarkAggregate, FalseDiscoveriesOverAllObjectsAndPerCell) {
  const BenchmarkAggregate a = AggregateOutcomes(HandMadeOutcomes(), TracedEffects());
  // pc5 kept table friction, n4 push relaxation; the failed object does not count.
  ExpectRate(a.false_discoveries, 2, 15, "all");
  ASSERT_EQ(a.false_discoveries_per_cell.size(), 3u);
  EXPECT_EQ(a.false_discoveries_per_cell[0].cell, "plasticity-clear");
  ExpectRate(a.false_discoveries_per_cell[0].rate, 1, 6, "plasticity-clear");
  EXPECT_EQ(a.false_discoveries_per_cell[1].cell, "plasticity-faint");
  ExpectRate(a.false_discoveries_per_cell[1].rate, 0, 4, "plasticity-faint");
  EXPECT_EQ(a.false_discoveries_per_cell[2].cell, "none");
  ExpectRate(a.false_discoveries_per_cell[2].rate, 1, 5, "none");
}

TEST(LoopBenchmarkAggregate, ConfusableCellsCountTheWrongOneKept) {
  const BenchmarkAggregate a = AggregateOutcomes(HandMadeOutcomes(), TracedEffects());
  ExpectRate(a.confusable_wrong_kept, 1, 10, "all");
  ASSERT_EQ(a.confusable.size(), 2u);
  EXPECT_EQ(a.confusable[0].cell, "plasticity-clear");
  EXPECT_EQ(a.confusable[0].effect, "plasticity");
  EXPECT_EQ(a.confusable[0].confusable_with, "table_friction");
  ExpectRate(a.confusable[0].wrong_kept, 1, 6, "plasticity-clear");
  ExpectRate(a.confusable[1].wrong_kept, 0, 4, "plasticity-faint");
}

TEST(LoopBenchmarkAggregate, HeldOutChangesRunTimesAndSensitivities) {
  const BenchmarkAggregate a = AggregateOutcomes(HandMadeOutcomes(), TracedEffects());
  std::map<std::pair<std::string, std::string>, Quartiles> by_group;
  for (const ChangeSummary& c : a.holdout_change)
    by_group[{c.effect, c.magnitude}] = c.relative_change;
  ASSERT_EQ(by_group.size(), 4u);
  const Quartiles& clear = by_group.at({"plasticity", "clear"});
  EXPECT_EQ(clear.count, 5);
  EXPECT_NEAR(clear.median, -0.3, 1e-12);
  EXPECT_NEAR(clear.q1, -0.4, 1e-12);
  EXPECT_NEAR(clear.q3, -0.2, 1e-12);
  EXPECT_NEAR(by_group.at({"plasticity", "faint"}).median, -0.05, 1e-12);
  EXPECT_NEAR(by_group.at({"table_friction", kNotPresent}).median, 0.01, 1e-12);
  EXPECT_NEAR(by_group.at({"push_relaxation", kNotPresent}).median, -0.02, 1e-12);
  // Table order: effects in TracedEffects() order, magnitudes faint, clear, not present.
  EXPECT_EQ(a.holdout_change.front().effect, "table_friction");
  EXPECT_EQ(a.holdout_change[1].magnitude, "faint");
  EXPECT_EQ(a.holdout_change[2].magnitude, "clear");

  // Run time: 10 objects of 10 s, 5 of 20 s and the failed one's 3 s.
  EXPECT_EQ(a.run_time_s.count, 16);
  EXPECT_DOUBLE_EQ(a.total_run_time_s, 203.0);
  EXPECT_DOUBLE_EQ(a.run_time_s.median, 10.0);
  EXPECT_DOUBLE_EQ(a.run_time_s.max, 20.0);
  // Sensitivity 10 px against held-out sums of 1000 (before) and 500 (pc0 after).
  EXPECT_EQ(a.max_sensitivity_relative.count, 15);
  EXPECT_DOUBLE_EQ(a.max_sensitivity_relative.median, 10.0 / 1000.0);
  EXPECT_DOUBLE_EQ(a.max_sensitivity_relative.max, 10.0 / 500.0);
}

// ---- round trips --------------------------------------------------------------

LoopBenchmarkReport HandMadeReport() {
  LoopBenchmarkReport r;
  r.family_dir = "/data/fam";
  r.family_name = "fam";
  r.family_spec = "plasticity:clear,faint;none";
  r.family_seed = 3;
  r.command = "calib loop-benchmark /data/fam --out out";
  r.outcomes = HandMadeOutcomes();
  r.outcomes[0].first_round = {{"plasticity", 0.75}, {"table_friction", 1.0 / 3.0}};
  r.outcomes[0].train_xor_before = 1234567.0;
  r.outcomes[0].train_xor_after = 0.1 + 0.2;  // a value that needs all 17 digits
  r.outcomes[1].resumed = true;
  r.outcomes.back().error = "a message, with \"quotes\",\nand a line break";
  r.aggregate = AggregateOutcomes(r.outcomes, TracedEffects());
  return r;
}

TEST(LoopBenchmarkReport, JsonRoundTrips) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_json");
  const LoopBenchmarkReport report = HandMadeReport();
  WriteBenchmarkJson(dir / "benchmark.json", report);
  const json doc = json::parse(testing::ReadText(dir / "benchmark.json"));
  EXPECT_EQ(doc["format"], "calib-loop-benchmark/1");
  EXPECT_EQ(doc["aggregate"]["false_discoveries"]["all"]["successes"], 2);
  EXPECT_TRUE(doc["objects"][15]["holdout_xor_before"].is_null());  // NaN of the failed object
  const LoopBenchmarkReport back = LoopBenchmarkReportFromJson(doc, "benchmark.json");
  EXPECT_EQ(ToJson(back).dump(), ToJson(report).dump());
  EXPECT_EQ(back.outcomes[0].train_xor_after, 0.1 + 0.2);
  EXPECT_EQ(back.outcomes.back().error, report.outcomes.back().error);
}

TEST(LoopBenchmarkReport, MalformedSummaryNamesTheKey) {
  json doc = ToJson(HandMadeOutcomes()[0]);
  doc["holdout_xor_before"] = "many";
  try {
    ObjectOutcomeFromJson(doc, "objects/pc0/summary.json");
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("objects/pc0/summary.json: holdout_xor_before"), std::string::npos)
        << message;
  }
  doc = ToJson(HandMadeOutcomes()[0]);
  doc["kept_changes"][0].erase("effect");
  try {
    ObjectOutcomeFromJson(doc, "summary.json");
    FAIL() << "accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("kept_changes[0].effect: missing"), std::string::npos)
        << e.what();
  }
}

double Field(const std::vector<std::string>& row, const std::map<std::string, size_t>& column,
             const std::string& name) {
  const std::string& text = row.at(column.at(name));
  return text.empty() ? NAN : std::stod(text);
}

TEST(LoopBenchmarkReport, CsvHoldsOneRowPerObjectThatParsesBack) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_csv");
  const LoopBenchmarkReport report = HandMadeReport();
  WriteBenchmarkCsv(dir / "benchmark.csv", report.outcomes);
  const testing::CsvRows rows = testing::ParseCsvFile(dir / "benchmark.csv");
  ASSERT_EQ(rows.size(), report.outcomes.size() + 1);
  EXPECT_EQ(rows[0], OutcomeCsvHeader(TracedEffects()));
  std::map<std::string, size_t> column;
  for (size_t c = 0; c < rows[0].size(); ++c) column[rows[0][c]] = c;
  for (size_t i = 0; i < report.outcomes.size(); ++i) {
    const ObjectOutcome& o = report.outcomes[i];
    const std::vector<std::string>& row = rows[i + 1];
    ASSERT_EQ(row.size(), rows[0].size()) << o.id;
    EXPECT_EQ(row[column["id"]], o.id);
    EXPECT_EQ(row[column["cell"]], o.cell);
    EXPECT_EQ(row[column["loop_effect"]], o.loop_effect);
    EXPECT_EQ(row[column["status"]], o.status);
    EXPECT_EQ(row[column["error"]], o.error) << o.id;  // quoted by libcsv, read back whole
    EXPECT_EQ(row[column["resumed"]], o.resumed ? "1" : "0");
    EXPECT_EQ(row[column["detected"]], !o.ok() ? "" : o.Detected() ? "1" : "0") << o.id;
    EXPECT_EQ(row[column["false_discovery"]], !o.ok()              ? ""
                                              : o.FalseDiscovery() ? "1"
                                                                   : "0")
        << o.id;
    std::vector<std::string> kept;
    std::stringstream list(row[column["effects_kept"]]);
    for (std::string e; std::getline(list, e, ';');) kept.push_back(e);
    EXPECT_EQ(kept, o.effects_kept) << o.id;
    for (const auto& [name, value] : std::vector<std::pair<std::string, double>>{
             {"train_xor_before", o.train_xor_before},
             {"train_xor_after", o.train_xor_after},
             {"holdout_xor_before", o.holdout_xor_before},
             {"holdout_xor_after", o.holdout_xor_after},
             {"holdout_change", o.HoldoutChange()},
             {"max_sensitivity_relative", o.MaxSensitivityRelative()},
             {"run_time_s", o.run_time_s}}) {
      const double back = Field(row, column, name);
      if (std::isnan(value)) {
        EXPECT_TRUE(std::isnan(back)) << o.id << " " << name;
      } else {
        EXPECT_EQ(back, value) << o.id << " " << name;  // written to round-trip exactly
      }
    }
    const KeptEffectChange* plastic = o.ChangeOf("plasticity");
    if (plastic != nullptr) {
      EXPECT_EQ(Field(row, column, "kept_change:plasticity"), plastic->Relative()) << o.id;
    } else {
      EXPECT_EQ(row[column["kept_change:plasticity"]], "") << o.id;
    }
  }
  EXPECT_EQ(Field(rows[1], column, "confidence:table_friction"), 1.0 / 3.0);
  EXPECT_EQ(rows[1][column["top_hypothesis"]], "plasticity");
  EXPECT_EQ(rows[2][column["confidence:plasticity"]], "");  // no first round
}

TEST(LoopBenchmarkHtml, ShowsTheRatesAndLinksEveryObject) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_html");
  const LoopBenchmarkReport report = HandMadeReport();
  HtmlReportOptions options;
  options.gnuplot.executable = "no-such-gnuplot";
  const HtmlReportSummary without = WriteBenchmarkHtml(dir / "without.html", report, options);
  EXPECT_FALSE(without.plots_made);
  const std::string page = testing::ReadText(dir / "without.html");
  EXPECT_NE(page.find("This report has no plots"), std::string::npos);
  EXPECT_NE(page.find("<b>2 / 15 = 0.13</b>"), std::string::npos);  // false discoveries
  EXPECT_NE(page.find("5 / 6</td><td class=\"n\">0.83</td><td class=\"n\">[0.44, 0.97]"),
            std::string::npos);
  for (const ObjectOutcome& o : report.outcomes) {
    EXPECT_NE(page.find("href=\"objects/" + o.id + "/report.html\""), std::string::npos) << o.id;
  }
  EXPECT_NE(page.find("a message, with &quot;quotes&quot;"), std::string::npos);
  // The first round's confidences as rates: pc0 traced plasticity (its
  // effect) at 0.75 and table friction at 1/3.
  EXPECT_NE(page.find("<td>0.75&ndash;1.00</td><td class=\"n\">1 / 1</td>"), std::string::npos);
  EXPECT_NE(page.find("<td>0.25&ndash;0.50</td><td class=\"n\">0 / 1</td>"), std::string::npos);

  options.gnuplot.executable = "gnuplot";
  std::string message;
  if (!GnuplotAvailable("gnuplot", &message)) GTEST_SKIP() << message;
  const HtmlReportSummary with = WriteBenchmarkHtml(dir / "a.html", report, options);
  EXPECT_TRUE(with.plots_made);
  EXPECT_EQ(with.plots, 1);
  WriteBenchmarkHtml(dir / "b.html", report, options);
  const std::string a = testing::ReadText(dir / "a.html");
  EXPECT_NE(a.find("<svg"), std::string::npos);
  EXPECT_EQ(a, testing::ReadText(dir / "b.html"));  // deterministic
}

// ---- running: selection, resume, failures ------------------------------------

// A family folder of `ids` ("p-..." with plasticity, the others none), two
// empty recording folders each.
fs::path MakeFamily(const fs::path& dir, const std::vector<std::string>& ids) {
  json objects = json::array();
  for (const std::string& id : ids) {
    const bool plastic = id.rfind("p-", 0) == 0;
    fs::create_directories(dir / id / "push-a");
    fs::create_directories(dir / id / "push-b");
    objects.push_back({{"id", id},
                       {"cell", plastic ? "plasticity-clear" : "none"},
                       {"effect", plastic ? json("plasticity") : json(nullptr)},
                       {"loop_effect", plastic ? json("plasticity") : json(nullptr)},
                       {"magnitude", plastic ? json("clear") : json(nullptr)},
                       {"confusable_with", plastic ? json("table_friction") : json(nullptr)},
                       {"recordings", {id + "/push-a", id + "/push-b"}}});
  }
  std::ofstream(dir / "family.json")
      << json{{"format", "calib-family/1"}, {"name", "fam"},     {"spec", "test"}, {"seed", 1},
              {"count", ids.size()},        {"objects", objects}}
             .dump(1);
  return dir;
}

// A loop stand-in: a report that keeps plasticity where the training
// recording's object is a "p-" one, written where RunLoop writes it.
struct FakeLoop {
  std::vector<std::string> ran;  // object ids, in order
  std::string fail_on;           // an id whose loop throws

  ObjectLoopRunner Runner() {
    return [this](const LoopOptions& o, const LoopLog&) {
      const std::string id = o.out_dir.filename().string();
      ran.push_back(id);
      if (id == fail_on) throw std::runtime_error("segmentation failed on " + id);
      EXPECT_EQ(o.train.size(), 1u);
      EXPECT_EQ(o.train[0].filename(), "push-a");
      EXPECT_EQ(o.holdout.size(), 1u);
      LoopReport r;
      r.command = o.command;
      r.run_time_s = 2.0;
      r.recordings = {{"push-a", o.train[0].string(), "train", 10, 30.0, {}, {}, {}},
                      {"push-b", o.holdout[0].string(), "holdout", 10, 30.0, {}, {}, {}}};
      r.stages = {
          Stage("base", StageDecision::kBase, {Score("push-a", 900), Score("push-b", 1000)}, 4.0)};
      if (id.rfind("p-", 0) == 0) {
        r.stages.push_back(Stage("base+plasticity", StageDecision::kAccepted,
                                 {Score("push-a", 400), Score("push-b", 500)}, 2.0));
        r.effects_kept = {"plasticity"};
      }
      WriteLoopReportJson(o.out_dir / "report.json", r);
      return r;
    };
  }
};

LoopBenchmarkOptions Options(const fs::path& family, const fs::path& out, FakeLoop* loop) {
  LoopBenchmarkOptions options;
  options.family_dir = family;
  options.out_dir = out;
  options.loop.budget = 8;
  options.run_object = loop->Runner();
  options.html.gnuplot.executable = "no-such-gnuplot";  // fast; the page is tested above
  return options;
}

TEST(LoopBenchmark, RunsEveryObjectAndWritesItsSummaryAndTheOutputs) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_run");
  const fs::path family = MakeFamily(dir / "fam", {"p-00", "p-01", "n-00"});
  FakeLoop loop;
  const LoopBenchmarkResult result = RunLoopBenchmark(Options(family, dir / "out", &loop));
  EXPECT_EQ(loop.ran, (std::vector<std::string>{"p-00", "p-01", "n-00"}));
  EXPECT_EQ(result.ran, 3);
  EXPECT_EQ(result.resumed, 0);
  for (const std::string id : {"p-00", "p-01", "n-00"}) {
    const fs::path summary = dir / "out" / "objects" / id / "summary.json";
    ASSERT_TRUE(fs::exists(summary)) << summary;
    EXPECT_EQ(ObjectOutcomeFromJson(json::parse(testing::ReadText(summary)), summary.string()).id, id);
  }
  EXPECT_TRUE(fs::exists(result.json));
  EXPECT_TRUE(fs::exists(result.csv));
  EXPECT_TRUE(fs::exists(result.html));
  const ConfidenceRates rates = ConfidenceRatesFromJson(
      json::parse(testing::ReadText(result.confidence_rates)), result.confidence_rates.string());
  EXPECT_EQ(rates.family, "fam");
  EXPECT_EQ(ToJson(rates)["bins"], ToJson(result.report.aggregate.confidence_rates)["bins"]);
  const BenchmarkAggregate& a = result.report.aggregate;
  ExpectRate(a.detection.at(0).detected, 2, 2, "plasticity");
  ExpectRate(a.false_discoveries, 0, 3, "false discoveries");
  EXPECT_DOUBLE_EQ(result.report.outcomes[0].HoldoutChange(), -0.5);
  EXPECT_EQ(result.report.family_name, "fam");
}

TEST(LoopBenchmark, ResumesFromReportsMadeWithTheSameOptions) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_resume");
  const fs::path family = MakeFamily(dir / "fam", {"p-00", "p-01", "n-00"});
  FakeLoop first;
  const LoopBenchmarkResult fresh = RunLoopBenchmark(Options(family, dir / "out", &first));

  // Same options (threads do not change the numbers): nothing runs again.
  FakeLoop second;
  LoopBenchmarkOptions same = Options(family, dir / "out", &second);
  same.loop.threads = 1;
  const LoopBenchmarkResult again = RunLoopBenchmark(same);
  EXPECT_TRUE(second.ran.empty());
  EXPECT_EQ(again.resumed, 3);
  EXPECT_EQ(again.ran, 0);
  ASSERT_EQ(again.report.outcomes.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_TRUE(again.report.outcomes[i].resumed);
    ObjectOutcome back = again.report.outcomes[i];
    back.resumed = false;
    EXPECT_EQ(ToJson(back).dump(), ToJson(fresh.report.outcomes[i]).dump());
  }
  EXPECT_EQ(again.report.aggregate.resumed, 3);

  // A missing report: only that object runs.
  fs::remove(dir / "out" / "objects" / "p-01" / "report.json");
  FakeLoop third;
  RunLoopBenchmark(Options(family, dir / "out", &third));
  EXPECT_EQ(third.ran, (std::vector<std::string>{"p-01"}));

  // A report cut short (a run killed while writing it): run again.
  std::ofstream(dir / "out" / "objects" / "n-00" / "report.json") << "{\"title\": ";
  FakeLoop fourth;
  RunLoopBenchmark(Options(family, dir / "out", &fourth));
  EXPECT_EQ(fourth.ran, (std::vector<std::string>{"n-00"}));

  // Other loop options: every object runs again.
  FakeLoop fifth;
  LoopBenchmarkOptions other = Options(family, dir / "out", &fifth);
  other.loop.budget = 16;
  RunLoopBenchmark(other);
  EXPECT_EQ(fifth.ran.size(), 3u);
}

TEST(LoopBenchmark, AFailingLoopIsRecordedAndTheBenchmarkGoesOn) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_failure");
  const fs::path family = MakeFamily(dir / "fam", {"p-00", "p-01", "n-00"});
  FakeLoop loop;
  loop.fail_on = "p-01";
  const LoopBenchmarkResult result = RunLoopBenchmark(Options(family, dir / "out", &loop));
  EXPECT_EQ(loop.ran, (std::vector<std::string>{"p-00", "p-01", "n-00"}));
  EXPECT_EQ(result.failed, 1);
  const ObjectOutcome& failed = result.report.outcomes[1];
  EXPECT_EQ(failed.status, "error");
  EXPECT_EQ(failed.error, "segmentation failed on p-01");
  EXPECT_EQ(result.report.aggregate.failed, 1);
  ExpectRate(result.report.aggregate.detection.at(0).detected, 1, 1, "the failed object left out");
  const json doc = json::parse(testing::ReadText(result.json));
  EXPECT_EQ(doc["objects"][1]["error"], "segmentation failed on p-01");

  // The failed object has no report: the next run tries it again, only it.
  FakeLoop next;
  RunLoopBenchmark(Options(family, dir / "out", &next));
  EXPECT_EQ(next.ran, (std::vector<std::string>{"p-01"}));
}

// An object family.json marks not_made (the generator could not make it):
// no loop runs, its outcome says why, and it is left out of every rate.
TEST(LoopBenchmark, AnObjectTheGeneratorDidNotMakeIsListedAndLeftOut) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_not_made");
  const fs::path family = MakeFamily(dir / "fam", {"p-00", "p-01", "n-00"});
  json manifest = json::parse(testing::ReadText(family / "family.json"));
  manifest["objects"][1]["not_made"] = "push-b: SimulateTruth: frame 113: no convergence";
  std::ofstream(family / "family.json") << manifest.dump(1);
  fs::remove_all(family / "p-01");
  FakeLoop loop;
  const LoopBenchmarkResult result = RunLoopBenchmark(Options(family, dir / "out", &loop));
  EXPECT_EQ(loop.ran, (std::vector<std::string>{"p-00", "n-00"}));
  EXPECT_EQ(result.not_made, 1);
  EXPECT_EQ(result.failed, 0);
  ASSERT_EQ(result.report.outcomes.size(), 3u);
  const ObjectOutcome& skipped = result.report.outcomes[1];
  EXPECT_EQ(skipped.id, "p-01");
  EXPECT_EQ(skipped.status, "not_made");
  EXPECT_EQ(skipped.error, "push-b: SimulateTruth: frame 113: no convergence");
  const BenchmarkAggregate& a = result.report.aggregate;
  EXPECT_EQ(a.objects, 3);
  EXPECT_EQ(a.not_made, 1);
  EXPECT_EQ(a.failed, 0);
  EXPECT_EQ(a.run_time_s.count, 2);
  ExpectRate(a.detection.at(0).detected, 1, 1, "the object not made left out");
  ExpectRate(a.false_discoveries, 0, 2, "false discoveries over the objects made");
  const json doc = json::parse(testing::ReadText(result.json));
  EXPECT_EQ(doc["aggregate"]["not_made"], 1);
  EXPECT_EQ(doc["objects"][1]["status"], "not_made");
  EXPECT_FALSE(fs::exists(dir / "out" / "objects" / "p-01")) << "nothing is written for it";
}

TEST(LoopBenchmark, BadOptionsStopItBeforeAnyLoopRuns) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_bad_options");
  const fs::path family = MakeFamily(dir / "fam", {"p-00", "n-00"});
  const auto message = [&](const std::function<void(LoopBenchmarkOptions&)>& change) {
    FakeLoop loop;
    LoopBenchmarkOptions options = Options(family, dir / "out", &loop);
    change(options);
    try {
      RunLoopBenchmark(options);
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(loop.ran.empty()) << e.what();
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message([](LoopBenchmarkOptions& o) { o.loop.budget = 1; }).find("--budget = 1"),
            std::string::npos);
  EXPECT_NE(message([](LoopBenchmarkOptions& o) {
              o.loop.optimizer = "newton";
            }).find("--optimizer newton: unknown"),
            std::string::npos);
  EXPECT_NE(message([](LoopBenchmarkOptions& o) { o.limit_per_cell = -1; }).find("limit_per_cell"),
            std::string::npos);
  EXPECT_NE(message([](LoopBenchmarkOptions& o) { o.only = {"x-00"}; }).find("--only x-00"),
            std::string::npos);
}

TEST(LoopBenchmark, SelectsObjectsByIdCellAndLimit) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_select");
  const FamilyManifest m =
      ReadFamilyManifest(MakeFamily(dir, {"p-00", "n-00", "p-01", "p-02", "n-01"}));
  const auto ids = [](const std::vector<FamilyObject>& objects) {
    std::vector<std::string> out;
    for (const FamilyObject& o : objects) out.push_back(o.id);
    return out;
  };
  EXPECT_EQ(ids(SelectFamilyObjects(m, {}, {}, 0)).size(), 5u);
  EXPECT_EQ(ids(SelectFamilyObjects(m, {"p-02", "n-00"}, {}, 0)),
            (std::vector<std::string>{"n-00", "p-02"}));
  EXPECT_EQ(ids(SelectFamilyObjects(m, {}, {"none"}, 0)),
            (std::vector<std::string>{"n-00", "n-01"}));
  EXPECT_EQ(ids(SelectFamilyObjects(m, {}, {}, 1)), (std::vector<std::string>{"p-00", "n-00"}));
  EXPECT_EQ(ids(SelectFamilyObjects(m, {}, {"plasticity-clear"}, 2)),
            (std::vector<std::string>{"p-00", "p-01"}));
  try {
    SelectFamilyObjects(m, {"p-09"}, {}, 0);
    FAIL() << "an unknown id was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--only p-09: no such object"), std::string::npos)
        << e.what();
  }
  try {
    SelectFamilyObjects(m, {}, {"plasticity-faint"}, 0);
    FAIL() << "an unknown cell was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--cells plasticity-faint: no such cell"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("plasticity-clear, none"), std::string::npos) << e.what();
  }
}

TEST(LoopBenchmark, EachObjectsLoopIsTheCalibLoopCommandItRecords) {
  const fs::path dir = testing::ScratchDir("loop_benchmark_command");
  const FamilyManifest m = ReadFamilyManifest(MakeFamily(dir / "fam", {"p-00"}));
  LoopOptions loop;
  loop.budget = 8;
  loop.restarts = 1;
  const LoopOptions o = ObjectLoopOptions(loop, m, m.objects[0], dir / "out");
  EXPECT_EQ(o.train, (std::vector<fs::path>{dir / "fam" / "p-00" / "push-a"}));
  EXPECT_EQ(o.holdout, (std::vector<fs::path>{dir / "fam" / "p-00" / "push-b"}));
  EXPECT_EQ(o.out_dir, dir / "out" / "objects" / "p-00");
  EXPECT_EQ(o.command, LoopCommandLine(o));
  EXPECT_EQ(o.command.rfind("calib loop --train " + (dir / "fam" / "p-00" / "push-a").string() +
                                " --holdout " + (dir / "fam" / "p-00" / "push-b").string(),
                            0),
            0u)
      << o.command;
  EXPECT_NE(o.command.find(" --budget 8 "), std::string::npos) << o.command;
  EXPECT_NE(o.command.find(" --restarts 1 "), std::string::npos) << o.command;
  LoopOptions threads = o;
  threads.threads = 7;
  threads.preparation.cache_dir = dir / "cache";
  EXPECT_EQ(LoopCommandLine(threads), o.command);
  LoopOptions friction = o;
  friction.simulation.contact_friction = 0.25;
  EXPECT_NE(LoopCommandLine(friction), o.command);
  // Every option that changes the decisions is on the line.
  LoopOptions drop = o;
  drop.min_relative_drop = 0.05;
  EXPECT_NE(LoopCommandLine(drop).find(" --min-drop 0.05"), std::string::npos) << LoopCommandLine(drop);
  LoopOptions rate = o;
  rate.rank_by_rate = true;
  EXPECT_NE(LoopCommandLine(rate).find(" --rank-by rate"), std::string::npos) << LoopCommandLine(rate);
  EXPECT_EQ(o.command.find("--rank-by"), std::string::npos) << "the default: lines made before stay";
}

}  // namespace
}  // namespace calib
