// The keep rule's judge (discovery/src/keep_criterion.cpp) where the model
// an effect is judged against fails on a held-out recording: the frames it
// simulated are compared (also with a candidate that fails there no
// earlier), and the verdict says so. And the refit of a fit
// that fails on a held-out recording (StageCalibrator::RefitWhereHeldOutFails):
// the best candidate on training that simulates there, or a note that none
// does.

#include "loop_stages.h"
#include "loop_test_support.h"

#include "calib/discovery/residual.h"
#include "calib/results/store.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
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

// push-a trained, push-b held out; any drop counts (no relevance margin).
struct TwoPushes {
  TwoPushes() {
    options.min_relative_drop = 0.0;
    recs[0].name = "push-a";
    recs[1].name = "push-b";
    recs[1].train = false;
  }
  LoopOptions options;
  std::vector<LoopRecording> recs = std::vector<LoopRecording>(2);
};

TEST(KeepCriterion, AReferenceThatFailsOnAHeldOutRecordingIsComparedOverTheFramesItSimulated) {
  const TwoPushes pushes;
  const LoopOptions& options = pushes.options;
  const std::vector<LoopRecording>& recs = pushes.recs;
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

TEST(KeepCriterion, ACandidateFailingNoEarlierThanAFailingReferenceIsComparedOverItsFrames) {
  const TwoPushes pushes;
  const KeepCriterion judge(pushes.options, pushes.recs);
  // The previous model fails on the held-out push from frame 30.
  const Fit previous = FitWith(Result({500.0}, 1, 0.9), Result(std::vector<double>(30, 100.0), 40, 0.90));

  // The candidate fails there too, from frame 35: the 30 frames compared.
  const Fit later = FitWith(Result({400.0}, 1, 0.9), Result(std::vector<double>(35, 60.0), 40, 0.95));
  const KeepCriterion::Verdict v = judge.Judge(previous, nullptr, later, 7);
  EXPECT_TRUE(v.eligible) << v.reason;
  EXPECT_EQ(v.test.frames, 30);
  EXPECT_DOUBLE_EQ(v.after, 1800.0);
  EXPECT_NE(v.reason.find("the previous model fails on push-b from frame 30 (a triangle inverted), this "
                          "one from frame 35: compared over the 30 frames before"),
            std::string::npos)
      << v.reason;

  // From frame 25, earlier than the reference: rejected, named.
  const Fit earlier = FitWith(Result({400.0}, 1, 0.9), Result(std::vector<double>(25, 60.0), 40, 0.95));
  const KeepCriterion::Verdict e = judge.Judge(previous, nullptr, earlier, 7);
  EXPECT_FALSE(e.eligible);
  EXPECT_EQ(e.reason,
            "the calibrated model fails to simulate push-b (held out) from frame 25: a triangle inverted");

  // Against a reference that simulates the whole push, any failure there
  // is a rejection.
  const Fit whole = FitWith(Result({500.0}, 1, 0.9), Result(std::vector<double>(40, 100.0), 40, 0.90));
  EXPECT_FALSE(judge.Judge(whole, nullptr, later, 7).eligible);
}

EvaluationRecord Candidate(int64_t id, const ParameterValues& parameters, double score) {
  EvaluationRecord e;
  e.id = id;
  e.parameters = parameters;
  e.ok = std::isfinite(score);
  e.score = e.ok ? score : std::numeric_limits<double>::quiet_NaN();
  if (!e.ok) {
    e.failure_frame = 3;
    e.reason = "a triangle inverted";
  }
  return e;
}

TEST(KeepCriterion, RankedByTrainingScoreIsDistinctBestFirstWithoutTheExcludedSet) {
  const ParameterValues a{{"k", 1.0}}, b{{"k", 2.0}}, c{{"k", 3.0}}, d{{"k", 4.0}};
  const std::vector<EvaluationRecord> evaluations = {
      Candidate(0, c, 30.0), Candidate(1, a, 10.0), Candidate(2, d, std::nan("")),
      Candidate(3, b, 20.0), Candidate(4, a, 10.0), Candidate(5, b, 15.0)};
  EXPECT_EQ(RankedByTrainingScore(evaluations, {}, 10), (std::vector<ParameterValues>{a, b, c}))
      << "failed ones left out, each set once at its best score";
  EXPECT_EQ(RankedByTrainingScore(evaluations, a, 10), (std::vector<ParameterValues>{b, c}));
  EXPECT_EQ(RankedByTrainingScore(evaluations, {}, 2), (std::vector<ParameterValues>{a, b}));
  EXPECT_TRUE(RankedByTrainingScore(evaluations, {}, 0).empty());
}

// push_centre trained, push_offset held out; a stiff calibration of
// push_centre with the implicit step simulates both.
class Refit : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    PreparationOptions preparation;
    preparation.cache_dir.clear();
    for (const char* name : {"push_centre", "push_offset"}) {
      LoopRecording r;
      r.name = name;
      r.train = recs_->empty();
      r.prepared = std::make_shared<const PreparedRecording>(
          PrepareRecording(LoadRecording(testing::ExamplesDir() / name), preparation));
      r.residual_facts = std::make_shared<const RecordingResidualFacts>(ComputeResidualFacts(*r.prepared));
      recs_->push_back(std::move(r));
    }
  }

  static ParameterValues Stiff() {
    return {{"k_D", 90581.063097572}, {"k_d", 20.754982960562106}, {"k_A", 210.80891451878225},
            {"k_phi", 12379.743243423809}, {"mass", 0.2}, {"tau", 0.3421273516392307}};
  }
  // A set the model rejects (mass must be > 0): it fails everywhere.
  static ParameterValues Rejected(double mass) {
    ParameterValues v = Stiff();
    v["mass"] = mass;
    return v;
  }
  // A fit that simulates the training recording and fails on the held-out
  // one from frame 12, with `values`, calibrated by the job `job`.
  static Fit FailingFit(const ParameterValues& values, int64_t job) {
    Fit fit;
    fit.values = values;
    fit.jobs = {job};
    fit.whole_recording_jobs = {job};
    EvaluationResult train;
    train.status = EvaluationStatus::kOk;
    train.xor_sum = 1000;
    EvaluationResult held_out;
    held_out.status = EvaluationStatus::kFailed;
    held_out.failure_frame = 12;
    held_out.failure_reason = "the mesh snapped through";
    fit.results = {train, held_out};
    return fit;
  }

  // The refit, then (with `sensitivity`) MeasureSensitivity.
  void Run(Fit* fit, int refit_candidates, ResultStore& store, const Fit* reference = nullptr,
           bool sensitivity = false) const {
    LoopOptions options;
    options.refit_candidates = refit_candidates;
    const KeepCriterion criterion(options, *recs_);
    const SearchScales scales;
    const LoopLog log;
    const StageCalibrator calibrator(options, *recs_, scales, criterion, store, 2, log);
    calibrator.RefitWhereHeldOutFails(fit, reference);
    if (sensitivity) calibrator.MeasureSensitivity(fit);
  }

  static inline std::unique_ptr<std::vector<LoopRecording>> recs_ =
      std::make_unique<std::vector<LoopRecording>>();
};

