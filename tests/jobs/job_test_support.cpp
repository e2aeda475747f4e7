#include "jobs/job_test_support.h"

#include "calib/jobs/batch_evaluator.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <thread>

namespace calib::testing {
namespace {

class SyntheticWorker final : public ObjectiveWorker {
 public:
  explicit SyntheticWorker(SyntheticOptions options) : options_(options) {}

  using ObjectiveWorker::Evaluate;
  ObjectiveResult Evaluate(const ParameterValues& values, const EarlyStop& stop) override {
    if (options_.sleep_s > 0.0) {
      std::this_thread::sleep_for(std::chrono::duration<double>(options_.sleep_s));
    }
    if (options_.flaky) {
      if (values != last_thrown_) {
        last_thrown_ = values;
        throw std::runtime_error("transient: connection to the recording store lost");
      }
      last_thrown_.clear();
    }
    const double f = SyntheticObjective::Score(values);
    ObjectiveResult r;
    r.iou.frames_total = 10;
    r.iou.worst_recording = 0;
    r.iou.worst_frame = static_cast<int>(std::fmod(f * 7.0, 10.0));
    r.iou.mean = 1.0 / (1.0 + f);
    r.iou.min = 1.0 / (1.0 + 1.5 * f);
    r.iou.max = 1.0 / (1.0 + 0.5 * f);
    const double tau = values.at("tau");
    const bool fails = tau > options_.fail_above_tau;
    // Every frame scores f: the score so far after frame k is (k + 1) f.
    const int frames = fails ? 3 : 10;
    if (stop.trace) r.recording_frames = {10};
    for (int k = 0; k < frames; ++k) {
      const double so_far = (k + 1) * f;
      if (stop.trace) r.trace.push_back(so_far);
      if (so_far > stop.stop_above) {
        r.status = CandidateStatus::kPruned;
        r.score = so_far;
        r.iou.frames_scored = k + 1;
        return r;
      }
    }
    if (fails) {
      r.status = CandidateStatus::kFailed;
      r.score = 3.0 * f;  // the frames before the failure
      r.iou.frames_scored = 3;
      r.failure_frame = 3;
      r.failure_recording = 0;
      r.reason = fmt::format("recording synthetic: frame 3: tau = {} above {}: blew up", tau,
                             options_.fail_above_tau);
      return r;
    }
    r.status = CandidateStatus::kOk;
    r.score = 10.0 * f;
    r.iou.frames_scored = 10;
    return r;
  }

 private:
  SyntheticOptions options_;
  ParameterValues last_thrown_;
};

}  // namespace

const char* const kBaseParametersYaml = R"yaml(parameters:
  - {name: k_D,   lower: 10,   upper: 5000, scale: log}
  - {name: k_d,   lower: 0.01, upper: 50,   scale: log}
  - {name: k_A,   lower: 1,    upper: 5000, scale: log}
  - {name: k_phi, lower: 0.1,  upper: 1000, scale: log}
  - {name: mass,  fixed: 0.2}
  - {name: tau,   lower: 0,    upper: 0.5}
)yaml";

std::unique_ptr<ObjectiveWorker> SyntheticObjective::MakeWorker() const {
  return std::make_unique<SyntheticWorker>(options_);
}

double SyntheticObjective::Score(const ParameterValues& values) {
  const std::pair<const char*, double> targets[] = {
      {"k_D", 300.0}, {"k_d", 2.0}, {"k_A", 100.0}, {"k_phi", 5.0}};
  double f = 0.0;
  for (const auto& [name, target] : targets) {
    const double d = std::log10(values.at(name)) - std::log10(target);
    f += d * d + 0.2 * (1.0 - std::cos(2.0 * std::numbers::pi * d));
  }
  const double d = (values.at("tau") - 0.1) * 4.0;
  return 1000.0 * (f + d * d);
}

JobSpec SyntheticJobSpec(const std::string& optimizer, const std::string& extra,
                         const std::string& name) {
  std::string text = fmt::format(R"yaml(
name: {}
train: [placeholder_recording]
{}optimizer: {}
seed: 7
)yaml",
                                 name, kBaseParametersYaml, optimizer);
  if (extra.find("budget:") == std::string::npos) text += "budget: {evaluations: 96}\n";
  text += extra;
  text += '\n';
  JobSpecParseOptions options;
  options.recordings = RecordingCheck::kNone;
  return ParseJobSpec(text, "synthetic.yaml", std::filesystem::temp_directory_path(), options);
}

std::string SmallPushJobYaml(const std::string& name, const std::string& push_centre, int seed,
                             int budget, const std::string& results) {
  return fmt::format(R"yaml(
name: {}
train: [{}]
model:
  substeps: 4
  mesh: {{edge_length_px: 40}}
{}optimizer: {{name: cmaes, settings: {{population: 4, initial_sigma: 0.3}}}}
budget: {{evaluations: {}}}
seed: {}
threads: 2
checkpoint: {{every_evaluations: 4, every_seconds: 0}}
{}
)yaml",
                     name, push_centre, kBaseParametersYaml, budget, seed, results);
}

