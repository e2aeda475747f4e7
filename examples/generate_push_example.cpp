// Writes the bundled example recording examples/push_centre: a yellow sponge
// (400 x 256 px) on a dark table, seen from above at 30 fps for 330 frames; a
// finger disc comes in at the middle of the top side, dents the sponge by up
// to 40 px, holds and retracts; a pencil disc stands against the bottom side.
// The sponge's outline is drawn kinematically (the rest rectangle, pushed in
// by the finger with a smooth dent that recovers when it leaves), not by the
// calibrated model. The force column is a smooth function of the dent depth.
//
//   calib_example_generator OUT_DIR

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  const std::filesystem::path out = argv[1];
  std::filesystem::create_directories(out);
  const int width = 640, height = 480, frames = 330;
  const double fps = 30.0;
  const double x0 = 120, y0 = 112, x1 = 520, y1 = 368;  // sponge 400 x 256
  const double finger_r = 14.0, pencil_r = 9.0, cx = 320.0;

  cv::VideoWriter video(
      (out / "video.mp4").string(), cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps,
      cv::Size(width, height));
  if (!video.isOpened()) {
    std::fprintf(stderr, "cannot open %s\n", (out / "video.mp4").c_str());
    return 1;
  }
  std::ofstream track(out / "track.csv");
  track << "frame,finger_x,finger_y,finger_r,pencil_x,pencil_y,pencil_r,force_x,force_y\n";

  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 4.0);
  for (int f = 0; f < frames; ++f) {
    const double t = static_cast<double>(f) / (frames - 1);
    const double push = 40.0 * std::clamp(std::min(t / 0.4, (1.0 - t) / 0.3), 0.0, 1.0);
    const double finger_y = y0 - finger_r + push;
    // The top side follows the finger with a smooth dent (width ~ 3 finger
    // radii) while the far side bulges a little sideways.
    std::vector<cv::Point> outline;
    const int n = 200;
    for (int i = 0; i <= n; ++i) {
      const double x = x0 + (x1 - x0) * i / n;
      const double u = (x - cx) / (3.0 * finger_r);
      const double dent = push * std::exp(-u * u);
      outline.emplace_back(cvRound(x * 16), cvRound((y0 + dent) * 16));
    }
    const double bulge = 0.08 * push;
    for (int i = 0; i <= n; ++i) {
      const double s = static_cast<double>(i) / n;
      const double y = y0 + (y1 - y0) * s;
      outline.emplace_back(cvRound((x1 + bulge * std::sin(M_PI * s)) * 16), cvRound(y * 16));
    }
    for (int i = n; i >= 0; --i) {
      const double x = x0 + (x1 - x0) * i / n;
      outline.emplace_back(cvRound(x * 16), cvRound(y1 * 16));
    }
    for (int i = n; i >= 0; --i) {
      const double s = static_cast<double>(i) / n;
      const double y = y0 + (y1 - y0) * s;
      outline.emplace_back(cvRound((x0 - bulge * std::sin(M_PI * s)) * 16), cvRound(y * 16));
    }

    cv::Mat image(height, width, CV_8UC3);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const int shade = 55 + (x + y) / 40;  // table with a lighting gradient
        image.at<cv::Vec3b>(y, x) = cv::Vec3b(shade, shade, shade + 5);
      }
    }
    cv::fillPoly(image, std::vector<std::vector<cv::Point>>{outline}, cv::Scalar(40, 200, 225),
                 cv::LINE_AA, 4);
    cv::circle(image, cv::Point(cvRound(cx * 16), cvRound(finger_y * 16)),
               cvRound(finger_r * 16), cv::Scalar(150, 170, 215), cv::FILLED, cv::LINE_AA, 4);
    cv::circle(image, cv::Point(cvRound(cx * 16), cvRound((y1 + pencil_r) * 16)),
               cvRound(pencil_r * 16), cv::Scalar(60, 60, 160), cv::FILLED, cv::LINE_AA, 4);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        auto& px = image.at<cv::Vec3b>(y, x);
        const double d = noise(rng);
        for (int c = 0; c < 3; ++c) px[c] = cv::saturate_cast<uchar>(px[c] + d);
      }
    }
    cv::GaussianBlur(image, image, cv::Size(3, 3), 0.7);
    video.write(image);
    const double force = 0.04 * push + 0.0006 * push * push;
    track << fmt::format("{},{:.3f},{:.3f},{:.1f},{:.3f},{:.3f},{:.1f},{:.4f},{:.4f}\n", f, cx,
                         finger_y, finger_r, cx, y1 + pencil_r, pencil_r, 0.0, force);
  }
  std::ofstream(out / "recording.json") << R"({
  "format": "sponge-recording/1",
  "video": "video.mp4",
  "track": "track.csv",
  "fps": 30,
  "mm_per_px": 0.25,
  "object": {
    "color_hsv_lower": [20, 90, 90],
    "color_hsv_upper": [40, 255, 255]
  },
  "force_obstacle": "finger",
  "roi": [0, 0, 640, 480],
  "notes": "Bundled example: a kinematically drawn centre push (examples/generate_push_example.cpp)."
}
)";
  return 0;
}
