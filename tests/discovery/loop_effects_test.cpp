// The loop on the bundled synthetic recordings with one effect switched on
// (and nothing declared): it names the effect actually present and lowers
// the held-out error. truth.json is read here only to check the answer.

#include "loop_test_support.h"

#include "calib/core/mesh.h"
#include "calib/discovery/signals.h"
#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/recording.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>

#include <string>

namespace calib {
namespace {

using testing::ExamplesDir;

// With `out`, the loop's result is kept there for further checks.
void ExpectNamed(const std::string& train, const std::string& holdout, LoopResult* out = nullptr) {
  const auto train_dir = ExamplesDir() / train;
  const auto holdout_dir = ExamplesDir() / holdout;
  if (!std::filesystem::exists(train_dir / "truth.json") ||
      !std::filesystem::exists(holdout_dir / "recording.json")) {
    GTEST_FAIL() << "missing bundled example " << train_dir << " or " << holdout_dir;
  }
  const std::vector<std::string> truth = testing::TrueEffects(train_dir);
  ASSERT_EQ(truth.size(), 1u) << train << ": expected one effect in truth.json";
  const LoopOptions options = testing::TestLoopOptions({train_dir}, {holdout_dir}, "loop_" + train);
  LoopResult result = RunLoop(options);
  const LoopReport& report = result.report;
  SCOPED_TRACE(result.table);
  ASSERT_FALSE(report.effects_kept.empty()) << train << ": no effect kept; truth: " << truth[0];
  EXPECT_EQ(report.effects_kept.front(), truth[0]);
  const ReportStage* base = report.BaseStage();
  const ReportStage* final_stage = report.FinalStage();
  ASSERT_NE(base, nullptr);
  ASSERT_NE(final_stage, nullptr);
  EXPECT_LT(testing::HeldOutXor(*final_stage, report), testing::HeldOutXor(*base, report));
  // The evidence behind it is in the report.
  ASSERT_FALSE(report.rounds.empty());
  bool traced = false;
  for (const Hypothesis& h : report.rounds.front().hypotheses) traced |= h.effect == truth[0];
  EXPECT_TRUE(traced);
  EXPECT_TRUE(std::filesystem::exists(result.report_json));
  // A stage said to pass but not kept passed every part of the criterion.
  for (const ReportStage& stage : report.stages) {
    if (stage.reason.find("passes, but") == std::string::npos) continue;
    EXPECT_EQ(stage.reason.find("(rose:"), std::string::npos) << stage.reason;
    EXPECT_EQ(stage.reason.find("(fell"), std::string::npos) << stage.reason;
  }
  if (out != nullptr) *out = std::move(result);
}

// Inertia with gravity (a strip released from a bend, swinging) is named
// and kept with the loop's default simulation (the implicit step holding
// its contacts, outline contact, contact friction). Whether the loop names
// and keeps each of the other bundled pairs' effects (plasticity,
// viscoelastic relaxation, uneven stiffness, strong friction with the
// table, strain stiffening) is a benchmark, not a test: ten minutes of two
// cores per pair, and a detection rate rather than a yes or no
// (`calib loop-benchmark examples/bundled`, docs/loop.md "The bundled
// pairs").
TEST(LoopOnSyntheticEffect, InertiaWithGravity) {
  LoopResult result;
  ExpectNamed("hang_gravity", "hang_gravity_b", &result);
  if (HasFatalFailure()) return;
  const LoopReport& report = result.report;
  const ReportStage* final_stage = report.FinalStage();
  ASSERT_NE(final_stage, nullptr);
  SCOPED_TRACE(result.table);

  // The calibrated model swings as the truth does: its own simulated
  // swing (the mesh's centroid across the image) has the truth's period,
  // and keeps as much of its amplitude over the recording, each within 5 %.
  const auto train_dir = ExamplesDir() / "hang_gravity";
  PreparationOptions preparation;
  preparation.cache_dir.clear();
  const PreparedRecording prepared = PrepareRecording(LoadRecording(train_dir), preparation);
  SimulationOptions simulation = LoopOptions{}.simulation;
  simulation.area_weighted = true;  // the loop's, for a hanging object
  Evaluator evaluator(prepared, simulation, ModelDefinition{final_stage->effects});
  std::vector<double> model_x;
  const EvaluationResult evaluation = evaluator.Evaluate(
      final_stage->parameters,
      [&](int, const Simulator& sim, const BitMask&, const FrameScore&) {
        model_x.push_back(AreaCentroid(prepared.mesh, sim.positions()).x());
      });
  ASSERT_TRUE(evaluation.ok()) << evaluation.failure_reason;

  std::ifstream in(train_dir / "truth.json");
  const nlohmann::json truth = nlohmann::json::parse(in);
  const double fps = truth.at("scenario").at("fps").get<double>();
  std::vector<double> truth_x;
  for (const auto& frame : truth.at("frames")) {
    truth_x.push_back(frame.at("centroid_px").at(0).get<double>());
  }
  ASSERT_EQ(truth_x.size(), model_x.size());
  const Oscillation truth_swing = DetectOscillation(truth_x, fps);
  const Oscillation model_swing = DetectOscillation(model_x, fps);
  ASSERT_TRUE(truth_swing.found);
  ASSERT_TRUE(model_swing.found);
  EXPECT_NEAR(model_swing.period_s, truth_swing.period_s, 0.05 * truth_swing.period_s);
  const double duration_s = static_cast<double>(truth_x.size()) / fps;
  const double truth_kept = std::exp(-truth_swing.decay_per_s * duration_s);
  const double model_kept = std::exp(-model_swing.decay_per_s * duration_s);
  EXPECT_NEAR(model_kept, truth_kept, 0.05 * truth_kept)
      << "decay: model " << model_swing.decay_per_s << "/s, truth " << truth_swing.decay_per_s
      << "/s";

  // The release from another pose, held out, is predicted at mean IoU 0.90
  // or better (0.9765 here, seed 1). It is simulated with the training
  // recording's mesh, rest shape and element areas (object_transfer.h);
  // meshed on its own from its more bent frame 0 it swung 1.9 % slower at
  // the same parameters and drifted out of phase (0.887).
  const auto* held_out = final_stage->ErrorOn("hang_gravity_b");
  ASSERT_NE(held_out, nullptr);
  EXPECT_GE(held_out->mean_iou, 0.90);
  bool carried = false;
  for (const std::string& note : report.notes) {
    carried |= note.find("hang_gravity_b: another recording of the object of hang_gravity") == 0;
  }
  EXPECT_TRUE(carried) << "the report says the held-out release was simulated with the training mesh";

  // The model's tip is taken as the video's: the farthest pixel (centre) of
  // the mesh as scored, not its farthest node, so that the two are measured
  // alike (a node lies up to a pixel beyond the covered pixels' centres).
  // Median distances to the video's tip, training / held out: 4.47 / 5.10
  // px, against 5.77 / 5.38 from the farthest node.
  for (const RecordingScore& e : final_stage->errors) {
    SCOPED_TRACE(e.recording);
    ASSERT_EQ(e.tip_x_px.size(), e.frame_iou.size());
    for (size_t f = 0; f < e.tip_x_px.size(); ++f) {
      ASSERT_EQ(e.tip_x_px[f] - std::floor(e.tip_x_px[f]), 0.5) << "frame " << f;
      ASSERT_EQ(e.tip_y_px[f] - std::floor(e.tip_y_px[f]), 0.5) << "frame " << f;
    }
  }
}

}  // namespace
}  // namespace calib
