// Tracking the mesh through the video (shape_tracking.h): a strip moved
// rigidly is followed node by node; the start of a free motion is the
// velocity of the tracked nodes and a rest shape that a swing does not
// shrink or stretch; bad arguments are named.

#include "calib/evaluator/shape_tracking.h"

#include "calib/evaluator/bit_mask_cv.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {
namespace {

using calib::testing::MakeGridMesh;

constexpr int kFrameWidth = 220, kFrameHeight = 200;

// A 30 x 120 px strip with its top edge centred on (100, 40).
Mesh Strip() { return MakeGridMesh(3, 12, 10.0, Vec2(85, 40)); }

Vec2 Rotated(const Vec2& p, const Vec2& pivot, double angle) {
  const Vec2 d = p - pivot;
  return pivot + Vec2(std::cos(angle) * d.x() - std::sin(angle) * d.y(),
                      std::sin(angle) * d.x() + std::cos(angle) * d.y());
}

// The pixels of the polygon `corners` (frame pixel (x, y) covers
// [x, x + 1) x [y, y + 1)), drawn with sub-pixel precision.
BitMask PolygonMask(const std::vector<Vec2>& corners) {
  constexpr int kShift = 8;
  std::vector<cv::Point> points;
  for (const Vec2& c : corners) {
    points.emplace_back(static_cast<int>(std::lround((c.x() - 0.5) * (1 << kShift))),
                        static_cast<int>(std::lround((c.y() - 0.5) * (1 << kShift))));
  }
  cv::Mat image = cv::Mat::zeros(kFrameHeight, kFrameWidth, CV_8UC1);
  cv::fillPoly(image, std::vector<std::vector<cv::Point>>{points}, cv::Scalar(255), cv::LINE_8, kShift);
  return FromMat(image, 0, 0);
}

TEST(ShapeTracking, FollowsAStripMovedRigidlyNodeByNode) {
  const Mesh mesh = Strip();
  const Vec2 pivot(100, 40);
  const std::vector<Vec2> corners{{85, 40}, {115, 40}, {115, 160}, {85, 160}};
  // Swinging 0.3 rad either way about its top, drifting right.
  const auto angle = [](int f) { return 0.3 * std::sin(2.0 * std::numbers::pi * f / 40.0); };
  const auto place = [&](const Vec2& p, int f) -> Vec2 {
    return Rotated(p, pivot, angle(f)) + Vec2(0.4 * f, 0.0);
  };
  constexpr int kFrames = 40;
  std::vector<BitMask> masks;
  for (int f = 0; f < kFrames; ++f) {
    std::vector<Vec2> moved;
    for (const Vec2& c : corners) moved.push_back(place(c, f));
    masks.push_back(PolygonMask(moved));
  }
  const std::vector<uint8_t> none(mesh.NumNodes(), 0);
  const TrackedShapes tracked = TrackMesh(mesh, none, masks, kFrames);
  ASSERT_EQ(tracked.positions.size(), static_cast<size_t>(kFrames));
  double worst = 0.0, sum = 0.0;
  int count = 0;
  for (int f = 0; f < kFrames; ++f) {
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      const double error = (tracked.positions[f][i] - place(mesh.rest_positions[i], f)).norm();
      worst = std::max(worst, error);
      sum += error;
      ++count;
    }
    EXPECT_LT(tracked.outline_distance_px[f], 0.5) << "frame " << f;
  }
  // Pixel outlines: within a pixel everywhere, a fraction of one on average.
  EXPECT_LT(worst, 1.5);
  EXPECT_LT(sum / count, 0.5);
}

