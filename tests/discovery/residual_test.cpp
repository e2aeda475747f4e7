// Residual analysis on hand-made masks and meshes: the XOR split, bands,
// rest-shape regions, centroid and orientation, phases, oscillation,
// persistence after release, JSON round trip and determinism.

#include "calib/discovery/residual.h"

#include "calib/evaluator/evaluation.h"
#include "calib/evaluator/rasterizer.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

namespace calib {
namespace {

using calib::testing::StillScene;

constexpr double kPi = std::numbers::pi;

// Mask of the pixels whose centres lie inside [x0, x1) x [y0, y1).
BitMask RectMask(int width, int height, int x0, int y0, int x1, int y1) {
  BitMask m(width, height);
  for (int y = y0; y < y1; ++y) m.SetSpan(y, x0, x1);
  return m;
}

// Pixels whose centres lie inside the ellipse of semi-axes a, b rotated by
// angle about centre c.
BitMask EllipseMask(int width, int height, const Vec2& c, double a, double b, double angle) {
  BitMask m(width, height);
  const double ca = std::cos(angle), sa = std::sin(angle);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const Vec2 d = Vec2(x + 0.5, y + 0.5) - c;
      const double u = ca * d.x() + sa * d.y(), v = -sa * d.x() + ca * d.y();
      if ((u * u) / (a * a) + (v * v) / (b * b) <= 1.0) m.Set(x, y);
    }
  }
  return m;
}

// A scene of `frames` frames at `fps` without obstacles.
std::vector<Vec2> Shifted(const std::vector<Vec2>& p, const Vec2& d) {
  std::vector<Vec2> out = p;
  for (Vec2& q : out) q += d;
  return out;
}

// ---------------------------------------------------------------------------
// Geometry.

TEST(MaskMoments, RectangleCentroidAndAxisAreExact) {
  const BitMask m = RectMask(200, 100, 20, 30, 100, 50);  // 80 x 20
  const MaskMoments mm = ComputeMoments(m);
  EXPECT_EQ(mm.area_px, 80 * 20);
  EXPECT_DOUBLE_EQ(mm.centroid_px.x(), 60.0);
  EXPECT_DOUBLE_EQ(mm.centroid_px.y(), 40.0);
  EXPECT_NEAR(mm.angle_rad, 0.0, 1e-12);
  // Variances 80^2/12 - 1/12 and 20^2/12 - 1/12 (discrete uniform).
  EXPECT_NEAR(mm.anisotropy, 1.0 - (400.0 - 1) / (6400.0 - 1), 1e-9);

  const BitMask tall = RectMask(200, 100, 20, 10, 40, 90);
  EXPECT_NEAR(ComputeMoments(tall).angle_rad, kPi / 2, 1e-12) << "vertical axis is +pi/2";
}

TEST(MaskMoments, RotatedEllipseOrientation) {
  for (double deg : {-60.0, -20.0, 0.0, 15.0, 35.0, 80.0}) {
    const double angle = deg * kPi / 180.0;
    const BitMask m = EllipseMask(300, 300, Vec2(150.0, 150.0), 100.0, 40.0, angle);
    const MaskMoments mm = ComputeMoments(m);
    // Point-symmetric about the centre: the centroid is exact.
    EXPECT_NEAR(mm.centroid_px.x(), 150.0, 1e-9) << deg;
    EXPECT_NEAR(mm.centroid_px.y(), 150.0, 1e-9) << deg;
    EXPECT_NEAR(AxisAngleDifference(mm.angle_rad, angle), 0.0, 0.2 * kPi / 180) << deg;
  }
}

TEST(MaskMoments, EmptyMaskHasNoCentroid) {
  const MaskMoments mm = ComputeMoments(BitMask(70, 10));
  EXPECT_EQ(mm.area_px, 0);
  EXPECT_FALSE(mm.centroid_px.allFinite());
  EXPECT_TRUE(std::isnan(mm.angle_rad));
}

TEST(AxisAngleDifference, WrapsModuloPi) {
  EXPECT_NEAR(AxisAngleDifference(0.1, -0.1), 0.2, 1e-12);
  EXPECT_NEAR(AxisAngleDifference(kPi / 2 - 0.05, -kPi / 2 + 0.05), -0.1, 1e-12);
  EXPECT_NEAR(AxisAngleDifference(kPi, 0.0), 0.0, 1e-12);
  const double d = AxisAngleDifference(kPi / 2, 0.0);
  EXPECT_NEAR(d, kPi / 2, 1e-12) << "(-pi/2, pi/2]";
}

