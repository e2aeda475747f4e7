#include "calib/evaluator/segmentation.h"

#include "calib/evaluator/bit_mask_cv.h"
#include "calib/evaluator/media.h"
#include "calib/evaluator/segmentation_cache.h"
#include "support/test_support.h"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <bit>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;

// The object is a saturated yellow (HSV 30, 190, 210) on dark blue cloth.
const HsvRange kObjectHsv{{20, 110, 90}, {40, 255, 255}};
const cv::Scalar kBackgroundBgr(70, 45, 35);

cv::Scalar ObjectBgr() {
  cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(30, 190, 210)), bgr;
  cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
  const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
  return cv::Scalar(c[0], c[1], c[2]);
}

/// A concave outline (a blob with a notch) centred at `c`, pixels.
std::vector<cv::Point> BlobOutline(cv::Point c, double scale) {
  const std::vector<cv::Point2d> unit = {{-1.0, -0.7}, {-0.2, -0.8}, {0.0, -0.3},
                                         {0.3, -0.8},  {1.0, -0.6},  {1.1, 0.2},
                                         {0.6, 0.8},   {-0.4, 0.9},  {-1.1, 0.3}};
  std::vector<cv::Point> points;
  for (const cv::Point2d& u : unit) points.emplace_back(c.x + scale * u.x, c.y + scale * u.y);
  return points;
}

struct MaskScene {
  cv::Mat bgr;    ///< the rendered, degraded frame
  cv::Mat truth;  ///< CV_8UC1 0/255: the object as drawn
};

/// Paints `truth` in the object colour on the background and degrades it:
/// a lighting gradient (x0.7 at the left to x1.05 at the right), gaussian
/// pixel noise (sigma 10), one speckle per 4000 px (2 x 2 object-coloured
/// ones on the background, dark ones 3 px across on the object), then a
/// slight blur. `extra` is painted in the object colour but is not part of
/// the truth (distractors).
MaskScene Render(const cv::Mat& truth, const cv::Mat& extra = cv::Mat(), uint64_t seed = 7) {
  cv::RNG rng(seed);
  cv::Mat image(truth.size(), CV_8UC3, kBackgroundBgr);
  image.setTo(ObjectBgr(), truth);
  if (!extra.empty()) image.setTo(ObjectBgr(), extra);
  const int speckles = truth.cols * truth.rows / 4000;
  for (int i = 0; i < speckles; ++i) {
    const cv::Point p(rng.uniform(0, truth.cols), rng.uniform(0, truth.rows));
    if (truth.at<uint8_t>(p) != 0) {
      cv::circle(image, p, 1, kBackgroundBgr, cv::FILLED);
    } else {
      cv::rectangle(image, p, p + cv::Point(1, 1), ObjectBgr(), cv::FILLED);
    }
  }
  cv::Mat f;
  image.convertTo(f, CV_32FC3);
  for (int x = 0; x < f.cols; ++x) {
    f.col(x) *= 0.7 + 0.35 * x / f.cols;
  }
  cv::Mat noise(f.size(), CV_32FC3);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, 10.0);
  f += noise;
  f.convertTo(image, CV_8UC3);  // saturates
  cv::GaussianBlur(image, image, cv::Size(3, 3), 0.7);
  return {image, truth};
}

cv::Mat BlobTruth(cv::Size size, cv::Point centre, double scale) {
  cv::Mat truth(size, CV_8UC1, cv::Scalar(0));
  cv::fillPoly(truth, std::vector<std::vector<cv::Point>>{BlobOutline(centre, scale)},
               cv::Scalar(255));
  return truth;
}

double IoU(const BitMask& a, const BitMask& b) {
  EXPECT_TRUE(a.SameShape(b));
  int64_t inter = 0, uni = 0;
  for (size_t i = 0; i < a.words().size(); ++i) {
    inter += std::popcount(a.words()[i] & b.words()[i]);
    uni += std::popcount(a.words()[i] | b.words()[i]);
  }
  return uni == 0 ? 1.0 : static_cast<double>(inter) / uni;
}

PixelRect WholeFrame(const cv::Mat& m) { return {0, 0, m.cols, m.rows}; }

BitMask TruthOver(const cv::Mat& truth, const PixelRect& roi) {
  return FromMat(truth(cv::Rect(roi.x, roi.y, roi.width, roi.height)), roi.x, roi.y);
}

