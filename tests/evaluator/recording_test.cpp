#include "calib/evaluator/recording.h"

#include "calib/evaluator/media.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace calib {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kWidth = 64;
constexpr int kHeight = 48;
constexpr int kFrames = 5;

cv::Mat SyntheticFrame(int index) {
  cv::Mat frame(kHeight, kWidth, CV_8UC3, cv::Scalar(60, 30, 20));
  cv::circle(frame, cv::Point(20 + 4 * index, 24), 10, cv::Scalar(40, 200, 220), cv::FILLED);
  return frame;
}

void WriteAviVideo(const fs::path& file, int frames) {
  VideoWriter writer;
  ASSERT_TRUE(writer.Open(file, FourCC("MJPG"), 30.0, cv::Size(kWidth, kHeight))) << file;
  for (int i = 0; i < frames; ++i) writer.Write(SyntheticFrame(i));
}

void WritePngSequence(const fs::path& folder, int frames) {
  fs::create_directories(folder);
  for (int i = 0; i < frames; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    ASSERT_TRUE(WriteImage(folder / name, SyntheticFrame(i)));
  }
}

void WriteText(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
}

/// A valid recording (two obstacles, a force sensor on "finger") that each
/// test breaks in one way before writing it.
struct RecordingFixture {
  fs::path dir;
  json doc;
  std::string track;

  explicit RecordingFixture(const std::string& name) : dir(testing::ScratchDir(name)) {
    doc = {{"format", "sponge-recording/1"},
           {"video", "video.avi"},
           {"track", "track.csv"},
           {"fps", 30},
           {"mm_per_px", 0.25},
           {"object", {{"color_hsv_lower", {20, 90, 90}}, {"color_hsv_upper", {40, 255, 255}}}},
           {"force_obstacle", "finger"},
           {"roi", {2, 3, 60, 40}},
           {"clamps", {{10, 0, 20, 4}}},
           {"notes", "synthetic"}};
    track = "frame,finger_x,finger_y,finger_r,pencil_x,pencil_y,pencil_r,force_x,force_y\n";
    for (int i = 0; i < kFrames; ++i) {
      track += std::to_string(i) + "," + std::to_string(10 + i) + ".5,12,4," + "40,30.25,3," +
               std::to_string(0.1 * i) + ",-0.5\n";
    }
    WriteAviVideo(dir / "video.avi", kFrames);
  }

  void Write() const {
    WriteText(dir / "recording.json", doc.dump(2));
    WriteText(dir / "track.csv", track);
  }

  /// The message of the RecordingError that loading throws ("" and a test
  /// failure when it loads).
  std::string LoadError() const {
    Write();
    try {
      LoadRecording(dir);
    } catch (const RecordingError& e) {
      return e.what();
    }
    ADD_FAILURE() << "LoadRecording(" << dir << ") did not throw";
    return "";
  }

  std::string JsonPath() const { return (dir / "recording.json").string(); }
  std::string TrackPath() const { return (dir / "track.csv").string(); }
  std::string VideoPath() const { return (dir / "video.avi").string(); }
};

/// Replaces the first occurrence of `from` in `text` by `to`.
std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  if (pos != std::string::npos) text.replace(pos, from.size(), to);
  return text;
}

#define EXPECT_HAS(message, part) \
  EXPECT_NE(std::string(message).find(part), std::string::npos) << "message: " << (message)