TEST(CountXorShifted, MatchesBruteForce) {
  // Masks wider than a word, with a ragged last word.
  const int w = 150, h = 40;
  BitMask a(w, h), b(w, h);
  uint32_t state = 12345;
  auto next = [&state] {
    state = state * 1664525u + 1013904223u;
    return state >> 8;
  };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (next() % 3 == 0) a.Set(x, y);
      if (next() % 4 == 0) b.Set(x, y);
    }
  }
  for (auto [dx, dy] : {std::pair{0, 0}, {1, 0}, {-1, 0}, {63, 2}, {64, -3}, {-65, 1}, {100, 5},
                        {-149, 0}, {7, 39}, {0, -40}}) {
    int64_t expected = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int xb = x - dx, yb = y - dy;
        const bool vb = xb >= 0 && xb < w && yb >= 0 && yb < h && b.Get(xb, yb);
        expected += a.Get(x, y) != vb;
      }
    }
    EXPECT_EQ(CountXorShifted(a, b, dx, dy), expected) << "shift " << dx << ", " << dy;
  }
}

// ---------------------------------------------------------------------------
// Signals.

TEST(DetectOscillation, FindsThePeriodOfANoisySinusoid) {
  const double fps = 240.0, period_frames = 23.7;
  std::vector<double> y(600);
  uint32_t state = 7;
  for (size_t i = 0; i < y.size(); ++i) {
    state = state * 1664525u + 1013904223u;
    const double noise = ((state >> 8) / 16777216.0 - 0.5) * 0.6;
    y[i] = 3.0 * std::sin(2 * kPi * i / period_frames) + 0.01 * i + noise;
  }
  const Oscillation o = DetectOscillation(y, fps);
  ASSERT_TRUE(o.found);
  EXPECT_NEAR(o.period_frames, period_frames, 0.01 * period_frames);
  EXPECT_NEAR(o.period_s, period_frames / fps, 0.01 * period_frames / fps);
  EXPECT_GT(o.strength, 0.9);
  EXPECT_NEAR(o.amplitude, 3.0, 0.2);
  EXPECT_NEAR(o.decay_per_s, 0.0, 0.3);
  EXPECT_NEAR(o.cycles, 600 / period_frames, 0.5);
}

TEST(DetectOscillation, MeasuresTheDecay) {
  const double fps = 30.0, rate = 0.5;  // 1/s
  std::vector<double> y(300);
  for (size_t i = 0; i < y.size(); ++i) {
    const double t = i / fps;
    y[i] = 10.0 * std::exp(-rate * t) * std::cos(2 * kPi * t / 0.8);
  }
  const Oscillation o = DetectOscillation(y, fps);
  ASSERT_TRUE(o.found);
  EXPECT_NEAR(o.period_s, 0.8, 0.02);
  EXPECT_NEAR(o.decay_per_s, rate, 0.1);
}

TEST(DetectOscillation, NoPeriodInNoiseOrATrend) {
  std::vector<double> noise(400), trend(400), step(400);
  uint32_t state = 99;
  for (size_t i = 0; i < noise.size(); ++i) {
    state = state * 1664525u + 1013904223u;
    noise[i] = (state >> 8) / 16777216.0;
    trend[i] = 0.5 * i;
    step[i] = i < 200 ? 0.0 : 1.0;
  }
  EXPECT_FALSE(DetectOscillation(noise, 30.0).found);
  EXPECT_FALSE(DetectOscillation(trend, 30.0).found);
  EXPECT_FALSE(DetectOscillation(step, 30.0).found);
  EXPECT_FALSE(DetectOscillation(std::vector<double>(5, 1.0), 30.0).found);
}

TEST(FitExponentialDecay, RecoversTimeConstantFloorAndAmplitude) {
  const double dt = 1.0 / 30.0;
  std::vector<double> y(60);
  for (size_t i = 0; i < y.size(); ++i) y[i] = 5.0 + 20.0 * std::exp(-(i * dt) / 0.4);
  const ExponentialFit fit = FitExponentialDecay(y, dt);
  ASSERT_TRUE(fit.ok);
  EXPECT_NEAR(fit.tau_s, 0.4, 0.004);
  EXPECT_NEAR(fit.floor, 5.0, 0.05);
  EXPECT_NEAR(fit.amplitude, 20.0, 0.1);
  EXPECT_GT(fit.r2, 0.9999);
}

TEST(LinearSlopeAndCorrelation, OnLines) {
  const std::vector<double> y = {1.0, 3.0, NAN, 7.0, 9.0};
  EXPECT_NEAR(LinearSlope(y, 0.5), 4.0, 1e-12);
  const std::vector<double> x = {0, 1, 2, 3, 4}, z = {4, 3, 2, 1, 0};
  EXPECT_NEAR(Correlation(x, z), -1.0, 1e-12);
  EXPECT_EQ(Correlation(x, std::vector<double>(5, 2.0)), 0.0);
}

// ---------------------------------------------------------------------------
// Phases.

