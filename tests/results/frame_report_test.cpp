// The per-frame CSV: one row per frame, failure and not-simulated frames
// marked, and a reason holding separators and quotes read back intact by a
// CSV parser (libcsv).

#include "calib/results/frame_report.h"

#include "support/csv_support.h"
#include "support/test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace calib {
namespace {

using testing::ParseCsv;
using Rows = testing::CsvRows;

TEST(FrameReport, MarksFailedAndUnsimulatedFramesAndKeepsTheReasonIntact) {
  EvaluationResult result;
  result.status = EvaluationStatus::kFailed;
  result.num_frames = 5;
  result.failure_frame = 2;
  result.failure_reason = R"(node 3 left the scene ("12.5, 7" px), diverged)";
  result.frames = {FrameScore{}, FrameScore{}};
  result.frames[1].xor_px = 17.375;  // pixel areas, px^2
  result.frames[1].missed_px = 10.25;
  result.frames[1].extra_px = 7.125;
  result.frames[1].iou = 0.875;
  const auto path = testing::ScratchDir("report") / "frames.csv";
  WriteFrameReportCsv(path, result, 5);
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  const Rows rows = ParseCsv(text.str());
  ASSERT_EQ(rows.size(), 6u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"frame", "xor", "missed", "extra", "iou", "status",
                                               "reason"}));
  EXPECT_EQ(rows[2],
            (std::vector<std::string>{"1", "17.375", "10.25", "7.125", "0.875000", "ok", ""}));
  EXPECT_EQ(rows[3][5], "failed");
  EXPECT_EQ(rows[3][6], result.failure_reason);
  EXPECT_EQ(rows[4][5], "not_simulated");
  EXPECT_EQ(rows[5][0], "4");
}

TEST(FrameReport, CentroidColumnsWhereEachFrameHasOne) {
  EvaluationResult result;
  result.status = EvaluationStatus::kFailed;
  result.num_frames = 4;
  result.failure_frame = 2;
  result.failure_reason = "diverged";
  result.frames = {FrameScore{}, FrameScore{}};
  FrameCentroids centroids;
  centroids.mesh_px = {Vec2(10.5, 20.25), Vec2(11.0, 21.0)};
  centroids.object_px = {Vec2(10.0, 20.0), Vec2(NAN, NAN), Vec2(12.0, 22.5), Vec2(13.0, 23.0)};
  const auto path = testing::ScratchDir("report") / "frames_centroids.csv";
  WriteFrameReportCsv(path, result, 4, &centroids);
  const Rows rows = testing::ParseCsvFile(path);
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"frame", "xor", "missed", "extra", "iou", "status",
                                               "reason", "mesh_cx", "mesh_cy", "object_cx",
                                               "object_cy"}));
  const auto tail = [&](int row) {
    return std::vector<std::string>(rows[row].begin() + 7, rows[row].end());
  };
  EXPECT_EQ(tail(1), (std::vector<std::string>{"10.5", "20.25", "10", "20"}));
  EXPECT_EQ(tail(2), (std::vector<std::string>{"11", "21", "", ""})) << "no object in frame 1";
  EXPECT_EQ(tail(3), (std::vector<std::string>{"", "", "12", "22.5"})) << "failed: no mesh";
  EXPECT_EQ(tail(4), (std::vector<std::string>{"", "", "13", "23"}));
}

TEST(FrameReport, RecordingDifferenceHasOneRowPerFrame) {
  RecordingDifference d;
  d.frames = {FrameDifference{0, 0, 0, 450, 450, 1.0}, FrameDifference{30, 12, 18, 450, 456, 0.9375}};
  const auto path = testing::ScratchDir("report") / "difference.csv";
  WriteRecordingDifferenceCsv(path, d);
  const Rows rows = testing::ParseCsvFile(path);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"frame", "xor", "only_a", "only_b", "a", "b", "iou"}));
  EXPECT_EQ(rows[1], (std::vector<std::string>{"0", "0", "0", "0", "450", "450", "1.000000"}));
  EXPECT_EQ(rows[2], (std::vector<std::string>{"1", "30", "12", "18", "450", "456", "0.937500"}));
}

TEST(FrameReport, UnwritablePathIsNamed) {
  EvaluationResult result;
  try {
    WriteFrameReportCsv("/nonexistent-dir/frames.csv", result, 1);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/frames.csv"), std::string::npos);
  }
}

}  // namespace
}  // namespace calib