TEST(Recording, LoadsValidRecording) {
  RecordingFixture fx("rec");
  fx.Write();
  const Recording rec = LoadRecording(fx.dir);
  EXPECT_EQ(rec.video_path, fx.dir / "video.avi");
  EXPECT_EQ(rec.track_path, fx.dir / "track.csv");
  EXPECT_DOUBLE_EQ(rec.fps, 30.0);
  ASSERT_TRUE(rec.mm_per_px.has_value());
  EXPECT_DOUBLE_EQ(*rec.mm_per_px, 0.25);
  EXPECT_EQ(rec.object_hsv.lower, (std::array<int, 3>{20, 90, 90}));
  EXPECT_EQ(rec.object_hsv.upper, (std::array<int, 3>{40, 255, 255}));
  ASSERT_TRUE(rec.force_obstacle.has_value());
  EXPECT_EQ(*rec.force_obstacle, "finger");
  EXPECT_EQ(rec.roi.x, 2);
  EXPECT_EQ(rec.roi.y, 3);
  EXPECT_EQ(rec.roi.width, 60);
  EXPECT_EQ(rec.roi.height, 40);
  ASSERT_EQ(rec.clamps.size(), 1u);
  EXPECT_EQ(rec.clamps[0].width, 20);
  EXPECT_EQ(rec.notes, "synthetic");
  EXPECT_EQ(rec.frame_width, kWidth);
  EXPECT_EQ(rec.frame_height, kHeight);
  EXPECT_EQ(rec.num_frames, kFrames);

  ASSERT_EQ(rec.obstacles.size(), 2u);
  EXPECT_EQ(rec.obstacles[0].name, "finger");
  EXPECT_EQ(rec.obstacles[1].name, "pencil");
  EXPECT_EQ(rec.ForceObstacleIndex(), 0);
  for (int i = 0; i < kFrames; ++i) {
    const Disc& finger = rec.obstacles[0].discs.at(i);
    EXPECT_DOUBLE_EQ(finger.centre.x(), 10.5 + i) << "frame " << i;
    EXPECT_DOUBLE_EQ(finger.centre.y(), 12.0) << "frame " << i;
    EXPECT_DOUBLE_EQ(finger.radius_px, 4.0) << "frame " << i;
    EXPECT_DOUBLE_EQ(rec.obstacles[1].discs.at(i).centre.y(), 30.25) << "frame " << i;
    EXPECT_NEAR(rec.forces.at(i).x(), 0.1 * i, 1e-6) << "frame " << i;
    EXPECT_DOUBLE_EQ(rec.forces.at(i).y(), -0.5) << "frame " << i;
  }
}

TEST(Recording, LoadsImageSequencePattern) {
  RecordingFixture fx("rec");
  WritePngSequence(fx.dir / "frames", kFrames);
  fx.doc["video"] = "frames/%06d.png";
  fx.Write();
  const Recording rec = LoadRecording(fx.dir);
  EXPECT_EQ(rec.num_frames, kFrames);
  EXPECT_EQ(rec.frame_width, kWidth);
  EXPECT_EQ(rec.frame_height, kHeight);
}

TEST(Recording, OptionalKeysAbsentGiveDefaults) {
  RecordingFixture fx("rec");
  for (const char* key : {"mm_per_px", "force_obstacle", "roi", "clamps", "notes"}) {
    fx.doc.erase(key);
  }
  fx.Write();
  const Recording rec = LoadRecording(fx.dir);
  EXPECT_FALSE(rec.mm_per_px.has_value());
  EXPECT_FALSE(rec.force_obstacle.has_value());
  EXPECT_EQ(rec.ForceObstacleIndex(), -1);
  EXPECT_TRUE(rec.forces.empty());
  EXPECT_EQ(rec.roi.x, 0);
  EXPECT_EQ(rec.roi.y, 0);
  EXPECT_EQ(rec.roi.width, kWidth) << "absent roi must be the whole frame";
  EXPECT_EQ(rec.roi.height, kHeight);
  EXPECT_TRUE(rec.clamps.empty());
  EXPECT_EQ(rec.obstacles.size(), 2u);
}

TEST(Recording, NullForceObstacleMeansNoForces) {
  RecordingFixture fx("rec");
  fx.doc["force_obstacle"] = nullptr;
  fx.track = "frame\n0\n1\n2\n3\n4\n";
  fx.Write();
  const Recording rec = LoadRecording(fx.dir);
  EXPECT_FALSE(rec.force_obstacle.has_value());
  EXPECT_TRUE(rec.obstacles.empty());
  EXPECT_TRUE(rec.forces.empty());
}

TEST(Recording, UnknownKeysAndColumnsAreIgnored) {
  RecordingFixture fx("rec");
  fx.doc["camera"] = {{"model", "x"}};
  fx.doc["object"]["name"] = "sponge";
  fx.track =
      "frame,temperature,finger_x,finger_y,finger_r,force_x,force_y,pencil_x,pencil_y,"
      "pencil_r\n";
  for (int i = 0; i < kFrames; ++i) fx.track += std::to_string(i) + ",warm,1,2,3,0,0,4,5,6\n";
  fx.Write();
  const Recording rec = LoadRecording(fx.dir);
  ASSERT_EQ(rec.obstacles.size(), 2u);
  EXPECT_EQ(rec.obstacles[0].name, "finger");
  EXPECT_EQ(rec.obstacles[1].name, "pencil");
  EXPECT_DOUBLE_EQ(rec.obstacles[1].discs[0].radius_px, 6.0);
}

TEST(Recording, QuotedCsvFieldsAreParsed) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, "\n0,10.5,", "\n\"0\",\"10.5\",");
  fx.Write();
  EXPECT_DOUBLE_EQ(LoadRecording(fx.dir).obstacles[0].discs[0].centre.x(), 10.5);
}

// ---------------------------------------------------------------------------
// One test per kind of malformed input.