// Pusher above the object moving down (in), still, back up; force follows
// the depth.
LoadTrack PushTrack() {
  LoadTrack t;
  t.fps = 30.0;
  for (int f = 0; f < 100; ++f) {
    double y;
    if (f < 10) {
      y = 0.0;
    } else if (f < 30) {
      y = (f - 10) * 1.0;
    } else if (f < 45) {
      y = 20.0;
    } else if (f < 65) {
      y = 20.0 - (f - 45) * 1.0;
    } else {
      y = 0.0;
    }
    t.pusher_centre.push_back(Vec2(100.0, 50.0 + y));
    t.object_centre.push_back(Vec2(100.0, 150.0));
    t.force_n.push_back(std::max(0.0, y - 2.0) * 0.1);
  }
  return t;
}

TEST(DetectLoadPhases, FromForceTrackAndPusherMotion) {
  const std::vector<LoadPhase> p = DetectLoadPhases(PushTrack(), PhaseOptions{});
  ASSERT_EQ(p.size(), 100u);
  EXPECT_EQ(p[0], LoadPhase::kBeforeLoad);
  EXPECT_EQ(p[10], LoadPhase::kBeforeLoad) << "force still 0";
  EXPECT_EQ(p[20], LoadPhase::kLoading);
  EXPECT_EQ(p[28], LoadPhase::kLoading);
  EXPECT_EQ(p[32], LoadPhase::kHold);
  EXPECT_EQ(p[43], LoadPhase::kHold);
  EXPECT_EQ(p[50], LoadPhase::kUnloading);
  EXPECT_EQ(p[62], LoadPhase::kUnloading) << "force still above 5% of the peak";
  EXPECT_EQ(p[64], LoadPhase::kReleased) << "force below 5% of the peak";
  EXPECT_EQ(p[99], LoadPhase::kReleased);
  // Names round-trip.
  for (int i = 0; i < kNumLoadPhases; ++i) {
    const auto phase = static_cast<LoadPhase>(i);
    EXPECT_EQ(LoadPhaseFromString(ToString(phase)), phase);
  }
  EXPECT_THROW(LoadPhaseFromString("pushing"), std::invalid_argument);
}

TEST(DetectLoadPhases, StaticPusherUsesTheForceTrend) {
  LoadTrack t = PushTrack();
  for (Vec2& c : t.pusher_centre) c = Vec2(100.0, 50.0);
  const std::vector<LoadPhase> p = DetectLoadPhases(t, PhaseOptions{});
  EXPECT_EQ(p[20], LoadPhase::kLoading);
  EXPECT_EQ(p[37], LoadPhase::kHold);
  EXPECT_EQ(p[55], LoadPhase::kUnloading);
  EXPECT_EQ(p[80], LoadPhase::kReleased);
}

TEST(DetectLoadPhases, NoLoadIsFreeMotion) {
  LoadTrack t;
  t.num_frames = 50;
  const std::vector<LoadPhase> p = DetectLoadPhases(t, PhaseOptions{});
  ASSERT_EQ(p.size(), 50u);
  for (LoadPhase x : p) EXPECT_EQ(x, LoadPhase::kFree);
  t.force_n.assign(50, 0.0);
  for (LoadPhase x : DetectLoadPhases(t, PhaseOptions{})) EXPECT_EQ(x, LoadPhase::kFree);
}

TEST(ResidualOptions, InvalidFieldsAreNamed) {
  std::string error;
  ResidualOptions o;
  EXPECT_TRUE(o.IsValid(&error)) << error;
  o.obstacle_bands_px = {5.0, 3.0};
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("obstacle_bands_px[1]"), std::string::npos) << error;
  o = ResidualOptions();
  o.phases.load_off_fraction = 0.5;
  EXPECT_FALSE(o.IsValid(&error));
  EXPECT_NE(error.find("load_off_fraction"), std::string::npos) << error;
}

// ---------------------------------------------------------------------------
// The analyser on a shifted rectangle: exact split, regions, offset.

struct ShiftCase {
  Mesh mesh = testing::MakeGridMesh(10, 6, 10.0, Vec2(100.0, 100.0));  // [100,200) x [100,160)
  Scene scene = StillScene(1, 30.0);
  std::vector<BitMask> object = {RectMask(320, 240, 100, 100, 200, 160)};
};

