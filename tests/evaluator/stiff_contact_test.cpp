// The stiff regime's contact on a whole recording: with the implicit step a
// calibrated stiff mesh moves 10-20 px a substep where it touches the finger
// (its springs undo the finger's dent, the projection puts it back), more
// than the pencil's 9 px radius. Resolved from the end of the step alone,
// the mesh went through the pencil in the hold of examples/push_centre at
// these values and then lay across it for the rest of the video (XOR sum
// 3.65 M against 0.86 M at friction 0.2).

#include "calib/evaluator/evaluation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

namespace calib {
namespace {

TEST(StiffContact, TheMeshNeverCoversAnObstacleCentre) {
  const Recording recording =
      LoadRecording(std::filesystem::path(CALIB_SOURCE_DIR) / "examples/push_centre");
  PreparationOptions preparation;
  preparation.cache_dir.clear();
  const PreparedRecording prepared = PrepareRecording(recording, preparation);
  ASSERT_GT(prepared.scene.num_obstacles, 0);

  SimulationOptions options;
  options.integrator = IntegratorKind::kImplicitFirstOrder;
  options.outline_contact = true;
  Evaluator evaluator(prepared, options, ModelDefinition{{"table_friction"}});
  // A stiff calibration of push_centre (k_D / k_d / k_A / k_phi hundreds of
  // times the explicit step's) with the table's friction.
  const ParameterValues values = {{"k_D", 90581.063097572},    {"k_d", 20.754982960562106},
                                  {"k_A", 210.80891451878225},  {"k_phi", 12379.743243423809},
                                  {"mass", 0.2},                {"tau", 0.3421273516392307},
                                  {"friction_force", 0.45}};
  int covered_frames = 0;
  const EvaluationResult result = evaluator.Evaluate(
      values, [&](int frame, const Simulator& sim, const BitMask& mesh_mask, const FrameScore&) {
        for (const Disc& disc : sim.obstacles()) {
          const int x = static_cast<int>(std::floor(disc.centre.x())) - mesh_mask.origin_x();
          const int y = static_cast<int>(std::floor(disc.centre.y())) - mesh_mask.origin_y();
          if (x < 0 || y < 0 || x >= mesh_mask.width() || y >= mesh_mask.height()) continue;
          if (mesh_mask.Get(x, y)) {
            ++covered_frames;
            ADD_FAILURE() << "frame " << frame << ": the mesh covers the obstacle at ("
                          << disc.centre.x() << ", " << disc.centre.y() << ")";
            return;
          }
        }
      });
  ASSERT_TRUE(result.ok()) << result.failure_reason;
  EXPECT_EQ(covered_frames, 0);
  // It follows the sponge: mean IoU over the video as the calibration's.
  EXPECT_GT(result.mean_iou, 0.96);
}

}  // namespace
}  // namespace calib