TEST(RecordingError, MissingRecordingJsonNamesFile) {
  RecordingFixture fx("rec");
  fx.Write();
  fs::remove(fx.dir / "recording.json");
  try {
    LoadRecording(fx.dir);
    FAIL() << "no error";
  } catch (const RecordingError& e) {
    EXPECT_HAS(e.what(), fx.JsonPath());
    EXPECT_HAS(e.what(), "cannot open");
  }
}

TEST(RecordingError, InvalidJsonNamesFile) {
  RecordingFixture fx("rec");
  fx.Write();
  WriteText(fx.dir / "recording.json", "{\"format\": \"sponge-recording/1\",");
  try {
    LoadRecording(fx.dir);
    FAIL() << "no error";
  } catch (const RecordingError& e) {
    EXPECT_HAS(e.what(), fx.JsonPath());
    EXPECT_HAS(e.what(), "invalid JSON");
  }
}

TEST(RecordingError, MissingRequiredKeyNamesKey) {
  for (const std::string key : {"format", "video", "track", "fps", "object"}) {
    RecordingFixture fx("rec");
    fx.doc.erase(key);
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, fx.JsonPath());
    EXPECT_HAS(message, "missing required key '" + key + "'");
  }
  for (const std::string key : {"color_hsv_lower", "color_hsv_upper"}) {
    RecordingFixture fx("rec");
    fx.doc["object"].erase(key);
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, fx.JsonPath());
    EXPECT_HAS(message, "missing required key 'object." + key + "'");
  }
}

TEST(RecordingError, WrongTypeNamesKeyAndValue) {
  struct Case {
    std::string key;
    json value;
    std::string expected;
  };
  const Case cases[] = {{"fps", "thirty", "key 'fps' must be a number"},
                        {"video", 3, "key 'video' must be a string"},
                        {"track", json::array(), "key 'track' must be a string"},
                        {"object", "yellow", "key 'object' must be an object"},
                        {"roi", {0, 0, 10}, "key 'roi' must be an array"},
                        {"roi", {0, 0, 10.5, 10}, "key 'roi[2]' must be an integer"},
                        {"clamps", {{"a", 0, 1, 1}}, "key 'clamps[0][0]' must be a number"},
                        {"clamps", 5, "key 'clamps' must be an array"},
                        {"force_obstacle", 1, "key 'force_obstacle' must be a string"},
                        {"mm_per_px", "small", "key 'mm_per_px' must be a number"},
                        {"notes", 7, "key 'notes' must be a string"}};
  for (const Case& c : cases) {
    RecordingFixture fx("rec");
    fx.doc[c.key] = c.value;
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, fx.JsonPath());
    EXPECT_HAS(message, c.expected);
  }
  RecordingFixture fx("rec");
  fx.doc["object"]["color_hsv_lower"] = "20,90,90";
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, "key 'object.color_hsv_lower' must be an array");
}

TEST(RecordingError, WrongFormatStringNamesValue) {
  RecordingFixture fx("rec");
  fx.doc["format"] = "sponge-recording/2";
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.JsonPath());
  EXPECT_HAS(message, "'format'");
  EXPECT_HAS(message, "sponge-recording/2");
}

TEST(RecordingError, MissingVideoFileNamesFile) {
  RecordingFixture fx("rec");
  fx.doc["video"] = "absent.mp4";
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, (fx.dir / "absent.mp4").string());
}

TEST(RecordingError, UnreadableVideoNamesFile) {
  RecordingFixture fx("rec");
  WriteText(fx.dir / "video.avi", "this is not a video");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.VideoPath());
  EXPECT_HAS(message, "cannot open video");
}

TEST(RecordingError, MissingTrackFileNamesFile) {
  RecordingFixture fx("rec");
  fx.doc["track"] = "absent.csv";
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, (fx.dir / "absent.csv").string());
  EXPECT_HAS(message, "cannot open");
}

TEST(RecordingError, BadNumberNamesRowAndColumn) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, "\n2,12.5,", "\n2,12.5x,");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "row 2 (line 4)");
  EXPECT_HAS(message, "column 'finger_x'");
  EXPECT_HAS(message, "'12.5x'");
}

TEST(RecordingError, MalformedCsvNamesFileAndLine) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, "\n1,", "\n\"1,");  // a quote that never closes
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "CSV parse error at line");
}

TEST(RecordingError, EmptyCellNamesRowAndColumn) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, ",30.25,3,0.3", ",30.25,,0.3");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, "row 3 (line 5)");
  EXPECT_HAS(message, "column 'pencil_r'");
}