TEST(ResidualAnalyser, ShiftedMeshSplitsIntoMissedAndExtraExactly) {
  ShiftCase c;
  ResidualAnalyser analyser(c.mesh, c.scene, c.object, {}, "shift");
  const std::vector<Vec2> positions = Shifted(c.mesh.rest_positions, Vec2(10.0, 0.0));
  BitMask mesh_mask(320, 240);
  Rasterizer().RasterizeMesh(c.mesh, positions, mesh_mask);
  analyser.AddFrame(0, positions, mesh_mask);
  const ResidualAnalysis a = analyser.Finish();

  ASSERT_EQ(a.frames.size(), 1u);
  const ResidualFrame& f = a.frames[0];
  EXPECT_EQ(f.missed_px, 10 * 60);
  EXPECT_EQ(f.extra_px, 10 * 60);
  EXPECT_EQ(f.aligned_xor_px, 0) << "a translation explains it all";
  EXPECT_DOUBLE_EQ(f.offset_px.x(), 10.0);
  EXPECT_DOUBLE_EQ(f.offset_px.y(), 0.0);
  EXPECT_NEAR(f.angle_diff_rad, 0.0, 1e-12);
  EXPECT_EQ(a.xor_sum, 1200);
  EXPECT_EQ(a.phases.size(), 1u);
  EXPECT_EQ(a.phases[0].phase, LoadPhase::kFree);
  EXPECT_NEAR(a.rest_area_px, 6000.0, 1e-9);
  EXPECT_NEAR(a.rest_perimeter_px, 320.0, 1e-9);
  EXPECT_NEAR(a.residual_thickness_px, 1200.0 / 320.0, 1e-12);

  // Extra pixels map (barycentrically) to the right edge of the rest shape,
  // missed pixels (nearest boundary) to the left edge.
  const auto& all = a.regions.counts[0];
  const auto at = [](RestRegion r) { return static_cast<int>(r); };
  EXPECT_EQ(all[at(RestRegion::kRight)].extra, 600);
  EXPECT_EQ(all[at(RestRegion::kRight)].missed, 0);
  EXPECT_EQ(all[at(RestRegion::kLeft)].missed, 600);
  EXPECT_EQ(all[at(RestRegion::kLeft)].extra, 0);
  EXPECT_EQ(all[at(RestRegion::kTop)].missed + all[at(RestRegion::kBottom)].missed, 600);
  EXPECT_EQ(all[at(RestRegion::kAll)].missed, 600);
  EXPECT_NEAR(a.regions.area_px[at(RestRegion::kLeft)], 3000.0, 1e-9);
  // The signed dipole points left (missed on the left, extra on the right).
  EXPECT_LT(a.regions.signed_dipole.x(), -0.5);
  EXPECT_NEAR(a.regions.signed_dipole.y(), 0.0, 1e-9);

  // Heat map: everything in the leftmost and rightmost columns of cells.
  const RestHeatMap& h = a.heat_map;
  ASSERT_GT(h.cols, 2);
  double missed_left = 0, extra_right = 0, total = 0;
  for (int r = 0; r < h.rows; ++r) {
    for (int col = 0; col < h.cols; ++col) {
      const size_t i = static_cast<size_t>(r) * h.cols + col;
      total += h.missed[i] + h.extra[i];
      if (col == 0) missed_left += h.missed[i];
      if (col == h.cols - 1 || (col + 1) * h.cell_px >= 90.0) extra_right += h.extra[i];
    }
  }
  EXPECT_EQ(total, 1200.0);
  EXPECT_EQ(missed_left, 600.0);
  EXPECT_EQ(extra_right, 600.0);
  double area = 0;
  for (double v : h.area_px) area += v;
  EXPECT_EQ(area, 6000.0);
}

// Pixels whose centres lie inside the rectangle [x0, x1) x [y0, y1)
// turned by `angle` about its centre.
BitMask TurnedRectMask(int width, int height, double x0, double y0, double x1, double y1,
                       double angle) {
  BitMask m(width, height);
  const Vec2 c(0.5 * (x0 + x1), 0.5 * (y0 + y1));
  const double ca = std::cos(angle), sa = std::sin(angle);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const Vec2 d = Vec2(x + 0.5, y + 0.5) - c;
      const Vec2 u(ca * d.x() + sa * d.y(), -sa * d.x() + ca * d.y());  // turned back
      if (std::abs(u.x()) < 0.5 * (x1 - x0) && std::abs(u.y()) < 0.5 * (y1 - y0)) m.Set(x, y);
    }
  }
  return m;
}

TEST(ResidualAnalyser, ATurnedMeshIsAPoseErrorNotAShapeError) {
  ShiftCase c;
  ResidualAnalyser analyser(c.mesh, c.scene, c.object, {}, "turn");
  // The mesh turned by 10 degrees about the rest shape's centre.
  const double turn = 10.0 * kPi / 180.0;
  const Vec2 centre(150.0, 130.0);
  std::vector<Vec2> positions = c.mesh.rest_positions;
  for (Vec2& p : positions) {
    const Vec2 d = p - centre;
    p = centre + Vec2(std::cos(turn) * d.x() - std::sin(turn) * d.y(),
                      std::sin(turn) * d.x() + std::cos(turn) * d.y());
  }
  BitMask mesh_mask(320, 240);
  Rasterizer().RasterizeMesh(c.mesh, positions, mesh_mask);
  analyser.AddFrame(0, positions, mesh_mask);
  const ResidualAnalysis analysis = analyser.Finish();
  const ResidualFrame& f = analysis.frames.at(0);
  EXPECT_GT(f.aligned_xor_px, 1000) << "no translation lays a turned mesh onto the object";
  EXPECT_LT(f.rigid_xor_px, f.aligned_xor_px / 50) << "the turn back does";
  EXPECT_NEAR(f.rigid_turn_rad, -turn, 0.6 * kPi / 180.0) << "within the search's half-degree step";
}