TEST(ShapeTracking, TheVelocityIsTheSlopeAtFrameZeroOfEachNodesTrack) {
  const Mesh mesh = Strip();
  const double fps = 240.0;
  TrackedShapes shapes;
  // Node i moves by u_i f + a f^2 / 2 per frame f: a quadratic fit is exact.
  for (int f = 0; f < 6; ++f) {
    std::vector<Vec2> x = mesh.rest_positions;
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      const Vec2 u(0.01 * i, -0.02 * i), a(0.003, 0.001 * (i % 3));
      x[i] += u * f + 0.5 * a * f * f;
    }
    shapes.positions.push_back(x);
    shapes.outline_distance_px.push_back(0.0);
  }
  const std::vector<uint8_t> none(mesh.NumNodes(), 0);
  const NodeMotion motion = EstimateNodeMotion(mesh, none, shapes, fps, 6, 5);
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    EXPECT_NEAR(motion.velocity_px_s[i].x(), 0.01 * i * fps, 1e-9 * fps) << "node " << i;
    EXPECT_NEAR(motion.velocity_px_s[i].y(), -0.02 * i * fps, 1e-9 * fps) << "node " << i;
  }
}

// The strip clamped at its top-middle node, (95, 40) on the top row, and
// its shapes turned about that node by angle(f) and stretched about it by
// stretch(f) in frames f = 0 .. count - 1.
struct ClampedStrip {
  Mesh mesh = Strip();
  Vec2 pivot = mesh.rest_positions[1];
  std::vector<uint8_t> clamped = std::vector<uint8_t>(mesh.NumNodes(), 0);
  ClampedStrip() { clamped[1] = 1; }

  TrackedShapes Swing(int count, const std::function<double(int)>& angle,
                      const std::function<double(int)>& stretch) const {
    TrackedShapes shapes;
    for (int f = 0; f < count; ++f) {
      std::vector<Vec2> x;
      for (const Vec2& p : mesh.rest_positions) x.push_back(Rotated(pivot + stretch(f) * (p - pivot), pivot, angle(f)));
      shapes.positions.push_back(x);
      shapes.outline_distance_px.push_back(0.0);
    }
    return shapes;
  }
};

TEST(ShapeTracking, ASwingDoesNotShrinkTheRestShape) {
  // The strip swings rigidly +-0.35 rad about its clamped top-middle node.
  // The mean of its positions is shorter than the strip (by 1 - cos 0.35,
  // 7 px at the foot); the rest shape has the strip's own lengths, hanging.
  const ClampedStrip strip;
  const Mesh& mesh = strip.mesh;
  const TrackedShapes shapes =
      strip.Swing(8, [](int f) { return f % 2 == 0 ? 0.35 : -0.35; }, [](int) { return 1.0; });
  const NodeMotion motion = EstimateNodeMotion(mesh, strip.clamped, shapes, 240.0, 8, 2);
  double worst = 0.0, worst_mean = 0.0;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    worst = std::max(worst, (motion.rest_shape_px[i] - mesh.rest_positions[i]).norm());
    Vec2 mean = Vec2::Zero();
    for (const auto& x : shapes.positions) mean += x[i] / 8.0;
    worst_mean = std::max(worst_mean, (mean - mesh.rest_positions[i]).norm());
  }
  EXPECT_GT(worst_mean, 5.0) << "the mean of positions shrinks the strip";
  EXPECT_LT(worst, 0.01);
}