TEST_F(Refit, TakesTheBestCandidateOnTrainingThatSimulatesEveryHeldOutRecording) {
  ResultStore store(calib::testing::ScratchDir("refit_best") / "store.sqlite");
  const int64_t job = store.CreateJob("base", nlohmann::json::object());
  ParameterValues softer = Stiff();
  softer["k_D"] *= 0.5;
  const std::vector<EvaluationRecord> history = {
      Candidate(0, Rejected(-1.0), 100.0),     // best on training, fails held out
      Candidate(1, Stiff(), std::nan("")),     // failed on training: never a candidate
      Candidate(2, softer, 300.0), Candidate(3, Stiff(), 200.0), Candidate(4, Stiff(), 250.0)};
  store.RecordEvaluations(job, history);

  Fit fit = FailingFit(Rejected(-2.0), job);
  Run(&fit, 24, store);
  EXPECT_EQ(fit.values, Stiff()) << fit.refit;
  EXPECT_TRUE(fit.AllOk()) << "measured again on every recording";
  EXPECT_GT(fit.results[1].xor_sum, 0.0);
  EXPECT_NE(fit.refit.find("failed to simulate push_offset (held out) from frame 12 (the mesh snapped "
                           "through)"),
            std::string::npos)
      << fit.refit;
  EXPECT_NE(fit.refit.find("of its next 3 candidates by training XOR, number 2 is the first that "
                           "simulates every held-out recording"),
            std::string::npos)
      << fit.refit;
}