TEST(ResidualAnalyser, ObstacleBandsCountByDistance) {
  ShiftCase c;
  c.scene.num_obstacles = 1;
  // A disc of radius 5 centred 10 px right of the object's right edge: the
  // extra band x in [200, 210) lies 0..10 px from its centre.
  c.scene.obstacle_discs = {Disc{Vec2(215.0, 130.0), 5.0}};
  ResidualOptions options;
  options.obstacle_bands_px = {5.0, 1000.0};
  ResidualAnalyser analyser(c.mesh, c.scene, c.object, {"pencil"}, "bands", options);
  const std::vector<Vec2> positions = Shifted(c.mesh.rest_positions, Vec2(10.0, 0.0));
  BitMask mesh_mask(320, 240);
  Rasterizer().RasterizeMesh(c.mesh, positions, mesh_mask);
  analyser.AddFrame(0, positions, mesh_mask);
  const ResidualAnalysis a = analyser.Finish();
  int64_t expected_near = 0;
  for (int y = 100; y < 160; ++y) {
    for (int x = 200; x < 210; ++x) {
      if ((Vec2(x + 0.5, y + 0.5) - Vec2(215.0, 130.0)).norm() - 5.0 <= 5.0) ++expected_near;
    }
  }
  ASSERT_EQ(a.band_extra_px.size(), 2u);
  EXPECT_EQ(a.band_extra_px[0], expected_near);
  EXPECT_EQ(a.band_extra_px[0] + a.band_extra_px[1], 600);
  EXPECT_EQ(a.band_missed_px[0], 0);
  EXPECT_EQ(a.band_missed_px[1], 600) << "all within 1000 px";
  EXPECT_EQ(a.far_missed_px + a.far_extra_px, 0);
  EXPECT_EQ(a.obstacle_names, std::vector<std::string>{"pencil"});
}

TEST(ResidualAnalyser, RejectsFramesOutOfOrderAndBadShapes) {
  ShiftCase c;
  ResidualAnalyser analyser(c.mesh, c.scene, c.object, {}, "x");
  BitMask mesh_mask(320, 240);
  EXPECT_THROW(analyser.AddFrame(1, c.mesh.rest_positions, mesh_mask), std::invalid_argument);
  EXPECT_THROW(analyser.AddFrame(0, c.mesh.rest_positions, BitMask(10, 10)), std::invalid_argument);
  EXPECT_THROW(ResidualAnalyser(c.mesh, StillScene(2, 30.0), c.object, {}, "x"),
               std::invalid_argument);
  ResidualAnalyser empty(c.mesh, c.scene, c.object, {}, "x");
  const ResidualAnalysis a = empty.Finish();
  EXPECT_EQ(a.frames_analysed, 0);
  EXPECT_EQ(a.xor_sum, 0);
}

// ---------------------------------------------------------------------------
// Over time: a swinging object against a still mesh, and a dent.

// The object (a rectangle) swings sideways as x0 + A sin(2 pi t / T); the
// mesh stays at rest.
struct SwingCase {
  Mesh mesh = testing::MakeGridMesh(4, 12, 10.0, Vec2(140.0, 40.0));
  Scene scene;
  std::vector<BitMask> object;

  SwingCase(double period_s, double fps, int frames) : scene(StillScene(frames, fps)) {
    for (int f = 0; f < frames; ++f) {
      const int dx = static_cast<int>(std::lround(12.0 * std::sin(2 * kPi * f / fps / period_s)));
      object.push_back(RectMask(320, 200, 140 + dx, 40, 180 + dx, 160));
    }
  }
  ResidualAnalysis Analyse() const {
    ResidualAnalyser analyser(mesh, scene, object, {}, "swing");
    BitMask mesh_mask(320, 200);
    Rasterizer().RasterizeMesh(mesh, mesh.rest_positions, mesh_mask);
    for (int f = 0; f < scene.num_frames; ++f) analyser.AddFrame(f, mesh.rest_positions, mesh_mask);
    return analyser.Finish();
  }
};

TEST(ResidualAnalyser, SwingingObjectOscillatesAgainstAStillMesh) {
  const ResidualAnalysis a = SwingCase(0.25, 240.0, 600).Analyse();
  const Oscillation& o = a.oscillation.offset;
  ASSERT_TRUE(o.found);
  EXPECT_NEAR(o.period_s, 0.25, 0.005);
  EXPECT_NEAR(o.amplitude, 12.0, 1.0);
  EXPECT_TRUE(a.oscillation.object_motion.found);
  EXPECT_FALSE(a.oscillation.mesh_motion.found);
  EXPECT_NEAR(a.motion.object_motion_rms_px, 12.0 / std::sqrt(2.0), 0.5);
  EXPECT_NEAR(a.motion.mesh_motion_rms_px, 0.0, 1e-9);
  EXPECT_NEAR(std::abs(a.motion.motion_axis.x()), 1.0, 1e-6);
  EXPECT_FALSE(a.push.has_push);
  EXPECT_FALSE(a.persistence.released);
}

