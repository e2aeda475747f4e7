// The frame renderer: deterministic for a seed, the texture moves with the
// material, the finger is semi-transparent, and the spec's HSV segmentation
// with the range written into recording.json recovers the true object mask.

#include "calib/synth/renderer.h"

#include "calib/core/mesher.h"
#include "calib/evaluator/segmentation.h"

#include <gtest/gtest.h>

#include <cmath>

namespace calib::synth {
namespace {

struct Fixture {
  CameraSpec camera;
  Mesh mesh;
};

// A 400 x 256 px sponge, as in the push scenario, meshed with 8 px edges.
Fixture MakeFixture() {
  Fixture f;
  MesherOptions options;
  options.edge_length_px = 8.0;
  f.mesh = MeshPolygon({{120, 112}, {520, 112}, {520, 368}, {120, 368}}, options);
  return f;
}

// The rest shape bent and squeezed smoothly (a frame a simulator could give).
std::vector<Vec2> Deformed(const Mesh& mesh) {
  std::vector<Vec2> p = mesh.rest_positions;
  for (Vec2& q : p) {
    const double u = (q.x() - 320.0) / 200.0;
    q.y() += 18.0 * std::exp(-16.0 * u * u) * (368.0 - q.y()) / 256.0;  // a dent from the top
    q.x() += 6.0 * std::sin(3.0 * (q.y() - 112.0) / 256.0);
  }
  return p;
}

double IouAwayFrom(const BitMask& a, const BitMask& b, const Disc& finger, double margin_px) {
  int64_t inter = 0, uni = 0;
  for (int y = 0; y < a.height(); ++y) {
    for (int x = 0; x < a.width(); ++x) {
      if (std::hypot(x + 0.5 - finger.centre.x(), y + 0.5 - finger.centre.y()) <
          finger.radius_px + margin_px) {
        continue;
      }
      const bool in_a = a.Get(x, y), in_b = b.Get(x, y);
      inter += in_a && in_b;
      uni += in_a || in_b;
    }
  }
  return uni == 0 ? 1.0 : static_cast<double>(inter) / uni;
}

TEST(Renderer, SameSeedSameFrameSameBits) {
  const Fixture f = MakeFixture();
  const FrameRenderer a(f.camera, f.mesh, 7), b(f.camera, f.mesh, 7), c(f.camera, f.mesh, 8);
  const auto p = Deformed(f.mesh);
  const std::vector<DrawnDisc> discs = {{Disc{Vec2(320, 90), 14}, f.camera.finger_rgb, 0.6}};
  const cv::Mat fa = a.Render(3, p, discs), fb = b.Render(3, p, discs);
  ASSERT_EQ(fa.type(), CV_8UC3);
  EXPECT_EQ(fa.cols, 640);
  EXPECT_EQ(fa.rows, 480);
  EXPECT_EQ(cv::norm(fa, fb, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(fa, a.Render(4, p, discs), cv::NORM_L1), 0.0) << "noise differs per frame";
  EXPECT_GT(cv::norm(fa, c.Render(3, p, discs), cv::NORM_L1), 0.0) << "another seed differs";
}

TEST(Renderer, TextureMovesWithTheMaterial) {
  Fixture f = MakeFixture();
  f.camera.noise_sigma = 0.0;
  f.camera.blur_sigma_px = 0.0;
  f.camera.lighting_gradient = 0.0;
  const FrameRenderer renderer(f.camera, f.mesh, 3);
  std::vector<Vec2> moved = f.mesh.rest_positions;
  for (Vec2& q : moved) q += Vec2(10.0, 7.0);
  const cv::Mat rest = renderer.Render(0, f.mesh.rest_positions, {});
  const cv::Mat shifted = renderer.Render(0, moved, {});
  // The interior of the object shifts by exactly (10, 7) px, pores included.
  const cv::Rect inner(140, 130, 360, 220);
  const cv::Mat diff = rest(inner) != shifted(inner + cv::Point(10, 7));
  EXPECT_EQ(cv::countNonZero(diff.reshape(1)), 0);
  // And it is textured: not one flat colour.
  cv::Scalar mean, stddev;
  cv::meanStdDev(rest(inner), mean, stddev);
  EXPECT_GT(stddev[1], 5.0);
}

TEST(Renderer, FingerIsSemiTransparent) {
  Fixture f = MakeFixture();
  f.camera.noise_sigma = 0.0;
  f.camera.blur_sigma_px = 0.0;
  f.camera.lighting_gradient = 0.0;
  const FrameRenderer renderer(f.camera, f.mesh, 3);
  const Disc finger{Vec2(60.5, 60.5), 14.0};  // over the table
  const cv::Mat frame = renderer.Render(0, f.mesh.rest_positions, {{finger, f.camera.finger_rgb, 0.6}});
  const cv::Vec3b centre = frame.at<cv::Vec3b>(60, 60);
  for (int c = 0; c < 3; ++c) {
    const double background = f.camera.background_rgb[2 - c], skin = f.camera.finger_rgb[2 - c];
    EXPECT_NEAR(centre[c], 0.4 * background + 0.6 * skin, 1.0) << "channel " << c;
  }
  // The same finger over the object shows the object's colour through it.
  const cv::Mat over = renderer.Render(0, f.mesh.rest_positions,
                                       {{Disc{Vec2(300.5, 200.5), 14.0}, f.camera.finger_rgb, 0.6}});
  const cv::Mat bare = renderer.Render(0, f.mesh.rest_positions, {});
  const cv::Vec3b o = over.at<cv::Vec3b>(200, 300), b = bare.at<cv::Vec3b>(200, 300);
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(o[c], 0.4 * b[c] + 0.6 * f.camera.finger_rgb[2 - c], 1.0) << "channel " << c;
  }
}

TEST(Renderer, SegmentationWithTheWrittenRangeMatchesTheTruthMask) {
  const Fixture f = MakeFixture();
  const FrameRenderer renderer(f.camera, f.mesh, 11);
  const auto p = Deformed(f.mesh);
  const Disc finger{Vec2(320, 112 + 18 - 14.5), 14.0};
  const Disc pencil{Vec2(320, 377), 9.0};
  const cv::Mat frame = renderer.Render(5, p, {{pencil, f.camera.pencil_rgb, 1.0},
                                               {finger, f.camera.finger_rgb, f.camera.finger_opacity}});
  const HsvRange range = ObjectHsvRange(f.camera);
  std::string error;
  EXPECT_TRUE(ColoursSeparate(f.camera, &error)) << error;
  const BitMask segmented = SegmentFrame(frame, range, PixelRect{0, 0, 640, 480}, SegmentationOptions{});
  const BitMask truth = renderer.TruthMask(p);
  EXPECT_GT(truth.Count(), 90000);
  const double iou = IouAwayFrom(segmented, truth, finger, 3.0);
  EXPECT_GE(iou, 0.98) << "segmented " << segmented.Count() << " truth " << truth.Count();
}

TEST(Renderer, ColoursThatDoNotSeparateAreNamed) {
  CameraSpec camera;
  camera.background_rgb = {200, 180, 40};  // as yellow as the sponge
  std::string error;
  EXPECT_FALSE(ColoursSeparate(camera, &error));
  EXPECT_NE(error.find("camera.background_rgb"), std::string::npos) << error;
  camera = CameraSpec{};
  camera.object_rgb = {128, 128, 128};  // grey: no hue to segment by
  EXPECT_FALSE(ColoursSeparate(camera, &error));
  EXPECT_NE(error.find("camera.object_rgb"), std::string::npos) << error;
}

}  // namespace
}  // namespace calib::synth
