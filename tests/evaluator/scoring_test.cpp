#include "calib/evaluator/scoring.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace calib {
namespace {

// Two bit masks: the areas are pixel counts.
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

// The score with sub-pixel coverage: boundary pixels count their covered
// fraction (FrameScore's definitions, pixel by pixel).
TEST(CompareCoverage, CountsHandMadeCoverage) {
  // Object: row 0 pixels [0, 4). Mesh: pixels 0 and 1 in full, 2 a quarter,
  // 5 a half.
  BitMask object(70, 2), interior(70, 2);
  object.SetSpan(0, 0, 4);
  interior.SetSpan(0, 0, 2);
  const std::vector<PixelCoverage> boundary = {{2, 0, 0.25}, {5, 0, 0.5}};
  const FrameScore s = CompareCoverage(object, interior, boundary);
  EXPECT_DOUBLE_EQ(s.missed_px, 0.75 + 1.0) << "three quarters of pixel 2, all of pixel 3";
  EXPECT_DOUBLE_EQ(s.extra_px, 0.5) << "half of pixel 5";
  EXPECT_DOUBLE_EQ(s.xor_px, 2.25);
  EXPECT_DOUBLE_EQ(s.object_px, 4.0);
  EXPECT_DOUBLE_EQ(s.mesh_px, 2.75);
  EXPECT_DOUBLE_EQ(s.iou, 2.25 / 4.5) << "intersection 2.25, union 4 + 2.75 - 2.25";
}

TEST(CompareCoverage, AgreesWithAPerPixelSumOnRandomCoverage) {
  std::mt19937_64 rng(20240612);
  for (const auto& [w, h] : {std::pair{1, 1}, std::pair{63, 7}, std::pair{65, 10},
                             std::pair{190, 33}}) {
    BitMask object(w, h, -2, 5), interior(w, h, -2, 5);
    std::vector<PixelCoverage> boundary;
    std::vector<double> coverage(static_cast<size_t>(w) * h, 0.0);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        object.Set(x, y, (rng() >> 63) != 0);
        const int kind = static_cast<int>(rng() % 3);  // empty, full, in part
        double& c = coverage[static_cast<size_t>(y) * w + x];
        if (kind == 1) {
          interior.Set(x, y);
          c = 1.0;
        } else if (kind == 2) {
          c = (static_cast<double>(rng() >> 11) + 1.0) * 0x1.0p-53;  // in (0, 1)
          boundary.push_back({x, y, c});
        }
      }
    }
    double xor_px = 0.0, missed = 0.0, extra = 0.0, object_px = 0.0, mesh_px = 0.0, both = 0.0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const double o = object.Get(x, y) ? 1.0 : 0.0;
        const double c = coverage[static_cast<size_t>(y) * w + x];
        xor_px += std::abs(o - c);
        missed += o * (1.0 - c);
        extra += (1.0 - o) * c;
        object_px += o;
        mesh_px += c;
        both += o * c;
      }
    }
    const FrameScore s = CompareCoverage(object, interior, boundary);
    const double tolerance = 1e-9 * (1.0 + w * h);
    EXPECT_NEAR(s.xor_px, xor_px, tolerance) << w << "x" << h;
    EXPECT_NEAR(s.missed_px, missed, tolerance) << w << "x" << h;
    EXPECT_NEAR(s.extra_px, extra, tolerance) << w << "x" << h;
    EXPECT_EQ(s.xor_px, s.missed_px + s.extra_px) << w << "x" << h;
    EXPECT_EQ(s.object_px, object_px) << w << "x" << h;
    EXPECT_NEAR(s.mesh_px, mesh_px, tolerance) << w << "x" << h;
    EXPECT_NEAR(s.iou, both / (object_px + mesh_px - both), 1e-12) << w << "x" << h;
  }
}

TEST(CompareCoverage, WithoutPartlyCoveredPixelsIsCompareMasks) {
  BitMask object(130, 6, 4, 4), mesh(130, 6, 4, 4);
  object.SetSpan(1, 3, 100);
  object.SetSpan(4, 60, 130);
  mesh.SetSpan(1, 50, 120);
  mesh.SetSpan(5, 0, 7);
  const FrameScore s = CompareCoverage(object, mesh, {});
  EXPECT_TRUE(s == CompareMasks(object, mesh));
  EXPECT_EQ(s.xor_px, 47 + 70 + 20 + 7)
      << "missed: row 1 pixels 3..49, row 4 60..129; extra: row 1 100..119, row 5 0..6";
}

TEST(CompareMasksDeathTest, DifferentShapesAbort) {
  EXPECT_DEATH(CompareMasks(BitMask(10, 10), BitMask(10, 11)), "differ in shape");
  EXPECT_DEATH(CompareMasks(BitMask(10, 10, 0, 0), BitMask(10, 10, 1, 0)), "differ in shape");
  EXPECT_DEATH(CompareCoverage(BitMask(10, 10), BitMask(11, 10), {}), "differ in shape");
}

}  // namespace
}  // namespace calib