// A rectangle pushed from above by a finger disc that dents it; the mesh
// never dents. After release the dent either stays (plastic) or fades with
// time constant tau_s (viscoelastic). The sensor reads 4 N x
// (dent / 20 px)^force_exponent.
struct DentCase {
  Mesh mesh = testing::MakeGridMesh(12, 6, 10.0, Vec2(100.0, 100.0));  // [100,220) x [100,160)
  Scene scene;
  std::vector<BitMask> object;
  std::vector<double> dent_depth;

  DentCase(bool plastic, double tau_s, double force_exponent = 1.0) {
    const double fps = 30.0;
    const int frames = 100;
    const double radius = 25.0, depth = 20.0;
    scene = StillScene(frames, fps);
    scene.num_obstacles = 1;
    scene.force_obstacle = 0;
    double hold_depth = 0.0;
    for (int f = 0; f < frames; ++f) {
      double d;  // finger depth below the top edge
      if (f < 10) {
        d = -5.0;
      } else if (f < 30) {
        d = -5.0 + (depth + 5.0) * (f - 10) / 20.0;
      } else if (f < 45) {
        d = depth;
      } else if (f < 55) {
        d = depth - (depth + 5.0) * (f - 45) / 10.0;
      } else {
        d = -5.0;
      }
      double dent;
      if (f < 45) {
        dent = std::max(0.0, d);
        hold_depth = dent;
      } else if (plastic) {
        dent = hold_depth;
      } else {
        dent = hold_depth * std::exp(-(f - 45) / fps / tau_s);
      }
      dent_depth.push_back(dent);
      const Vec2 finger(160.0, 100.0 + d - radius);
      scene.obstacle_discs.push_back(Disc{finger, radius});
      scene.forces.push_back(Vec2(0.0, 4.0 * std::pow(std::max(0.0, d) / depth, force_exponent)));
      BitMask m = RectMask(320, 240, 100, 100, 220, 160);
      const Vec2 cut(160.0, 100.0 + dent - radius);
      for (int y = 100; y < 160; ++y) {
        for (int x = 100; x < 220; ++x) {
          if (dent > 0.0 && (Vec2(x + 0.5, y + 0.5) - cut).norm() < radius) m.Set(x, y, false);
        }
      }
      object.push_back(std::move(m));
    }
  }

  ResidualAnalysis Analyse() const {
    ResidualAnalyser analyser(mesh, scene, object, {"finger"}, "dent");
    BitMask mesh_mask(320, 240);
    Rasterizer().RasterizeMesh(mesh, mesh.rest_positions, mesh_mask);
    for (int f = 0; f < scene.num_frames; ++f) analyser.AddFrame(f, mesh.rest_positions, mesh_mask);
    return analyser.Finish();
  }
};

TEST(ResidualAnalyser, ForceAgainstTravelSaysHowTheMaterialAnswersADeeperDent) {
  // Force ~ travel (a linear material) and ~ travel^2 (stiffening), the
  // travel counted from the contact; the loading frames above a tenth of the
  // peak force (dent 2..20 px).
  // Under a quadratic law the force reaches 2 % of its peak only 2.5 px
  // into the dent, so the travel counted from there reads a lower exponent.
  const PushSummary linear = DentCase(false, 0.5, 1.0).Analyse().push;
  EXPECT_NEAR(linear.force_travel_exponent, 1.0, 0.02);
  const PushSummary quadratic = DentCase(false, 0.5, 2.0).Analyse().push;
  EXPECT_GT(quadratic.force_travel_exponent, 1.5);
  EXPECT_LE(quadratic.force_travel_exponent, 2.0);
  for (const PushSummary& p : {linear, quadratic}) {
    EXPECT_GT(p.force_travel_correlation, 0.99);
    EXPECT_GE(p.force_travel_frames, 10);
    EXPECT_LE(p.force_travel_frames, 17);
  }
  // No sensor, no force against travel (the push is found from the contact).
  DentCase no_sensor(false, 0.5);
  no_sensor.scene.force_obstacle = -1;
  no_sensor.scene.forces.clear();
  const PushSummary p = no_sensor.Analyse().push;
  EXPECT_TRUE(p.has_push);
  EXPECT_TRUE(std::isnan(p.force_travel_exponent));
  EXPECT_EQ(p.force_travel_frames, 0);
}