TEST(SegmentFrame, RecoversNoisyObject) {
  const MaskScene scene = Render(BlobTruth({480, 360}, {240, 180}, 140));
  const PixelRect roi = WholeFrame(scene.bgr);
  const BitMask mask = SegmentFrame(scene.bgr, kObjectHsv, roi, SegmentationOptions());
  ASSERT_EQ(mask.width(), 480);
  ASSERT_EQ(mask.height(), 360);
  const double iou = IoU(mask, TruthOver(scene.truth, roi));
  EXPECT_GE(iou, 0.98) << "IoU " << iou;
}

TEST(SegmentFrame, NeverSetsPixelsOutsideRoi) {
  const MaskScene scene = Render(BlobTruth({480, 360}, {240, 180}, 140));
  const PixelRect roi{150, 60, 200, 170};  // cuts through the object
  const BitMask mask = SegmentFrame(scene.bgr, kObjectHsv, roi, SegmentationOptions());
  EXPECT_EQ(mask.width(), roi.width);
  EXPECT_EQ(mask.height(), roi.height);
  EXPECT_EQ(mask.origin_x(), roi.x);
  EXPECT_EQ(mask.origin_y(), roi.y);
  const double iou = IoU(mask, TruthOver(scene.truth, roi));
  EXPECT_GE(iou, 0.98) << "IoU " << iou;

  // A roi of background only stays empty although the object is beside it.
  const PixelRect empty_roi{0, 0, 60, 60};
  ASSERT_EQ(cv::countNonZero(scene.truth(cv::Rect(0, 0, 60, 60))), 0);
  EXPECT_EQ(SegmentFrame(scene.bgr, kObjectHsv, empty_roi, SegmentationOptions()).Count(), 0);
}

TEST(SegmentFrame, KeepsOnlyLargestComponent) {
  const cv::Mat truth = BlobTruth({480, 360}, {260, 190}, 130);
  cv::Mat distractor(truth.size(), CV_8UC1, cv::Scalar(0));
  cv::circle(distractor, {40, 40}, 14, cv::Scalar(255), cv::FILLED);
  ASSERT_EQ(cv::countNonZero(truth & distractor), 0);
  const MaskScene scene = Render(truth, distractor);
  const PixelRect roi = WholeFrame(scene.bgr);
  const BitMask mask = SegmentFrame(scene.bgr, kObjectHsv, roi, SegmentationOptions());
  const cv::Mat on = ToMat(mask);
  cv::Mat near_distractor;
  cv::dilate(distractor, near_distractor, cv::Mat(), cv::Point(-1, -1), 3);
  EXPECT_EQ(cv::countNonZero(on & near_distractor), 0) << "the distractor blob was kept";
  const double iou = IoU(mask, TruthOver(truth, roi));
  EXPECT_GE(iou, 0.98) << "IoU " << iou;
}

TEST(SegmentFrame, FillsHolesOnlyWhenAsked) {
  const cv::Mat truth = BlobTruth({480, 360}, {240, 180}, 140);
  cv::Mat hole(truth.size(), CV_8UC1, cv::Scalar(0));
  cv::circle(hole, {230, 200}, 9, cv::Scalar(255), cv::FILLED);
  const MaskScene scene = Render(truth & ~hole);
  const PixelRect roi = WholeFrame(scene.bgr);

  SegmentationOptions opt;
  const BitMask filled = SegmentFrame(scene.bgr, kObjectHsv, roi, opt);
  EXPECT_TRUE(filled.Get(230, 200));
  EXPECT_GE(IoU(filled, TruthOver(truth, roi)), 0.98);

  opt.fill_holes = false;
  const BitMask holed = SegmentFrame(scene.bgr, kObjectHsv, roi, opt);
  EXPECT_FALSE(holed.Get(230, 200));
  EXPECT_GE(IoU(holed, TruthOver(truth & ~hole, roi)), 0.98);
}

TEST(SegmentFrame, NoObjectGivesEmptyMask) {
  const MaskScene scene = Render(cv::Mat(120, 160, CV_8UC1, cv::Scalar(0)));
  const BitMask mask = SegmentFrame(scene.bgr, kObjectHsv, WholeFrame(scene.bgr), {});
  EXPECT_EQ(mask.width(), 160);
  EXPECT_EQ(mask.Count(), 0);
}