// A swing calibration's shorter horizons score fewer frames: their
// candidates' lower scores do not rank against the fit's, and only its
// jobs over the whole recordings give the refit its candidates.
TEST_F(Refit, RanksOnlyTheCandidatesOfJobsOverTheWholeRecordings) {
  ResultStore store(calib::testing::ScratchDir("refit_horizons") / "store.sqlite");
  const int64_t short_horizon = store.CreateJob("inertia-frames45", nlohmann::json::object());
  const int64_t whole = store.CreateJob("inertia", nlohmann::json::object());
  ParameterValues softer = Stiff();
  softer["k_D"] *= 0.5;
  const std::vector<EvaluationRecord> short_history = {Candidate(0, softer, 50.0)};
  const std::vector<EvaluationRecord> whole_history = {Candidate(0, Rejected(-1.0), 100.0),
                                                       Candidate(1, Stiff(), 200.0)};
  store.RecordEvaluations(short_horizon, short_history);
  store.RecordEvaluations(whole, whole_history);

  Fit fit = FailingFit(Rejected(-2.0), whole);
  fit.jobs = {short_horizon, whole};
  Run(&fit, 24, store);
  EXPECT_EQ(fit.values, Stiff()) << fit.refit;
  EXPECT_NE(fit.refit.find("of its next 2 candidates by training XOR, number 2"), std::string::npos)
      << fit.refit;
}

TEST_F(Refit, SaysSoWhereNoCandidateSimulatesAndLeavesTheFitAlone) {
  ResultStore store(calib::testing::ScratchDir("refit_none") / "store.sqlite");
  const int64_t job = store.CreateJob("base", nlohmann::json::object());
  const std::vector<EvaluationRecord> history = {Candidate(0, Rejected(-1.0), 100.0),
                                                 Candidate(1, Rejected(-3.0), 150.0),
                                                 Candidate(2, Stiff(), 200.0)};
  store.RecordEvaluations(job, history);

  // Only the two best are tried: neither simulates.
  Fit fit = FailingFit(Rejected(-2.0), job);
  Run(&fit, 2, store);
  EXPECT_EQ(fit.values, Rejected(-2.0));
  EXPECT_FALSE(fit.AllOk());
  EXPECT_NE(fit.refit.find("none of its next 2 candidates by training XOR simulates every held-out "
                           "recording"),
            std::string::npos)
      << fit.refit;

  // Off: the failing fit is left to the judge as it is.
  Fit off = FailingFit(Rejected(-2.0), job);
  Run(&off, 0, store);
  EXPECT_EQ(off.values, Rejected(-2.0));
  EXPECT_TRUE(off.refit.empty()) << off.refit;

  // A fit that fails on its training recording is not refitted.
  Fit broken = FailingFit(Rejected(-2.0), job);
  broken.results[0].status = EvaluationStatus::kFailed;
  Run(&broken, 24, store);
  EXPECT_EQ(broken.values, Rejected(-2.0));
  EXPECT_TRUE(broken.refit.empty()) << broken.refit;
}

TEST_F(Refit, NotWhereTheReferenceFailsNoLaterAndAsFarAsItWhereItFailsLater) {
  ResultStore store(calib::testing::ScratchDir("refit_reference") / "store.sqlite");
  const int64_t job = store.CreateJob("base", nlohmann::json::object());
  const std::vector<EvaluationRecord> history = {Candidate(0, Rejected(-1.0), 100.0),
                                                 Candidate(1, Stiff(), 200.0)};
  store.RecordEvaluations(job, history);
  // A previous model failing on the held-out push from frame `frame`.
  auto reference_failing_from = [](int frame) {
    Fit reference = FailingFit(Stiff(), 0);
    reference.results[1].failure_frame = frame;
    return reference;
  };

  // The fit fails from frame 12, the reference from 10: comparable, kept
  // as it is for the judge (which compares the 10 frames).
  const Fit earlier = reference_failing_from(10);
  Fit fit = FailingFit(Rejected(-2.0), job);
  Run(&fit, 24, store, &earlier, /*sensitivity=*/true);
  EXPECT_EQ(fit.values, Rejected(-2.0));
  EXPECT_TRUE(fit.refit.empty()) << fit.refit;
  EXPECT_EQ(fit.holdout_sensitivity_px, 0.0) << "a fit that fails held out has no held-out sum to move";

  // The reference simulates 20 frames: refitted, with the first candidate
  // that simulates at least as far.
  const Fit later = reference_failing_from(20);
  Fit refitted = FailingFit(Rejected(-2.0), job);
  Run(&refitted, 24, store, &later, /*sensitivity=*/true);
  EXPECT_EQ(refitted.values, Stiff()) << refitted.refit;
  EXPECT_NE(refitted.refit.find("number 2 is the first that simulates every held-out recording as far "
                                "as the previous model does"),
            std::string::npos)
      << refitted.refit;
  EXPECT_GT(refitted.holdout_sensitivity_px, 0.0) << "measured once the fit simulates";
}

}  // namespace
}  // namespace calib::loop_detail