TEST(ResidualAnalyser, PlasticDentPersistsAfterRelease) {
  const ResidualAnalysis a = DentCase(true, 0.0).Analyse();
  ASSERT_TRUE(a.push.has_push);
  EXPECT_NEAR(a.push.push_axis.y(), 1.0, 1e-6) << "pushed downwards";
  EXPECT_NEAR(a.push.contact_site_px.x(), 160.0, 1e-6);
  EXPECT_NEAR(a.push.contact_site_px.y(), 100.0, 1e-6);
  const PersistenceSummary& p = a.persistence;
  ASSERT_TRUE(p.released);
  EXPECT_GE(p.release_frame, 50);
  EXPECT_LE(p.release_frame, 55);
  EXPECT_LT(p.before_xor_px, 5.0) << "a dent of < 2 px before the force passes 10%";
  EXPECT_GT(p.persistent_ratio, 1.0) << "the full dent stays; the loaded mean includes the ramp";
  EXPECT_LT(p.fading_ratio, 0.01);
  EXPECT_NEAR(a.push.contact_zone_radius_px, 37.5, 1e-9) << "1.5 finger radii";
  EXPECT_GT(p.contact_fraction, 0.9);
  EXPECT_GT(p.contact_concentration, 2.0);
  // The residual is all extra pixels at the near side.
  const auto& rel = a.regions.counts[2];
  EXPECT_EQ(rel[static_cast<int>(RestRegion::kAll)].missed, 0);
  EXPECT_EQ(rel[static_cast<int>(RestRegion::kFar)].extra, 0);
  EXPECT_GT(rel[static_cast<int>(RestRegion::kNear)].extra, 0);
  // Phases.
  ASSERT_NE(a.Phase(LoadPhase::kHold), nullptr);
  EXPECT_EQ(a.Phase(LoadPhase::kBeforeLoad)->first_frame, 0);
  EXPECT_NEAR(a.Phase(LoadPhase::kHold)->first_frame, 30, 1);
  EXPECT_NEAR(a.push.hold_force_change, 0.0, 1e-9);
}

// A push that turns the object (8 degrees, kept after the release) without
// denting it, against a mesh that stays at rest: the residual persists, the
// shape error does not.
TEST(ResidualAnalyser, APoseLeftTurnedAfterReleaseIsNoPersistentShapeError) {
  DentCase c(true, 0.0);
  const double turn = 8.0 * kPi / 180.0;
  double kept = 0.0;
  for (int f = 0; f < c.scene.num_frames; ++f) {
    // The finger's depth below the top edge, from its disc.
    const double d = c.scene.obstacle_discs[f].centre.y() + 25.0 - 100.0;
    if (f < 45) kept = std::clamp(d / 20.0, 0.0, 1.0) * turn;
    c.object[f] = TurnedRectMask(320, 240, 100, 100, 220, 160, kept);
  }
  const PersistenceSummary& p = c.Analyse().persistence;
  ASSERT_TRUE(p.released);
  EXPECT_GT(p.persistent_ratio, 1.0) << "the whole turn stays; the loaded mean includes the ramp";
  EXPECT_LT(p.shape_persistent_ratio, 0.1);
  EXPECT_LT(p.released_late_rigid_xor_px, 0.05 * p.released_late_xor_px);

  // A dent is a shape error: it stays when the mesh is laid rigidly onto the
  // object.
  const PersistenceSummary dent = DentCase(true, 0.0).Analyse().persistence;
  EXPECT_GT(dent.shape_persistent_ratio, 0.8);
}

TEST(ResidualAnalyser, ViscoelasticDentFadesWithItsTimeConstant) {
  const double tau = 0.4;
  const ResidualAnalysis a = DentCase(false, tau).Analyse();
  const PersistenceSummary& p = a.persistence;
  ASSERT_TRUE(p.released);
  EXPECT_LT(p.persistent_ratio, 0.05);
  EXPECT_GT(p.fading_ratio, 0.05);
  ASSERT_TRUE(p.recovery.ok);
  // The dent's area falls faster than its depth (area ~ depth^1.5).
  EXPECT_GT(p.recovery.tau_s, 0.3 * tau);
  EXPECT_LT(p.recovery.tau_s, 1.2 * tau);
}

TEST(ResidualAnalyser, JsonRoundTripsAndRunsAreDeterministic) {
  const DentCase c(true, 0.0);
  const ResidualAnalysis a = c.Analyse();
  const ResidualAnalysis b = c.Analyse();
  const nlohmann::json ja = ToJson(a), jb = ToJson(b);
  EXPECT_EQ(ja.dump(), jb.dump()) << "two runs differ";
  const ResidualAnalysis back = ResidualAnalysisFromJson(ja);
  EXPECT_EQ(ToJson(back).dump(), ja.dump());
  EXPECT_EQ(back.frames.size(), a.frames.size());
  EXPECT_EQ(back.persistence.release_frame, a.persistence.release_frame);
  // Without frames.
  const nlohmann::json brief = ToJson(a, false);
  EXPECT_FALSE(brief.contains("frames"));
  EXPECT_TRUE(ResidualAnalysisFromJson(brief).frames.empty());
  // NaN is null and back.
  EXPECT_TRUE(ja["frames"][0]["angle_diff_rad"].is_number());
  nlohmann::json broken = ja;
  broken["persistence"].erase("persistent_ratio");
  try {
    ResidualAnalysisFromJson(broken);
    FAIL() << "a missing key must throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("persistence.persistent_ratio"), std::string::npos)
        << e.what();
  }
}