TEST(SegmentationOptions, DefaultsAreValid) {
  std::string error;
  EXPECT_TRUE(SegmentationOptions().IsValid(&error)) << error;
}

TEST(SegmentationOptions, RejectsNegativeRadiiNamingField) {
  SegmentationOptions opt;
  opt.open_radius_px = -1;
  std::string error;
  EXPECT_FALSE(opt.IsValid(&error));
  EXPECT_NE(error.find("open_radius_px = -1"), std::string::npos) << error;
  EXPECT_NE(error.find("open_radius_px >= 0"), std::string::npos) << error;

  opt = SegmentationOptions();
  opt.close_radius_px = -3;
  EXPECT_FALSE(opt.IsValid(&error));
  EXPECT_NE(error.find("close_radius_px = -3"), std::string::npos) << error;

  EXPECT_THROW(SegmentFrame(cv::Mat(4, 4, CV_8UC3), kObjectHsv, {0, 0, 4, 4}, opt),
               std::invalid_argument);
}

TEST(SegmentationOptions, CacheKeyDiffersWithEveryOption) {
  const SegmentationOptions base;
  SegmentationOptions a = base, b = base, c = base;
  a.open_radius_px = 2;
  b.close_radius_px = 3;
  c.fill_holes = false;
  EXPECT_NE(a.CacheKey(), base.CacheKey());
  EXPECT_NE(b.CacheKey(), base.CacheKey());
  EXPECT_NE(c.CacheKey(), base.CacheKey());
  EXPECT_EQ(base.CacheKey(), SegmentationOptions().CacheKey());
}

TEST(BitMaskCv, RoundTripKeepsPixelsAndOrigin) {
  cv::Mat m(37, 130, CV_8UC1);  // 130 = two full words and a partial one per row
  cv::RNG rng(3);
  rng.fill(m, cv::RNG::UNIFORM, 0, 2);
  const BitMask mask = FromMat(m, 5, 9);
  EXPECT_EQ(mask.origin_x(), 5);
  EXPECT_EQ(mask.origin_y(), 9);
  EXPECT_EQ(mask.Count(), cv::countNonZero(m));
  const cv::Mat back = ToMat(mask);
  ASSERT_EQ(back.type(), CV_8UC1);
  EXPECT_EQ(cv::countNonZero(back != (m * 255)), 0);
  EXPECT_EQ(FromMat(back, 5, 9), mask);
}

// ---------------------------------------------------------------------------
// SegmentRecording and its cache, on a lossless PNG-sequence recording.

constexpr int kFrames = 5;

/// Writes a recording of a blob moving right, as frames/%06d.png.
Recording WriteSequenceRecording(const fs::path& dir) {
  fs::create_directories(dir / "frames");
  std::string track = "frame\n";
  for (int i = 0; i < kFrames; ++i) {
    const MaskScene scene = Render(BlobTruth({200, 150}, {80 + 8 * i, 75}, 45), cv::Mat(), 11 + i);
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    EXPECT_TRUE(WriteImage(dir / "frames" / name, scene.bgr));
    track += std::to_string(i) + "\n";
  }
  std::ofstream(dir / "track.csv") << track;
  std::ofstream(dir / "recording.json") << R"({
    "format": "sponge-recording/1", "video": "frames/%06d.png", "track": "track.csv",
    "fps": 30, "object": {"color_hsv_lower": [20, 110, 90], "color_hsv_upper": [40, 255, 255]},
    "roi": [10, 5, 180, 140]})";
  return LoadRecording(dir);
}

std::vector<fs::path> CacheFiles(const fs::path& dir) {
  std::vector<fs::path> files;
  if (!fs::exists(dir)) return files;
  for (const auto& entry : fs::directory_iterator(dir)) files.push_back(entry.path());
  return files;
}

TEST(SegmentRecording, MatchesSegmentFramePerFrame) {
  const fs::path dir = testing::ScratchDir("seg");
  const Recording rec = WriteSequenceRecording(dir / "rec");
  const SegmentationOptions opt;
  const std::vector<BitMask> masks = SegmentRecording(rec, opt, {});
  ASSERT_EQ(masks.size(), static_cast<size_t>(kFrames));
  for (int i = 0; i < kFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    const cv::Mat frame = ReadImage(dir / "rec" / "frames" / name);
    EXPECT_EQ(masks[i], SegmentFrame(frame, rec.object_hsv, rec.roi, opt)) << "frame " << i;
    EXPECT_GT(masks[i].Count(), 1000) << "frame " << i;
  }
  EXPECT_TRUE(CacheFiles(dir / "cache").empty());
}