TEST(ShapeTracking, ASwingThatStretchesTheStripRestsAtTheStripsOwnLengths) {
  // The strip swings about its clamped top-middle node, dying down over 12
  // cycles, and is stretched about the clamp by the swing, as a swinging
  // strip is by its own momentum: by 1 + b theta'^2 (5 % at the start).
  // Each cycle's mean lengths are then longer by its energy; over the first
  // cycles they are long, and the fit against the cycles' energies finds
  // the strip's own lengths and its hanging pose.
  const ClampedStrip strip;
  const Mesh& mesh = strip.mesh;
  const std::vector<uint8_t>& clamped = strip.clamped;
  constexpr int kPeriod = 40, kCycles = 12, kFrames = kCycles * kPeriod + 5;
  const double omega = 2.0 * std::numbers::pi / kPeriod;  // rad a frame
  const auto amplitude = [&](int f) { return 0.5 * std::exp(-f / (3.0 * kPeriod)); };
  const TrackedShapes shapes = strip.Swing(
      kFrames, [&](int f) { return amplitude(f) * std::cos(omega * f); },
      [&](int f) { return 1.0 + 8.0 * std::pow(amplitude(f) * omega * std::sin(omega * f), 2); });
  const std::vector<MotionCycle> cycles =
      MotionCycles(std::span<const std::vector<Vec2>>(shapes.positions), clamped);
  ASSERT_GE(cycles.size(), static_cast<size_t>(kCycles - 2));
  for (const MotionCycle& c : cycles) EXPECT_NEAR(c.end - c.begin, kPeriod, 1) << c.begin;
  EXPECT_GT(cycles.front().mean_square_step_px2, 10.0 * cycles.back().mean_square_step_px2);

  const auto worst_length_error = [&](const std::vector<Vec2>& x) {
    double worst = 0.0;
    for (const std::array<int, 2>& e : mesh.edges) {
      const double rest = (mesh.rest_positions[e[0]] - mesh.rest_positions[e[1]]).norm();
      worst = std::max(worst, std::abs((x[e[0]] - x[e[1]]).norm() / rest - 1.0));
    }
    return worst;
  };
  const NodeMotion motion = EstimateNodeMotion(mesh, clamped, shapes, 240.0, kFrames, 5);
  const NodeMotion first_cycles = EstimateNodeMotion(mesh, clamped, shapes, 240.0, 2 * kPeriod + 1, 5);
  EXPECT_GT(worst_length_error(first_cycles.rest_shape_px), 0.01) << "the swing stretches the mean";
  EXPECT_LT(worst_length_error(motion.rest_shape_px), 0.002);
  const auto worst_node_error = [&](const std::vector<Vec2>& x) {
    double worst = 0.0;
    for (int i = 0; i < mesh.NumNodes(); ++i) worst = std::max(worst, (x[i] - mesh.rest_positions[i]).norm());
    return worst;
  };
  EXPECT_GT(worst_node_error(first_cycles.rest_shape_px), 1.0) << "px from the hanging strip";
  EXPECT_LT(worst_node_error(motion.rest_shape_px), 0.5) << "px from the hanging strip";
}

TEST(ShapeTracking, ARegistrationHoldsTheTrianglesToTheReferenceShape) {
  // The mask shows the straight strip turned 0.2 rad about its clamped top,
  // and the registration starts there, with the outline terms weighted low
  // so that the rigidity term counts. Held to the straight shape it stays
  // (within the pixel outline); held to the strip bent into an arc, the
  // nodes move towards the bend (3.1 px at worst against 0.35).
  const Mesh straight = Strip();
  const Vec2 pivot(100, 40);
  constexpr double kRadius = 100.0, kTurn = -0.2;
  const auto bend = [&](const Vec2& p) -> Vec2 {
    const double s = p.y() - pivot.y(), t = p.x() - pivot.x();
    return Vec2(pivot.x() + kRadius - (kRadius - t) * std::cos(s / kRadius),
                pivot.y() + (kRadius - t) * std::sin(s / kRadius));
  };
  std::vector<Vec2> bent, turned;
  for (const Vec2& p : straight.rest_positions) {
    bent.push_back(bend(p));
    turned.push_back(Rotated(p, pivot, kTurn));
  }
  std::vector<uint8_t> clamped(straight.NumNodes(), 0);
  for (int i = 0; i < straight.NumNodes(); ++i) clamped[i] = straight.rest_positions[i].y() == 40.0;
  const std::vector<Vec2> corners{{85, 40}, {115, 40}, {115, 160}, {85, 160}};
  std::vector<Vec2> turned_corners;
  for (const Vec2& c : corners) turned_corners.push_back(Rotated(c, pivot, kTurn));
  const BitMask mask = PolygonMask(turned_corners);

  const auto worst_error = [&](const std::vector<Vec2>& x) {
    double worst = 0.0;
    for (int i = 0; i < straight.NumNodes(); ++i) worst = std::max(worst, (x[i] - turned[i]).norm());
    return worst;
  };
  ShapeTrackingOptions options;
  options.outline_weight = 0.1;  // the rigidity term counts
  const MeshRegistration held_straight =
      RegisterMesh(straight, clamped, turned, straight.rest_positions, mask, options);
  const MeshRegistration held_bent = RegisterMesh(straight, clamped, turned, bent, mask, options);
  EXPECT_LT(held_straight.outline_distance_px, 0.5);
  EXPECT_LT(held_bent.outline_distance_px, 1.0);
  EXPECT_LT(worst_error(held_straight.positions), 1.0);
  EXPECT_GT(worst_error(held_bent.positions), 2.0 * worst_error(held_straight.positions));
  for (int i = 0; i < straight.NumNodes(); ++i) {
    if (clamped[i] != 0) {
      EXPECT_EQ(held_bent.positions[i], turned[i]) << "clamped node " << i;
    }
  }
  // A mask without object pixels leaves the start.
  const MeshRegistration none = RegisterMesh(straight, clamped, bent, straight.rest_positions,
                                             BitMask(kFrameWidth, kFrameHeight));
  EXPECT_EQ(none.positions, bent);
  EXPECT_EQ(none.outline_distance_px, -1.0);
}

