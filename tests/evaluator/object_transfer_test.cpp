// Another recording of the same object gets the calibrated recording's
// model (object_transfer.h): the bundled hanging strip released from two
// poses. A recording that is not of that object keeps its own mesh, and
// says why.

#include "calib/evaluator/object_transfer.h"

#include "calib/core/mesher.h"
#include "calib/evaluator/bit_mask_cv.h"
#include "calib/evaluator/contour.h"
#include "calib/evaluator/recording.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <filesystem>
#include <memory>
#include <string>

namespace calib {
namespace {

std::filesystem::path Example(const std::string& name) {
  return std::filesystem::path(CALIB_SOURCE_DIR) / "examples" / name;
}

class ObjectTransferTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    PreparationOptions options;
    options.cache_dir.clear();
    from_ = std::make_unique<PreparedRecording>(
        PrepareRecording(LoadRecording(Example("hang_gravity")), options));
    to_ = std::make_unique<PreparedRecording>(
        PrepareRecording(LoadRecording(Example("hang_gravity_b")), options));
  }
  static void TearDownTestSuite() {
    from_.reset();
    to_.reset();
  }
  static constexpr double kWindowS = 1.0;
  static std::unique_ptr<PreparedRecording> from_, to_;
};

std::unique_ptr<PreparedRecording> ObjectTransferTest::from_, ObjectTransferTest::to_;

TEST_F(ObjectTransferTest, AnotherRecordingOfTheObjectGetsItsMeshRestShapeAndAreas) {
  PreparedRecording to = *to_;
  ASSERT_NE(to.mesh.NumNodes(), 0);
  const ObjectTransfer transfer = CarryObjectModel(*from_, to, kWindowS);
  ASSERT_TRUE(transfer.carried) << transfer.reason;
  EXPECT_NE(transfer.reason.find("hang_gravity_b: another recording of the object of hang_gravity"),
            std::string::npos)
      << transfer.reason;
  // The lattice is the training recording's, at the new recording's pose:
  // on its frame-0 outline, nodes in the same clamps.
  // The synthetic swing's masks show no motion blur: scored as simulated,
  // started from the mesh itself.
  EXPECT_EQ(from_->motion_blur_frames, 0.0);
  EXPECT_TRUE(to.scene.motion.node_start_px.empty());
  EXPECT_EQ(to.mesh.triangles, from_->mesh.triangles);
  EXPECT_EQ(to.mesh.edges, from_->mesh.edges);
  EXPECT_GE(transfer.outline_distance_px, 0.0);
  EXPECT_LT(transfer.outline_distance_px, 0.5);
  EXPECT_EQ(ClampedNodes(to.mesh, to.scene), ClampedNodes(from_->mesh, from_->scene));
  double moved = 0.0;
  for (int i = 0; i < to.mesh.NumNodes(); ++i) {
    moved = std::max(moved, (to.mesh.rest_positions[i] - from_->mesh.rest_positions[i]).norm());
  }
  EXPECT_GT(moved, 20.0) << "frame 0 of the other release is another pose";
  // The rest shape and the element areas are the object's, from the
  // calibrated recording; the start is the new recording's own.
  EXPECT_EQ(to.scene.motion.node_rest_px, from_->scene.motion.node_rest_px);
  EXPECT_EQ(to.scene.motion.element_area_px2, from_->mesh.rest_area_px2);
  ASSERT_EQ(to.scene.motion.node_velocity_px_s.size(), static_cast<size_t>(to.mesh.NumNodes()));
  double speed = 0.0;
  for (const Vec2& v : to.scene.motion.node_velocity_px_s) speed = std::max(speed, v.norm());
  EXPECT_GT(speed, 0.0);
  // The rest of the recording is its own.
  EXPECT_EQ(to.object_masks.size(), to_->object_masks.size());
  EXPECT_EQ(to.recording.folder, to_->recording.folder);

  // Carried again from a recording that was itself carried to: the
  // element areas stay the first recording's.
  PreparedRecording again = *to_;
  ASSERT_TRUE(CarryObjectModel(to, again, kWindowS).carried);
  EXPECT_EQ(again.scene.motion.element_area_px2, from_->mesh.rest_area_px2);
}

TEST_F(ObjectTransferTest, AnObjectOfAnotherOutlineKeepsItsOwnMesh) {
  // The same release of a strip 8 px wider all round, meshed and tracked
  // on its own as PrepareRecording does.
  PreparedRecording to = *to_;
  const cv::Mat disc = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(17, 17));
  for (BitMask& m : to.object_masks) {
    cv::Mat mask = ToMat(m);
    cv::dilate(mask, mask, disc);
    m = FromMat(mask, m.origin_x(), m.origin_y());
  }
  to.outline = ObjectOutline(to.object_masks[0], PreparationOptions{}.outline_tolerance_px);
  MesherOptions mesher;
  mesher.held_regions = to.scene.clamps;
  to.mesh = MeshPolygon(to.outline, mesher);
  TrackObservedMotion(to, kWindowS);
  const int nodes = to.mesh.NumNodes();
  const auto rest = to.scene.motion.node_rest_px;
  const ObjectTransfer transfer = CarryObjectModel(*from_, to, kWindowS);
  EXPECT_FALSE(transfer.carried);
  EXPECT_GT(transfer.rest_area_change, kMaxCarriedRestAreaChange);
  EXPECT_NE(transfer.reason.find("hang_gravity_b: its own mesh and rest shape (its own rest shape's area"),
            std::string::npos)
      << transfer.reason;
  // The registration alone would not tell: a mesh reaches a wider outline
  // by stretching.
  EXPECT_EQ(to.mesh.NumNodes(), nodes);
  EXPECT_EQ(to.scene.motion.node_rest_px, rest);
  EXPECT_TRUE(to.scene.motion.element_area_px2.empty());
}

TEST_F(ObjectTransferTest, OtherClampsOrNoTrackedMotionKeepTheirOwnMesh) {
  PreparedRecording moved_clamp = *to_;
  moved_clamp.scene.clamps.front().x += 5.0;
  ObjectTransfer transfer = CarryObjectModel(*from_, moved_clamp, kWindowS);
  EXPECT_FALSE(transfer.carried);
  EXPECT_NE(transfer.reason.find("not held in the clamps of hang_gravity"), std::string::npos)
      << transfer.reason;

  PreparedRecording untracked_from = *from_;
  untracked_from.scene.motion.node_rest_px.clear();
  PreparedRecording to = *to_;
  transfer = CarryObjectModel(untracked_from, to, kWindowS);
  EXPECT_FALSE(transfer.carried);
  EXPECT_NE(transfer.reason.find("hang_gravity has no tracked rest shape"), std::string::npos)
      << transfer.reason;

  PreparedRecording untracked_to = *to_;
  untracked_to.scene.motion.node_rest_px.clear();
  transfer = CarryObjectModel(*from_, untracked_to, kWindowS);
  EXPECT_FALSE(transfer.carried);
  EXPECT_NE(transfer.reason.find("its motion was not tracked"), std::string::npos) << transfer.reason;
  EXPECT_EQ(untracked_to.mesh.NumNodes(), to_->mesh.NumNodes());
}

}  // namespace
}  // namespace calib