TEST(SegmentRecording, CacheRoundTrip) {
  const fs::path dir = testing::ScratchDir("seg");
  const fs::path cache = dir / "cache";
  const Recording rec = WriteSequenceRecording(dir / "rec");
  const SegmentationOptions opt;
  const std::vector<BitMask> fresh = SegmentRecording(rec, opt, {});

  EXPECT_EQ(SegmentRecording(rec, opt, cache), fresh);
  const std::vector<fs::path> files = CacheFiles(cache);
  ASSERT_EQ(files.size(), 1u) << "one cache file, no temporary left behind";
  const uint64_t key = SegmentationCacheKey(rec, opt);
  EXPECT_EQ(files[0], SegmentationCachePath(cache, key));
  EXPECT_EQ(SegmentRecording(rec, opt, cache), fresh);

  // The second call reads the cache: masks planted under the key come back.
  std::vector<BitMask> planted = fresh;
  for (BitMask& m : planted) m.Clear();
  planted[2].Set(3, 4);
  ASSERT_TRUE(WriteSegmentationCache(files[0], key, planted));
  EXPECT_EQ(SegmentRecording(rec, opt, cache), planted);
}

TEST(SegmentRecording, TruncatedCacheIsIgnoredAndRewritten) {
  const fs::path dir = testing::ScratchDir("seg");
  const fs::path cache = dir / "cache";
  const Recording rec = WriteSequenceRecording(dir / "rec");
  const SegmentationOptions opt;
  const std::vector<BitMask> fresh = SegmentRecording(rec, opt, cache);
  const fs::path file = SegmentationCachePath(cache, SegmentationCacheKey(rec, opt));
  const auto full_size = fs::file_size(file);

  for (const uintmax_t size : {uintmax_t{0}, uintmax_t{20}, full_size / 2, full_size - 1}) {
    fs::resize_file(file, size);
    EXPECT_EQ(SegmentRecording(rec, opt, cache), fresh) << "truncated to " << size;
    EXPECT_EQ(fs::file_size(file), full_size) << "not rewritten after truncation to " << size;
  }
}

TEST(SegmentRecording, CorruptCacheIsIgnoredAndRewritten) {
  const fs::path dir = testing::ScratchDir("seg");
  const fs::path cache = dir / "cache";
  const Recording rec = WriteSequenceRecording(dir / "rec");
  const SegmentationOptions opt;
  const std::vector<BitMask> fresh = SegmentRecording(rec, opt, cache);
  const fs::path file = SegmentationCachePath(cache, SegmentationCacheKey(rec, opt));
  const auto size = fs::file_size(file);

  for (const std::streamoff offset :
       {std::streamoff{0}, std::streamoff{30}, static_cast<std::streamoff>(size / 2)}) {
    {
      std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
      f.seekg(offset);
      const char byte = static_cast<char>(f.get() ^ 0x5a);
      f.seekp(offset);
      f.put(byte);
    }
    std::vector<BitMask> unused;
    ASSERT_FALSE(ReadSegmentationCache(file, SegmentationCacheKey(rec, opt), kFrames, rec.roi.width,
                                       rec.roi.height, rec.roi.x, rec.roi.y, &unused))
        << "corruption at byte " << offset << " not detected";
    EXPECT_EQ(SegmentRecording(rec, opt, cache), fresh) << "byte " << offset;
    EXPECT_TRUE(ReadSegmentationCache(file, SegmentationCacheKey(rec, opt), kFrames, rec.roi.width,
                                      rec.roi.height, rec.roi.x, rec.roi.y, &unused))
        << "not rewritten after corruption at byte " << offset;
  }
}