TEST(RecordingError, NonFiniteNumberNamesRowAndColumn) {
  for (const std::string bad : {"nan", "inf", "-inf"}) {
    RecordingFixture fx("rec");
    fx.track = Replace(fx.track, "\n1,11.5,12,", "\n1,11.5," + bad + ",");
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, fx.TrackPath());
    EXPECT_HAS(message, "row 1 (line 3)");
    EXPECT_HAS(message, "column 'finger_y'");
    EXPECT_HAS(message, "non-finite");
  }
}

TEST(RecordingError, NonPositiveFpsNamesValue) {
  for (const double fps : {0.0, -30.0}) {
    RecordingFixture fx("rec");
    fx.doc["fps"] = fps;
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, fx.JsonPath());
    EXPECT_HAS(message, "'fps'");
    EXPECT_HAS(message, "> 0");
  }
}

TEST(RecordingError, AbsurdFpsIsNamedAsTheRecordings) {
  RecordingFixture fx("rec");
  fx.doc["fps"] = 1e308;
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.JsonPath());
  EXPECT_HAS(message, "key 'fps' = 1e+308 must be <=");
}

TEST(RecordingError, AnObstacleFarOutsideTheFrameNamesRowAndColumn) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, ",30.25,3,0.3", ",1e308,3,0.3");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "row 3 (line 5), column 'pencil_y'");
  EXPECT_HAS(message, "from the frame");
}

TEST(RecordingError, APathOutsideTheFolderIsNamed) {
  for (const std::string bad : {"/etc/passwd", "../../video.mp4", "sub/../../video.mp4"}) {
    for (const std::string key : {"video", "track"}) {
      RecordingFixture fx("rec");
      fx.doc[key] = bad;
      const std::string message = fx.LoadError();
      EXPECT_HAS(message, fx.JsonPath());
      EXPECT_HAS(message, "key '" + key + "' = '" + bad + "': must be a path inside the recording folder");
    }
  }
}

TEST(RecordingError, ASymbolicLinkOutOfTheFolderIsNamed) {
  const fs::path elsewhere = testing::ScratchDir("rec_elsewhere");
  {
    RecordingFixture fx("rec");
    WriteText(elsewhere / "track.csv", fx.track);
    fs::create_symlink(elsewhere / "track.csv", fx.dir / "link.csv");
    fx.doc["track"] = "link.csv";
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, fx.JsonPath());
    EXPECT_HAS(message, "key 'track' = 'link.csv': must be a path inside the recording folder");
    EXPECT_HAS(message, "a symbolic link leads to " + (elsewhere / "track.csv").string());
  }
  {
    RecordingFixture fx("rec");
    fs::copy_file(fx.dir / "video.avi", elsewhere / "video.avi");
    fs::create_directory_symlink(elsewhere, fx.dir / "media");
    fx.doc["video"] = "media/video.avi";
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, "key 'video' = 'media/video.avi': must be a path inside the recording folder");
  }
  // A link to the recording folder itself, or inside it, is fine.
  RecordingFixture fx("rec");
  fs::create_symlink("track.csv", fx.dir / "inner.csv");
  fx.doc["track"] = "inner.csv";
  fx.Write();
  fs::create_directory_symlink(fx.dir, elsewhere / "linked_recording");
  EXPECT_NO_THROW(LoadRecording(elsewhere / "linked_recording"));
}

TEST(RecordingError, ATrackThatIsNoRegularFileIsNamed) {
  RecordingFixture fx("rec");
  fx.doc["track"] = "endless";
  ASSERT_EQ(::mkfifo((fx.dir / "endless").c_str(), 0600), 0);
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, (fx.dir / "endless").string());
  EXPECT_HAS(message, "not a regular file");
}

TEST(RecordingError, FrameColumnOutOfOrderNamesRow) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, "\n3,", "\n4,");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "row 3 (line 5), column 'frame'");
  EXPECT_HAS(message, "expected 3");
}

TEST(RecordingError, MissingFrameColumnNamesColumn) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, "frame,", "index,");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "column 'frame'");
}

TEST(RecordingError, RowCountMismatchNamesBothCounts) {
  RecordingFixture fx("rec");
  fx.track = fx.track.substr(0, fx.track.rfind("\n4,") + 1);  // drops the last row
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "4 data rows");
  EXPECT_HAS(message, "5 frames");
  EXPECT_HAS(message, fx.VideoPath());
}

TEST(RecordingError, RowWithWrongFieldCountNamesRow) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, ",-0.5\n", ",-0.5,7\n");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, "row 0 (line 2) has 10 fields; the header has 9");
}