void ExpectSameHistory(const std::vector<EvaluationRecord>& expected,
                       const std::vector<EvaluationRecord>& actual, const std::string& what) {
  ASSERT_EQ(expected.size(), actual.size()) << what << ": evaluations";
  const auto same_bits = [](double a, double b) {
    return std::memcmp(&a, &b, sizeof a) == 0 || (std::isnan(a) && std::isnan(b));
  };
  for (size_t i = 0; i < expected.size(); ++i) {
    const EvaluationRecord& e = expected[i];
    const EvaluationRecord& a = actual[i];
    const std::string where = fmt::format("{}: evaluation {}", what, e.id);
    ASSERT_EQ(e.id, a.id) << where;
    EXPECT_EQ(e.x.size(), a.x.size()) << where;
    for (size_t k = 0; k < e.x.size() && k < a.x.size(); ++k) {
      EXPECT_TRUE(same_bits(e.x[k], a.x[k])) << where << ": x[" << k << "] " << e.x[k]
                                             << " != " << a.x[k];
    }
    EXPECT_EQ(e.parameters, a.parameters) << where;
    EXPECT_EQ(e.ok, a.ok) << where;
    EXPECT_EQ(e.pruned, a.pruned) << where;
    EXPECT_TRUE(same_bits(e.score, a.score)) << where << ": score " << e.score << " != " << a.score;
    EXPECT_TRUE(same_bits(e.mean_iou, a.mean_iou)) << where;
    EXPECT_TRUE(same_bits(e.iou_min, a.iou_min)) << where;
    EXPECT_TRUE(same_bits(e.iou_max, a.iou_max)) << where;
    EXPECT_EQ(e.failure_frame, a.failure_frame) << where;
    EXPECT_EQ(e.pruned_recording, a.pruned_recording) << where;
    EXPECT_EQ(e.pruned_frame, a.pruned_frame) << where;
    EXPECT_EQ(e.reason, a.reason) << where;
    EXPECT_EQ(e.attempt, a.attempt) << where;
    EXPECT_EQ(e.detail, a.detail) << where;
    if (::testing::Test::HasFailure()) return;  // one evaluation's worth of messages
  }
}

JobRun RunJobIn(const JobSpec& spec, const std::filesystem::path& db, const Objective& objective,
                int threads, RunControl control, RunObserver* observer) {
  ResultStore store(db);
  const std::optional<JobInfo> existing = store.FindJob(spec.name);
  const int64_t job = existing ? existing->id : store.CreateJob(spec.name, ToJson(spec));
  ThreadBatchEvaluator evaluator(objective, threads);
  JobRun run;
  run.summary = RunCalibration(spec, store, job, evaluator, control, observer);
  run.history = store.Evaluations(job);
  run.best = store.Best(job);
  run.info = store.Job(job);
  return run;
}

void ExpectSameBest(const JobRun& expected, const JobRun& actual, const std::string& what) {
  ASSERT_EQ(expected.best.has_value(), actual.best.has_value()) << what;
  if (!expected.best) return;
  EXPECT_EQ(expected.best->id, actual.best->id) << what;
  EXPECT_EQ(expected.best->parameters, actual.best->parameters) << what;
  EXPECT_EQ(expected.best->score, actual.best->score) << what;
  ASSERT_TRUE(actual.summary.best.has_value()) << what;
  EXPECT_EQ(actual.summary.best->id, actual.best->id) << what << ": the summary's best is the store's";
}

void ExpectSameRunAtThreadCountsAndBatchSizes(const JobSpec& spec, const Objective& objective,
                                              const std::filesystem::path& dir,
                                              const JobRun& reference) {
  for (const int threads : {1, 2, 4}) {
    for (const int batch_size : {3, 64}) {
      const std::string what = fmt::format("{} threads, batch {}", threads, batch_size);
      RunControl control;
      control.batch_size = batch_size;
      const JobRun run = RunJobIn(spec, dir / fmt::format("t{}_b{}.sqlite", threads, batch_size),
                                  objective, threads, control);
      EXPECT_EQ(run.summary.status, reference.summary.status) << what;
      EXPECT_EQ(run.summary.stop_reason, reference.summary.stop_reason) << what;
      ExpectSameHistory(reference.history, run.history, what);
      ExpectSameBest(reference, run, what);
    }
  }
}

RunControl StopAfterPolls(int polls, int batch_size) {
  RunControl control;
  control.batch_size = batch_size;
  auto count = std::make_shared<int>(0);
  control.interrupted = [count, polls] { return ++*count > polls; };
  return control;
}

JobCommandOptions SyntheticJobCommandOptions() {
  JobCommandOptions options;
  options.threads = 1;
  options.write_report = false;
  options.progress = ProgressMode::kNone;
  options.make_objective = [](const JobSpec&, const PreparationOptions&) {
    return std::make_unique<SyntheticObjective>();
  };
  return options;
}

}  // namespace calib::testing