// ---------------------------------------------------------------------------
// The model-independent facts of a recording, computed once and shared.

// Feeds the dent case's mesh drifting sideways and sagging, a little more
// every frame (so that every part of the per-frame work has residual
// pixels to map, inside and outside the simulated triangles).
void FeedDriftingMesh(const DentCase& c, ResidualAnalyser& analyser) {
  Rasterizer rasterizer;
  BitMask mesh_mask(320, 240);
  std::vector<Vec2> positions(c.mesh.rest_positions.size());
  for (int f = 0; f < c.scene.num_frames; ++f) {
    for (size_t i = 0; i < positions.size(); ++i) {
      const Vec2& p = c.mesh.rest_positions[i];
      positions[i] = Vec2(p.x() + 3.0 * std::sin(0.2 * f), p.y() + 0.002 * f * (p.y() - 100.0));
    }
    rasterizer.RasterizeMesh(c.mesh, positions, mesh_mask);
    analyser.AddFrame(f, positions, mesh_mask);
  }
}

std::string AnalysisJson(ResidualAnalyser& analyser, const DentCase& c) {
  FeedDriftingMesh(c, analyser);
  return ToJson(analyser.Finish()).dump();
}

TEST(RecordingResidualFacts, SharedFactsGiveExactlyTheAnalysisOfTheOldConstructors) {
  for (const bool plastic : {true, false}) {
    const DentCase c(plastic, 0.4);
    ResidualAnalyser own(c.mesh, c.scene, c.object, {"finger"}, "dent");
    const std::string expected = AnalysisJson(own, c);

    const auto facts = std::make_shared<const RecordingResidualFacts>(
        ComputeResidualFacts(c.mesh, c.scene, c.object, {"finger"}, "dent"));
    EXPECT_EQ(facts->phases, own.phases());
    EXPECT_TRUE(facts->push.has_push);
    ResidualAnalyser shared(facts);
    EXPECT_EQ(AnalysisJson(shared, c), expected) << "plastic " << plastic;

    // Two analysers on one facts object at once, on two threads: the same
    // analysis.
    ResidualAnalyser first(facts), second(facts);
    std::string json_first, json_second;
    std::thread a([&] { json_first = AnalysisJson(first, c); });
    std::thread b([&] { json_second = AnalysisJson(second, c); });
    a.join();
    b.join();
    EXPECT_EQ(json_first, expected);
    EXPECT_EQ(json_second, expected);
  }
}

TEST(RecordingResidualFacts, FromAPreparedRecordingAsTheOldConstructor) {
  const DentCase c(true, 0.0);
  PreparedRecording prepared;
  prepared.recording.folder = "/recordings/dent_01";
  prepared.recording.obstacles.push_back({"finger", c.scene.obstacle_discs});
  prepared.object_masks = c.object;
  prepared.mesh = c.mesh;
  prepared.scene = c.scene;
  ResidualOptions options;
  options.heat_map_cells = 40;
  options.obstacle_bands_px = {4.0, 12.0};

  ResidualAnalyser own(prepared, options);
  const auto facts =
      std::make_shared<const RecordingResidualFacts>(ComputeResidualFacts(prepared, options));
  EXPECT_EQ(facts->recording_name, "dent_01");
  EXPECT_EQ(facts->obstacle_names, std::vector<std::string>{"finger"});
  ResidualAnalyser shared(facts);
  const std::string expected = AnalysisJson(own, c);
  EXPECT_EQ(AnalysisJson(shared, c), expected);
  EXPECT_EQ(nlohmann::json::parse(expected)["obstacle_bands_px"].size(), 2u)
      << "the facts' options are the analyser's";
}

TEST(RecordingResidualFacts, RejectsWhatTheConstructorRejects) {
  ShiftCase c;
  const auto message = [&](const Scene& scene, std::vector<std::string> names) {
    try {
      ComputeResidualFacts(c.mesh, scene, c.object, std::move(names), "x");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_EQ(message(StillScene(2, 30.0), {}),
            "ResidualAnalyser: 1 object masks for a scene of 2 frames");
  EXPECT_EQ(message(c.scene, {"a"}), "ResidualAnalyser: 1 obstacle names for 0 obstacles");
  ResidualOptions bad;
  bad.heat_map_cells = 0;
  EXPECT_THROW(ComputeResidualFacts(c.mesh, c.scene, c.object, {}, "x", bad),
               std::invalid_argument);
  EXPECT_THROW(ResidualAnalyser(std::shared_ptr<const RecordingResidualFacts>()),
               std::invalid_argument);
  EXPECT_THROW(ResidualAnalyser(std::make_shared<const RecordingResidualFacts>()),
               std::invalid_argument);
}

}  // namespace
}  // namespace calib