TEST(SegmentRecording, CacheKeyFollowsContentAndOptions) {
  const fs::path dir = testing::ScratchDir("seg");
  Recording rec = WriteSequenceRecording(dir / "rec");
  const SegmentationOptions opt;
  const uint64_t key = SegmentationCacheKey(rec, opt);

  SegmentationOptions other = opt;
  other.close_radius_px = 4;
  EXPECT_NE(SegmentationCacheKey(rec, other), key);
  Recording shifted = rec;
  shifted.roi.x += 1;
  shifted.roi.width -= 1;
  EXPECT_NE(SegmentationCacheKey(shifted, opt), key);
  Recording recoloured = rec;
  recoloured.object_hsv.lower[1] += 1;
  EXPECT_NE(SegmentationCacheKey(recoloured, opt), key);

  // Editing one frame of the sequence changes the key: no stale cache hit.
  const fs::path cache = dir / "cache";
  SegmentRecording(rec, opt, cache);
  const cv::Mat blank(150, 200, CV_8UC3, kBackgroundBgr);
  ASSERT_TRUE(WriteImage(dir / "rec" / "frames" / "000003.png", blank));
  EXPECT_NE(SegmentationCacheKey(rec, opt), key);
  EXPECT_EQ(SegmentRecording(rec, opt, cache)[3].Count(), 0);
  EXPECT_EQ(CacheFiles(cache).size(), 2u);
}

TEST(SegmentRecording, CacheKeyCoversSequencesStartingAtOne) {
  const fs::path dir = testing::ScratchDir("seg");
  const Recording rec = WriteSequenceRecording(dir / "rec");
  for (int i = kFrames - 1; i >= 0; --i) {  // renumber 0..4 as 1..5
    char from[32], to[32];
    std::snprintf(from, sizeof(from), "%06d.png", i);
    std::snprintf(to, sizeof(to), "%06d.png", i + 1);
    fs::rename(dir / "rec" / "frames" / from, dir / "rec" / "frames" / to);
  }
  const uint64_t key = SegmentationCacheKey(rec, {});
  ASSERT_TRUE(WriteImage(dir / "rec" / "frames" / "000005.png",
                         cv::Mat(150, 200, CV_8UC3, kBackgroundBgr)));
  EXPECT_NE(SegmentationCacheKey(rec, {}), key) << "the last frame is not part of the key";
}

TEST(SegmentRecording, FewerVideoFramesThanRecordingNamesBothCounts) {
  const fs::path dir = testing::ScratchDir("seg");
  Recording rec = WriteSequenceRecording(dir / "rec");
  rec.num_frames = kFrames + 2;
  try {
    SegmentRecording(rec, SegmentationOptions(), {});
    FAIL() << "no error";
  } catch (const RecordingError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find(rec.video_path.string()), std::string::npos) << message;
    EXPECT_NE(message.find("yields 5 frames"), std::string::npos) << message;
    EXPECT_NE(message.find("has 7"), std::string::npos) << message;
  }
}

TEST(SegmentRecording, UnwritableCacheStillSegments) {
  const fs::path dir = testing::ScratchDir("seg");
  const Recording rec = WriteSequenceRecording(dir / "rec");
  std::ofstream(dir / "not_a_folder") << "x";
  const std::vector<BitMask> masks = SegmentRecording(rec, {}, dir / "not_a_folder" / "cache");
  EXPECT_EQ(masks, SegmentRecording(rec, {}, {}));
}

/// Sets (or unsets, for nullopt) an environment variable for one scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, std::optional<std::string> value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value) {
      ::setenv(name, value->c_str(), 1);
    } else {
      ::unsetenv(name);
    }
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_, old_->c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

TEST(DefaultSegmentationCacheDir, FollowsEnvironmentPrecedence) {
  ScopedEnv home("HOME", "/home/someone");
  ScopedEnv xdg("XDG_CACHE_HOME", std::nullopt);
  ScopedEnv calib("CALIB_CACHE_DIR", std::nullopt);
  EXPECT_EQ(DefaultSegmentationCacheDir(), fs::path("/home/someone/.cache/calib/segmentation"));
  {
    ScopedEnv set_xdg("XDG_CACHE_HOME", "/var/cache/me");
    EXPECT_EQ(DefaultSegmentationCacheDir(), fs::path("/var/cache/me/calib/segmentation"));
    ScopedEnv set_calib("CALIB_CACHE_DIR", "/tmp/calib-cache");
    EXPECT_EQ(DefaultSegmentationCacheDir(), fs::path("/tmp/calib-cache"));
  }
}

}  // namespace
}  // namespace calib
