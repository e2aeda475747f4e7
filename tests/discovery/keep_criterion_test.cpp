// The keep rule's judge (discovery/src/keep_criterion.cpp) where the model
// an effect is judged against fails on a held-out recording: the frames it
// simulated are compared, and the verdict says so.

#include "loop_stages.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace calib::loop_detail {
namespace {

EvaluationResult Result(const std::vector<double>& xor_per_frame, int frames_in_recording,
                        double iou) {
  EvaluationResult e;
  e.num_frames = frames_in_recording;
  const bool failed = static_cast<int>(xor_per_frame.size()) < frames_in_recording;
  e.status = failed ? EvaluationStatus::kFailed : EvaluationStatus::kOk;
  if (failed) {
    e.failure_frame = static_cast<int>(xor_per_frame.size());
    e.failure_reason = "a triangle inverted";
  }
  for (double x : xor_per_frame) {
    FrameScore f;
    f.xor_px = x;
    f.iou = iou;
    e.frames.push_back(f);
    e.xor_sum += x;
  }
  e.mean_iou = iou * static_cast<double>(xor_per_frame.size()) / frames_in_recording;
  return e;
}

Fit FitWith(EvaluationResult train, EvaluationResult held_out) {
  Fit fit;
  fit.results = {std::move(train), std::move(held_out)};
  return fit;
}

TEST(KeepCriterion, AReferenceThatFailsOnAHeldOutRecordingIsComparedOverTheFramesItSimulated) {
  LoopOptions options;
  options.min_relative_drop = 0.0;
  std::vector<LoopRecording> recs(2);
  recs[0].name = "push-a";
  recs[1].name = "push-b";
  recs[1].train = false;
  // 40 held-out frames; the previous model fails from frame 30.
  std::vector<double> before(30, 100.0), after(40, 60.0);
  const Fit previous = FitWith(Result({500.0}, 1, 0.9), Result(before, 40, 0.90));
  const Fit candidate = FitWith(Result({400.0}, 1, 0.9), Result(after, 40, 0.95));
  const KeepCriterion judge(options, recs);
  const KeepCriterion::Verdict v = judge.Judge(previous, nullptr, candidate, 7);
  EXPECT_EQ(v.test.frames, 30);
  EXPECT_DOUBLE_EQ(v.before, 3000.0);
  EXPECT_DOUBLE_EQ(v.after, 1800.0) << "over the same 30 frames";
  EXPECT_TRUE(v.eligible) << v.reason;
  EXPECT_LT(v.test.p_value, 0.01) << v.reason;
  EXPECT_NE(v.reason.find("the previous model fails on push-b from frame 30 (a triangle inverted): "
                          "compared over the 30 frames before"),
            std::string::npos)
      << v.reason;

  // The mean IoU too is compared over those frames: a candidate that
  // overlaps the object less there (0.85 against 0.90) does not pass,
  // though its IoU over all 40 frames beats the reference's with the 10
  // frames it did not simulate counted as 0 (0.675).
  const Fit overlaps_less = FitWith(Result({400.0}, 1, 0.9), Result(after, 40, 0.85));
  const KeepCriterion::Verdict fell = judge.Judge(previous, nullptr, overlaps_less, 7);
  EXPECT_FALSE(fell.eligible) << fell.reason;
  EXPECT_NE(fell.reason.find("held-out mean IoU 0.90000 -> 0.85000"), std::string::npos)
      << fell.reason;

  // Failing from the first frame leaves nothing to compare: not kept.
  const Fit broken = FitWith(Result({500.0}, 1, 0.9), Result({}, 40, 0.0));
  const KeepCriterion::Verdict none = judge.Judge(broken, nullptr, candidate, 7);
  EXPECT_FALSE(none.eligible);
  EXPECT_NE(none.reason.find("no held-out frame to compare"), std::string::npos) << none.reason;
}

}  // namespace
}  // namespace calib::loop_detail