TEST(RecordingError, ForceColumnsMissingWhenForceObstacleSet) {
  RecordingFixture fx("rec");
  fx.track = "frame,finger_x,finger_y,finger_r,force_x\n";
  for (int i = 0; i < kFrames; ++i) fx.track += std::to_string(i) + ",1,2,3,0\n";
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "missing column 'force_y'");
  EXPECT_HAS(message, "force_obstacle is 'finger'");
}

TEST(RecordingError, ForceObstacleNamingNoObstacle) {
  RecordingFixture fx("rec");
  fx.doc["force_obstacle"] = "thumb";
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "force_obstacle 'thumb'");
  EXPECT_HAS(message, "'finger', 'pencil'");
}

TEST(RecordingError, PartialObstacleColumnsNameTheMissingOne) {
  RecordingFixture fx("rec");
  fx.track = Replace(fx.track, "pencil_r,", "pencil_radius,");
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.TrackPath());
  EXPECT_HAS(message, "obstacle 'pencil' lacks column 'pencil_r'");
}

TEST(RecordingError, RoiOutsideFrameNamesValue) {
  RecordingFixture fx("rec");
  fx.doc["roi"] = {10, 10, 60, 40};
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.JsonPath());
  EXPECT_HAS(message, "key 'roi' = [10, 10, 60, 40] is not inside the 64 x 48 frame");
}

TEST(RecordingError, RoiNonPositiveSizeNamesValue) {
  RecordingFixture fx("rec");
  fx.doc["roi"] = {0, 0, 0, 40};
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, "key 'roi' = [0, 0, 0, 40] has a non-positive size");
}

TEST(RecordingError, ClampOutsideFrameNamesIndex) {
  RecordingFixture fx("rec");
  fx.doc["clamps"] = {{0, 0, 4, 4}, {-1, 0, 4, 4}};
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, fx.JsonPath());
  EXPECT_HAS(message, "key 'clamps[1]' = [-1, 0, 4, 4] is not inside the 64 x 48 frame");
}

TEST(RecordingError, ClampNonPositiveSizeNamesIndex) {
  RecordingFixture fx("rec");
  fx.doc["clamps"] = {{0, 0, 4, -2}};
  const std::string message = fx.LoadError();
  EXPECT_HAS(message, "key 'clamps[0]' = [0, 0, 4, -2] has a non-positive size");
}

TEST(RecordingError, HsvOutOfRangeNamesElement) {
  struct Case {
    std::string key;
    json value;
    std::string expected;
  };
  const Case cases[] = {
      {"color_hsv_upper", {180, 255, 255}, "'object.color_hsv_upper[0]' = 180 out of range"},
      {"color_hsv_lower", {20, -1, 90}, "'object.color_hsv_lower[1]' = -1 out of range"},
      {"color_hsv_upper", {40, 255, 256}, "'object.color_hsv_upper[2]' = 256 out of range"},
      {"color_hsv_lower", {50, 90, 90}, "'object.color_hsv_lower[0]' = 50 exceeds"}};
  for (const Case& c : cases) {
    RecordingFixture fx("rec");
    fx.doc["object"][c.key] = c.value;
    const std::string message = fx.LoadError();
    EXPECT_HAS(message, fx.JsonPath());
    EXPECT_HAS(message, c.expected);
  }
}

TEST(RecordingError, MissingFolderNamesFolder) {
  const fs::path dir = testing::ScratchDir("rec") / "absent";
  try {
    LoadRecording(dir);
    FAIL() << "no error";
  } catch (const RecordingError& e) {
    EXPECT_HAS(e.what(), dir.string());
  }
}

// ---------------------------------------------------------------------------

TEST(Recording, RealRecordingConcave1Loads) {
  const fs::path dir = testing::RealRecordingsDir() / "concave_1";
  if (!fs::exists(dir / "recording.json")) GTEST_SKIP() << "no real recording at " << dir;
  const Recording rec = LoadRecording(dir);
  EXPECT_EQ(rec.num_frames, 1074);
  EXPECT_EQ(rec.frame_width, 640);
  EXPECT_EQ(rec.frame_height, 360);
  EXPECT_NEAR(rec.fps, 239.76, 1e-9);
  EXPECT_TRUE(rec.obstacles.empty());
  EXPECT_FALSE(rec.force_obstacle.has_value());
  EXPECT_TRUE(rec.forces.empty());
  ASSERT_EQ(rec.clamps.size(), 1u);
  EXPECT_EQ(rec.clamps[0].x, 270);
  EXPECT_EQ(rec.clamps[0].width, 75);
  EXPECT_EQ(rec.roi.width, 640);
  EXPECT_EQ(rec.roi.height, 360);
}

}  // namespace
}  // namespace calib
