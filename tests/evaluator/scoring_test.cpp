#include "calib/evaluator/scoring.h"

#include <gtest/gtest.h>

#include <random>

namespace calib {
namespace {

TEST(CompareMasks, CountsHandMadeMasks) {
  // Object: row 0 pixels [0, 10); mesh: row 0 pixels [6, 14) and pixel (100, 2).
  BitMask object(130, 4), mesh(130, 4);
  object.SetSpan(0, 0, 10);
  mesh.SetSpan(0, 6, 14);
  mesh.Set(100, 2);
  const FrameScore s = CompareMasks(object, mesh);
  EXPECT_EQ(s.object_px, 10);
  EXPECT_EQ(s.mesh_px, 9);
  EXPECT_EQ(s.missed_px, 6) << "object pixels 0..5";
  EXPECT_EQ(s.extra_px, 5) << "mesh pixels 10..13 and (100, 2)";
  EXPECT_EQ(s.xor_px, 11);
  EXPECT_DOUBLE_EQ(s.iou, 4.0 / 15.0);
}

TEST(CompareMasks, IdenticalMasksAgreeCompletely) {
  BitMask a(77, 13, 5, -2);
  a.SetSpan(3, 10, 70);
  a.SetSpan(12, 0, 77);
  const FrameScore s = CompareMasks(a, a);
  EXPECT_EQ(s.xor_px, 0);
  EXPECT_EQ(s.missed_px, 0);
  EXPECT_EQ(s.extra_px, 0);
  EXPECT_EQ(s.object_px, 137);
  EXPECT_EQ(s.mesh_px, 137);
  EXPECT_EQ(s.iou, 1.0);
}

TEST(CompareMasks, BothEmptyIsPerfectAgreement) {
  const FrameScore s = CompareMasks(BitMask(64, 8), BitMask(64, 8));
  EXPECT_EQ(s.xor_px, 0);
  EXPECT_EQ(s.iou, 1.0);
  const FrameScore none = CompareMasks(BitMask(), BitMask());
  EXPECT_EQ(none.iou, 1.0);
}

TEST(CompareMasks, DisjointMasksHaveZeroIou) {
  BitMask object(200, 5), mesh(200, 5);
  object.SetSpan(1, 0, 100);
  mesh.SetSpan(1, 100, 200);
  mesh.SetSpan(4, 0, 3);
  const FrameScore s = CompareMasks(object, mesh);
  EXPECT_EQ(s.iou, 0.0);
  EXPECT_EQ(s.missed_px, 100);
  EXPECT_EQ(s.extra_px, 103);
  EXPECT_EQ(s.xor_px, 203);
  // One side empty: IoU 0, everything on the other side counts.
  const FrameScore empty_mesh = CompareMasks(object, BitMask(200, 5));
  EXPECT_EQ(empty_mesh.iou, 0.0);
  EXPECT_EQ(empty_mesh.missed_px, 100);
  EXPECT_EQ(empty_mesh.extra_px, 0);
}

TEST(CompareMasks, AgreesWithAPerPixelLoopOnRandomMasks) {
  std::mt19937_64 rng(20240611);
  for (const auto& [w, h] : {std::pair{1, 1}, std::pair{63, 7}, std::pair{64, 9},
                             std::pair{65, 10}, std::pair{190, 33}, std::pair{640, 48}}) {
    for (int density_bits : {1, 2, 4}) {
      BitMask object(w, h, 3, 4), mesh(w, h, 3, 4);
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          // Pixel on with probability 1 / 2^density_bits (object) and 1/2 (mesh).
          object.Set(x, y, (rng() >> (64 - density_bits)) == 0);
          mesh.Set(x, y, (rng() >> 63) != 0);
        }
      }
      int64_t missed = 0, extra = 0, both = 0, object_px = 0, mesh_px = 0;
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          const bool o = object.Get(x, y), m = mesh.Get(x, y);
          missed += o && !m;
          extra += m && !o;
          both += o && m;
          object_px += o;
          mesh_px += m;
        }
      }
      const FrameScore s = CompareMasks(object, mesh);
      EXPECT_EQ(s.missed_px, missed) << w << "x" << h;
      EXPECT_EQ(s.extra_px, extra) << w << "x" << h;
      EXPECT_EQ(s.xor_px, missed + extra) << w << "x" << h;
      EXPECT_EQ(s.object_px, object_px) << w << "x" << h;
      EXPECT_EQ(s.mesh_px, mesh_px) << w << "x" << h;
      const int64_t union_px = missed + extra + both;
      EXPECT_DOUBLE_EQ(s.iou, union_px == 0 ? 1.0 : double(both) / double(union_px))
          << w << "x" << h;
    }
  }
}

TEST(CompareMasksDeathTest, DifferentShapesAbort) {
  EXPECT_DEATH(CompareMasks(BitMask(10, 10), BitMask(10, 11)), "differ in shape");
  EXPECT_DEATH(CompareMasks(BitMask(10, 10, 0, 0), BitMask(10, 10, 1, 0)), "differ in shape");
}

}  // namespace
}  // namespace calib
