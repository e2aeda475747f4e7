// The loop report: report.json round trip and content, report.html with its
// gnuplot SVG plots (or a clear notice without gnuplot), determinism.

#include "calib/discovery/loop.h"
#include "calib/discovery/loop_report.h"
#include "calib/discovery/report_html.h"

#include "calib/evaluator/media.h"
#include "calib/evaluator/rasterizer.h"
#include "support/test_support.h"

#include <fmt/format.h>
#include "support/process_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;

int Count(const std::string& text, const std::string& what) {
  int n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// A residual analysis of a rectangle against a mesh shifted right by
// `shift` px over `frames` frames.
ResidualAnalysis ShiftAnalysis(const std::string& name, double shift, int frames) {
  const Mesh mesh = testing::MakeGridMesh(10, 6, 10.0, Vec2(100.0, 100.0));
  Scene scene;
  scene.num_frames = frames;
  std::vector<BitMask> object;
  for (int f = 0; f < frames; ++f) {
    BitMask m(320, 240);
    for (int y = 100; y < 160; ++y) m.SetSpan(y, 100, 200);
    object.push_back(m);
  }
  ResidualAnalyser analyser(mesh, scene, object, {}, name);
  std::vector<Vec2> positions = mesh.rest_positions;
  for (Vec2& p : positions) p.x() += shift;
  BitMask mesh_mask(320, 240);
  Rasterizer().RasterizeMesh(mesh, positions, mesh_mask);
  for (int f = 0; f < frames; ++f) analyser.AddFrame(f, positions, mesh_mask);
  return analyser.Finish();
}

// Per-frame XOR areas around `per_frame` px^2, fractional as the score's are.
RecordingScore Error(const std::string& recording, double per_frame, int frames) {
  RecordingScore e;
  e.recording = recording;
  for (int f = 0; f < frames; ++f) {
    e.frame_xor.push_back(per_frame + (f % 7) * 10 + 0.25 * (f % 3));
    e.frame_iou.push_back(0.9 + 0.001 * (f % 5));
    e.xor_sum += e.frame_xor.back();
  }
  e.mean_iou = 0.902;
  return e;
}

// A report as the loop would fill it, with an overlay PNG in `dir`.
LoopReport MakeReport(const fs::path& dir) {
  LoopReport r;
  r.title = "calib loop: test";
  r.command = "calib loop --train a --holdout b --out x";
  r.seed = 7;
  r.selection_rule = "keep an effect when the held-out XOR sum drops by more than 2%";
  r.run_time_s = 12.5;
  r.recordings = {{"a", "/data/a", "train", 40, 30.0, {}, {}, {}}, {"b", "/data/b", "holdout", 40, 30.0, {}, {}, {}}};

  ReportStage base;
  base.name = "base";
  base.decision = StageDecision::kBase;
  base.parameters = {{"k_D", 400.0}, {"tau", 0.1}};
  base.errors = {Error("a", 1000, 40), Error("b", 1200, 40)};
  base.criterion = "held-out XOR sum";
  base.criterion_value = static_cast<double>(base.errors[1].xor_sum);
  base.reason = "the paper's model";
  base.evaluations = 160;
  base.calibration_time_s = 3.0;
  base.equally_good = {9, 450.0, 1150, 1420, 1260, 0.91};
  base.restart_training_xor = {2100.0, 1000.0, 1003.0};
  base.holdout_sensitivity_px = 12.5;
  base.uninformative = true;
  base.at_bounds = {"tau = 0.5 (upper bound)"};
  // Recording a hangs from a clamp: its tip in the video and the models'.
  for (int f = 0; f < 40; ++f) {
    r.recordings[0].tip_x_px.push_back(150.0 + 10.0 * std::sin(0.5 * f));
    r.recordings[0].tip_y_px.push_back(200.0);
    base.errors[0].tip_x_px.push_back(140.0);
    base.errors[0].tip_y_px.push_back(200.0);
    // The mesh registered to each frame of the video.
    r.recordings[0].registered_iou.push_back(0.95 + 0.001 * (f % 3));
  }
  base.errors[0].median_tip_distance_px = 12.25;

  ReportStage plastic = base;
  plastic.restart_training_xor.clear();
  plastic.uninformative = false;
  plastic.at_bounds.clear();
  plastic.name = "base+plasticity";
  plastic.effect_tried = "plasticity";
  plastic.decision = StageDecision::kAccepted;
  plastic.effects = {"plasticity"};
  plastic.parameters["plastic_yield_strain"] = 0.04;
  plastic.errors = {Error("a", 600, 40), Error("b", 700, 40)};
  plastic.errors[0].tip_x_px = r.recordings[0].tip_x_px;
  plastic.errors[0].tip_y_px = r.recordings[0].tip_y_px;
  plastic.errors[0].median_tip_distance_px = 0.0;
  plastic.reason = "held-out XOR -42%";
  plastic.equally_good = {};
  plastic.holdout_sensitivity_parameter = "plastic_yield_strain";
  plastic.test = {40, 10, 500.0, 320.0, 680.0, 0.0004, 1, true};

  ReportStage friction = plastic;
  friction.name = "base+plasticity+table_friction";
  friction.effect_tried = "table_friction";
  friction.decision = StageDecision::kRejected;
  friction.effects = {"plasticity", "table_friction"};
  friction.errors = {Error("a", 590, 40), Error("b", 710, 40)};
  friction.reason = "held-out XOR +1%: no gain";
  friction.errors[1].status = "failed";
  friction.errors[1].failure_frame = 31;
  friction.errors[1].failure_reason = "triangle 9 stays inverted after 8 constraint iterations";
  r.stages = {base, plastic, friction};

  const ResidualAnalysis before = ShiftAnalysis("a", 6.0, 40);
  const ResidualAnalysis after = ShiftAnalysis("a", 2.0, 40);
  r.rounds.push_back({1, "base", TraceHypotheses(before, {})});
  r.rounds.push_back({2, "base+plasticity", TraceHypotheses(after, {"plasticity"})});
  r.effects_kept = {"plasticity"};
  r.residuals = {{"a", "base", before}, {"a", "base+plasticity", after}};

  fs::create_directories(dir / "overlays");
  cv::Mat image(60, 80, CV_8UC3, cv::Scalar(30, 90, 200));
  WriteImage(dir / "overlays" / "a_base_000012.png", image);
  r.overlays = {{"a", "base", 12, 1060, 0.9, "overlays/a_base_000012.png", "worst frame"}};
  r.notes = {"a note with <html> & \"quotes\""};
  return r;
}

bool HaveGnuplot() {
  std::string message;
  return GnuplotAvailable("gnuplot", &message);
}

TEST(LoopReport, JsonRoundTripsWithTheBeforeAfterTable) {
  const fs::path dir = testing::ScratchDir("loop_report_json");
  const LoopReport report = MakeReport(dir);
  WriteLoopReportJson(dir / "report.json", report);
  const LoopReport back = ReadLoopReportJson(dir / "report.json");
  EXPECT_EQ(ToJson(back).dump(), ToJson(report).dump());

  const nlohmann::json doc = nlohmann::json::parse(testing::ReadText(dir / "report.json"));
  EXPECT_EQ(doc["format"], "calib-loop-report/1");
  EXPECT_EQ(doc["effects_kept"], nlohmann::json::array({"plasticity"}));
  EXPECT_EQ(doc["final_model"], "base+plasticity") << "the last accepted stage";
  ASSERT_EQ(doc["error_table"].size(), 2u);
  const auto& row_b = doc["error_table"][1];
  EXPECT_EQ(row_b["recording"], "b");
  EXPECT_EQ(row_b["role"], "holdout");
  EXPECT_EQ(row_b["before"]["xor_sum"], report.stages[0].errors[1].xor_sum);
  EXPECT_EQ(row_b["after"]["xor_sum"], report.stages[1].errors[1].xor_sum);
  EXPECT_DOUBLE_EQ(row_b["after"]["mean_iou"].get<double>(), 0.902);
  EXPECT_DOUBLE_EQ(doc["final_parameters"]["plastic_yield_strain"].get<double>(), 0.04);
  // The held-out spread of equally good fits, where it was measured only.
  EXPECT_EQ(doc["stages"][0]["equally_good"]["fits"], 9);
  EXPECT_EQ(doc["stages"][0]["equally_good"]["holdout_xor_max"], 1420);
  EXPECT_FALSE(doc["stages"][1].contains("equally_good"));
  EXPECT_EQ(back.stages[1].equally_good.fits, 0);
  // The base model's independent searches, where there were several.
  EXPECT_EQ(doc["stages"][0]["restart_training_xor"], nlohmann::json::array({2100.0, 1000.0, 1003.0}));
  // The registered mesh's IoU: for the recording that has it only.
  ASSERT_EQ(doc["recordings"][0]["registered_iou"].size(), 40u);
  EXPECT_DOUBLE_EQ(doc["recordings"][0]["registered_iou"][1].get<double>(), 0.95 + 0.001);
  EXPECT_FALSE(doc["recordings"][1].contains("registered_iou"));
  EXPECT_EQ(back.recordings[0].registered_iou, report.recordings[0].registered_iou);
  // The text table sets the final model's IoU beside it, over the whole
  // recording and its first second (30 frames at 30 fps): the registered
  // mesh's mean over 0.950, 0.951, 0.952, ...
  const std::string table = BeforeAfterTable(report);
  EXPECT_NE(table.find("a: mean IoU 0.9020 (first second 0.9020); the mesh registered to the "
                       "video 0.9510 (0.9510)"),
            std::string::npos)
      << table;
  EXPECT_EQ(table.find("b: mean IoU"), std::string::npos) << table;
  EXPECT_FALSE(doc["stages"][1].contains("restart_training_xor"));
  EXPECT_EQ(doc["stages"][0]["holdout_sensitivity_px"], 12.5);
  EXPECT_EQ(back.stages[0].holdout_sensitivity_px, 12.5);
  EXPECT_EQ(back.stages[1].holdout_sensitivity_px, 12.5);  // copied from base above
  EXPECT_EQ(back.stages[1].holdout_sensitivity_parameter, "plastic_yield_strain");
  // The keep rule's test, for tried stages only.
  EXPECT_FALSE(doc["stages"][0].contains("test"));
  EXPECT_EQ(doc["stages"][1]["test"]["p_value"], 0.0004);
  EXPECT_EQ(back.stages[1].test.frames, 40);
  EXPECT_EQ(back.stages[1].test.blocks, 10);
  EXPECT_EQ(back.stages[1].test.drop_low, 320.0);
  EXPECT_EQ(back.stages[1].test.drop_high, 680.0);
  EXPECT_EQ(back.stages[1].test.hypotheses, 1);
  EXPECT_TRUE(back.stages[1].test.significant);
  // Hypotheses with their evidence.
  const auto& first = doc["rounds"][0]["hypotheses"][0];
  EXPECT_TRUE(first.contains("confidence"));
  EXPECT_GE(first["evidence"].size(), 2u);
  EXPECT_FALSE(first["evidence"][0]["statement"].get<std::string>().empty());
  // Round 2 leaves out the effect already in the model.
  for (const auto& h : doc["rounds"][1]["hypotheses"]) EXPECT_NE(h["effect"], "plasticity");
  // The residuals are written without per-frame records.
  EXPECT_FALSE(doc["residuals"][0]["analysis"].contains("frames"));
  // A failed simulation keeps its frame and reason; the others have none.
  EXPECT_EQ(doc["stages"][2]["errors"][1]["failure_frame"], 31);
  EXPECT_EQ(back.stages[2].errors[1].failure_reason, "triangle 9 stays inverted after 8 constraint iterations");
  EXPECT_FALSE(doc["stages"][2]["errors"][0].contains("failure_frame"));
  EXPECT_EQ(back.stages[2].errors[0].failure_frame, -1);
  // What the calibration's history says, where it says something.
  EXPECT_EQ(doc["stages"][0]["uninformative"], true);
  EXPECT_EQ(doc["stages"][0]["at_bounds"], nlohmann::json::array({"tau = 0.5 (upper bound)"}));
  EXPECT_FALSE(doc["stages"][1].contains("uninformative"));
  EXPECT_FALSE(doc["stages"][1].contains("at_bounds"));
  EXPECT_TRUE(back.stages[0].uninformative);
  // The tips, for the recording held by a clamp only.
  EXPECT_EQ(doc["recordings"][0]["tip_x_px"].size(), 40u);
  EXPECT_FALSE(doc["recordings"][1].contains("tip_x_px"));
  EXPECT_EQ(back.recordings[0].tip_x_px, report.recordings[0].tip_x_px);
  EXPECT_EQ(back.stages[0].errors[0].median_tip_distance_px, 12.25);
  EXPECT_EQ(back.stages[0].errors[0].tip_x_px.size(), 40u);
  EXPECT_TRUE(std::isnan(back.stages[0].errors[1].median_tip_distance_px));
}

// The message LoopReportFromJson throws for `doc`, or "accepted".
std::string Rejection(const nlohmann::json& doc) {
  try {
    LoopReportFromJson(doc);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

TEST(LoopReport, MalformedJsonNamesTheKey) {
  const fs::path dir = testing::ScratchDir("loop_report_bad");
  nlohmann::json doc = ToJson(MakeReport(dir));
  doc["stages"][1].erase("decision");
  EXPECT_NE(Rejection(doc).find("stages[1].decision"), std::string::npos) << Rejection(doc);
  doc = ToJson(MakeReport(dir));
  doc["stages"][0]["equally_good"]["fits"] = 0;
  EXPECT_NE(Rejection(doc).find("stages[0].equally_good.fits"), std::string::npos) << Rejection(doc);
  doc = ToJson(MakeReport(dir));
  doc["stages"][0]["equally_good"].erase("holdout_xor_median");
  EXPECT_NE(Rejection(doc).find("stages[0].equally_good.holdout_xor_median"), std::string::npos) << Rejection(doc);
  doc = ToJson(MakeReport(dir));
  doc["stages"][0]["holdout_sensitivity_px"] = -1.0;
  EXPECT_NE(Rejection(doc).find("stages[0].holdout_sensitivity_px"), std::string::npos) << Rejection(doc);
  doc = ToJson(MakeReport(dir));
  doc["stages"][1]["test"]["p_value"] = 1.5;
  EXPECT_NE(Rejection(doc).find("stages[1].test.p_value"), std::string::npos) << Rejection(doc);
  doc = ToJson(MakeReport(dir));
  doc["stages"][1]["test"]["significant"] = "yes";
  EXPECT_NE(Rejection(doc).find("stages[1].test.significant"), std::string::npos) << Rejection(doc);
  doc = ToJson(MakeReport(dir));
  doc["stages"][0]["restart_training_xor"][1] = "low";
  EXPECT_NE(Rejection(doc).find("stages[0].restart_training_xor[1]"), std::string::npos) << Rejection(doc);
  doc = ToJson(MakeReport(dir));
  doc["stages"][2]["decision"] = "maybe";
  EXPECT_THROW(LoopReportFromJson(doc), std::invalid_argument);
  EXPECT_THROW(ReadLoopReportJson(dir / "absent.json"), std::runtime_error);
}

TEST(LoopReport, StagesAndWorstFrames) {
  const LoopReport report = MakeReport(testing::ScratchDir("loop_report_stages"));
  ASSERT_NE(report.FinalStage(), nullptr);
  EXPECT_EQ(report.FinalStage()->name, "base+plasticity");
  EXPECT_EQ(report.BaseStage()->name, "base");
  EXPECT_EQ(LoopReport().FinalStage(), nullptr);
  EXPECT_EQ(WorstFrames({5, 9, 8, 1, 9, 3, 7}, 3, 2), (std::vector<int>{1, 4, 6}));
  EXPECT_EQ(WorstFrames({5, 9, 8}, 5, 1), (std::vector<int>{1, 2, 0}));
  EXPECT_EQ(StageDecisionFromString(ToString(StageDecision::kRejected)), StageDecision::kRejected);
}

TEST(LoopReportHtml, EmbedsGnuplotSvgPlots) {
  if (!HaveGnuplot()) GTEST_SKIP() << "gnuplot is not installed (Debian: gnuplot-nox)";
  const fs::path dir = testing::ScratchDir("loop_report_html");
  const LoopReport report = MakeReport(dir);
  const HtmlReportSummary summary = WriteLoopReport(dir, report);
  EXPECT_TRUE(summary.plots_made) << summary.plot_message;
  // Bars, two per-frame error plots, two per-frame IoU plots, two heat
  // maps, and the tip of the recording held by a clamp.
  EXPECT_EQ(summary.plots, 8);
  EXPECT_EQ(summary.overlays, 1);
  const std::string html = testing::ReadText(dir / "report.html");
  EXPECT_EQ(Count(html, "<svg"), summary.plots);
  EXPECT_EQ(Count(html, "</svg>"), summary.plots);
  EXPECT_EQ(html.find("<?xml"), std::string::npos) << "SVG inlined without its prologue";
  EXPECT_NE(html.find("<image"), std::string::npos) << "heat maps are gnuplot images";
  EXPECT_NE(html.find("src=\"overlays/a_base_000012.png\""), std::string::npos);
  EXPECT_NE(html.find("base+plasticity"), std::string::npos);
  EXPECT_NE(html.find("3 independent searches, best training XOR of each: 2100, 1000, 1003"),
            std::string::npos);
  EXPECT_NE(html.find(fmt::format(">{:.0f}<", report.stages[1].errors[1].xor_sum)),
            std::string::npos)
      << "XOR sums rounded to whole px^2 in the table";
  EXPECT_NE(html.find("a note with &lt;html&gt; &amp; &quot;quotes&quot;"), std::string::npos);
  EXPECT_NE(html.find("<b>uninformative</b>"), std::string::npos);
  EXPECT_NE(html.find("on the box's bound: tau = 0.5 (upper bound)"), std::string::npos);
  EXPECT_NE(html.find("The tip across the image over time"), std::string::npos);
  EXPECT_NE(html.find("base model, final model and the mesh registered to each frame"),
            std::string::npos)
      << "recording a's IoU plot has the registered mesh";
  EXPECT_EQ(html.find("This report has no plots"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "report.json"));

  // Same report, same bytes.
  const fs::path again = testing::ScratchDir("loop_report_html_again");
  MakeReport(again);
  WriteLoopReport(again, report);
  EXPECT_EQ(testing::ReadText(again / "report.html"), html);
  EXPECT_EQ(testing::ReadText(again / "report.json"), testing::ReadText(dir / "report.json"));

  // Embedded overlays.
  HtmlReportOptions embed;
  embed.embed_images = true;
  WriteLoopReportHtml(dir / "embedded.html", report, embed);
  EXPECT_NE(testing::ReadText(dir / "embedded.html").find("src=\"data:image/png;base64,iVBORw0KGgo"),
            std::string::npos);
}

TEST(LoopReportHtml, WithoutGnuplotSaysSoOrThrows) {
  const fs::path dir = testing::ScratchDir("loop_report_nognuplot");
  const LoopReport report = MakeReport(dir);
  HtmlReportOptions options;
  options.gnuplot.executable = (dir / "no-such-gnuplot").string();
  const HtmlReportSummary summary = WriteLoopReportHtml(dir / "report.html", report, options);
  EXPECT_FALSE(summary.plots_made);
  EXPECT_EQ(summary.plots, 0);
  const std::string html = testing::ReadText(dir / "report.html");
  EXPECT_EQ(html.find("<svg"), std::string::npos);
  EXPECT_NE(html.find("This report has no plots"), std::string::npos);
  EXPECT_NE(html.find("gnuplot-nox"), std::string::npos);
  EXPECT_NE(html.find("<table>"), std::string::npos) << "the tables are still there";

  options.require_plots = true;
  try {
    WriteLoopReportHtml(dir / "report2.html", report, options);
    FAIL() << "require_plots without gnuplot must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("gnuplot-nox"), std::string::npos) << e.what();
  }
}

TEST(Gnuplot, RendersSvgAndReportsErrors) {
  if (!HaveGnuplot()) GTEST_SKIP() << "gnuplot is not installed (Debian: gnuplot-nox)";
  const std::string script =
      Datablock("d", {{0, 1}, {1, 3}, {2, NAN}, {3, 2}}) + "plot $d using 1:2 with lines title " +
      GnuplotQuote("a \"quoted\" title_with_underscores") + "\n";
  const std::string svg = RenderSvg(script, GnuplotOptions{});
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("title_with_underscores"), std::string::npos);
  EXPECT_EQ(RenderSvg(script, GnuplotOptions{}), svg) << "deterministic";
  try {
    RenderSvg("plot $nothing using 1:2\n", GnuplotOptions{});
    FAIL() << "a bad script must throw";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("gnuplot"), std::string::npos) << e.what();
  }
  GnuplotOptions bad;
  bad.width_px = 10;
  EXPECT_THROW(RenderSvg(script, bad), std::invalid_argument);
}

}  // namespace
}  // namespace calib