TEST(ShapeTracking, BadArgumentsAreNamed) {
  const Mesh mesh = Strip();
  const std::vector<BitMask> masks(3, BitMask(kFrameWidth, kFrameHeight));
  const std::vector<uint8_t> none(mesh.NumNodes(), 0);
  const auto message = [](const auto& call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message([&] { TrackMesh(mesh, none, masks, 4); }).find("4 frames asked of a recording of 3"),
            std::string::npos);
  EXPECT_NE(message([&] { TrackMesh(mesh, std::vector<uint8_t>(2, 0), masks, 2); })
                .find("2 clamp flags for a mesh of"),
            std::string::npos);
  ShapeTrackingOptions options;
  options.outline_weight = 0.0;
  EXPECT_NE(message([&] { TrackMesh(mesh, none, masks, 2, options); }).find("outline_weight"),
            std::string::npos);
  EXPECT_NE(message([&] {
              RegisterMesh(mesh, none, std::vector<Vec2>(3), mesh.rest_positions, masks[0]);
            }).find("a start of 3 and a reference shape of"),
            std::string::npos);
  EXPECT_NE(message([&] {
              RegisterMesh(mesh, none, mesh.rest_positions, std::vector<Vec2>(2), masks[0]);
            }).find("a reference shape of 2 nodes for a mesh of"),
            std::string::npos);
  EXPECT_NE(message([&] {
              RegisterMesh(mesh, none, mesh.rest_positions, mesh.rest_positions, masks[0], options);
            }).find("outline_weight"),
            std::string::npos);
  TrackedShapes one;
  one.positions.push_back(mesh.rest_positions);
  one.outline_distance_px.push_back(0.0);
  EXPECT_NE(message([&] { EstimateNodeMotion(mesh, none, one, 240.0, 1, 5); })
                .find("a velocity from 5 frames asked of 1 tracked frames"),
            std::string::npos);
  EXPECT_NE(message([&] { EstimateNodeMotion(mesh, none, one, 240.0, 3, 1); })
                .find("a mean over 3 frames asked of 1 tracked frames"),
            std::string::npos);
  const std::vector<std::vector<Vec2>> frames = {mesh.rest_positions, std::vector<Vec2>(5)};
  EXPECT_NE(message([&] { MotionCycles(frames, none); }).find("frame 1 has 5 nodes and"),
            std::string::npos);
}

}  // namespace
}  // namespace calib
