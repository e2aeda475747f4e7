#include "calib/jobs/objective.h"

#include "calib/core/enum_names.h"
#include "calib/evaluator/recording.h"

#include <fmt/format.h>

#include <stdexcept>
#include <utility>

namespace calib {

namespace {

constexpr auto kCandidateStatusNames = std::to_array<EnumName<CandidateStatus>>({
    {CandidateStatus::kOk, "ok"},
    {CandidateStatus::kFailed, "failed"},
    {CandidateStatus::kPruned, "pruned"},
});

}  // namespace

std::string ToString(CandidateStatus status) { return EnumToString(kCandidateStatusNames, status); }

CandidateStatus CandidateStatusFromString(std::string_view text) {
  return EnumFromString(kCandidateStatusNames, "candidate status", text);
}

ObjectiveResult CombineRecordingResults(const std::vector<EvaluationResult>& results,
                                        const std::vector<std::string>& names) {
  ObjectiveResult out;
  out.status = CandidateStatus::kOk;
  double xor_sum = 0.0;
  double iou_sum = 0.0;
  bool any_frame = false;
  // Frames in recording order, then frame order: the same sums for any
  // thread, so the result is bit-identical wherever it is computed.
  for (size_t r = 0; r < results.size(); ++r) {
    const EvaluationResult& result = results[r];
    out.iou.frames_total += result.num_frames;
    xor_sum += result.xor_sum;
    for (size_t f = 0; f < result.frames.size(); ++f) {
      const double iou = result.frames[f].iou;
      iou_sum += iou;
      if (!any_frame || iou > out.iou.max) out.iou.max = iou;
      if (!any_frame || iou < out.iou.min) {
        out.iou.min = iou;
        out.iou.worst_recording = static_cast<int>(r);
        out.iou.worst_frame = static_cast<int>(f);
        any_frame = true;
      }
    }
    out.iou.frames_scored += static_cast<int>(result.frames.size());
    if (result.status == EvaluationStatus::kStopped && out.status == CandidateStatus::kOk) {
      out.status = CandidateStatus::kPruned;
    } else if (!result.ok() && out.status == CandidateStatus::kOk) {
      out.status = CandidateStatus::kFailed;
      out.failure_frame = result.failure_frame;
      out.failure_recording = static_cast<int>(r);
      out.reason = fmt::format("recording {}: frame {}: {}", r < names.size() ? names[r] : "?",
                               result.failure_frame, result.failure_reason);
    }
  }
  out.score = xor_sum;
  if (out.iou.frames_scored > 0) out.iou.mean = iou_sum / out.iou.frames_scored;
  return out;
}

namespace {

class RecordingWorker final : public ObjectiveWorker {
 public:
  RecordingWorker(const std::vector<std::shared_ptr<const PreparedRecording>>& recordings,
                  const SimulationOptions& options, const ModelDefinition& model) {
    evaluators_.reserve(recordings.size());
    for (const auto& prepared : recordings) {
      evaluators_.emplace_back(*prepared, options, model);
      names_.push_back(RecordingDisplayName(prepared->recording.folder));
      recording_frames_.push_back(prepared->scene.num_frames);
      frames_total_ += prepared->scene.num_frames;
    }
    results_.reserve(recordings.size());
    trace_.reserve(frames_total_);
  }

  using ObjectiveWorker::Evaluate;
  ObjectiveResult Evaluate(const ParameterValues& values, const EarlyStop& stop) override {
    results_.clear();
    trace_.clear();
    // The recordings' scores summed in order, as CombineRecordingResults
    // sums them: the score so far after frame f of recording r is
    // score_before + (its frames 0..f summed in order), which after the last
    // recording's last frame is the candidate's score bit for bit.
    ScoreCutoff cutoff{0.0, stop.stop_above};
    for (Evaluator& evaluator : evaluators_) {
      const EvaluationResult& result =
          results_.emplace_back(evaluator.EvaluateWithCutoff(values, cutoff));
      if (stop.trace) {
        double xor_sum = 0.0;  // as Evaluator sums it
        for (const FrameScore& frame : result.frames) {
          xor_sum += frame.xor_px;
          trace_.push_back(cutoff.score_before + xor_sum);
        }
      }
      cutoff.score_before += result.xor_sum;
      if (!result.ok()) break;  // failed or stopped: spare the rest
    }
    ObjectiveResult result = CombineRecordingResults(results_, names_);
    result.iou.frames_total = frames_total_;  // also the recordings spared
    if (stop.trace) {
      result.trace = trace_;
      result.recording_frames = recording_frames_;
    }
    return result;
  }

 private:
  std::vector<Evaluator> evaluators_;
  std::vector<std::string> names_;
  std::vector<EvaluationResult> results_;
  std::vector<int> recording_frames_;
  std::vector<double> trace_;  // reserved for every frame: no allocation per frame
  int frames_total_ = 0;
};

}  // namespace

RecordingObjective::RecordingObjective(
    std::vector<std::shared_ptr<const PreparedRecording>> recordings, SimulationOptions options,
    ModelDefinition model)
    : recordings_(std::move(recordings)), options_(options), model_(std::move(model)) {
  if (recordings_.empty()) {
    throw std::invalid_argument("the objective needs at least one training recording");
  }
  std::string error;
  if (!options_.IsValid(&error)) throw std::invalid_argument(error);
  if (!model_.IsValid(&error)) throw std::invalid_argument(error);
}

std::unique_ptr<ObjectiveWorker> RecordingObjective::MakeWorker() const {
  return std::make_unique<RecordingWorker>(recordings_, options_, model_);
}

std::string RecordingObjective::Describe() const {
  int frames = 0;
  for (const auto& r : recordings_) frames += r->scene.num_frames;
  const std::string model =
      model_.effects.empty() ? std::string() : fmt::format("model {}, ", model_.ToString());
  return fmt::format("{}{} training recording{}, {} frames", model, recordings_.size(),
                     recordings_.size() == 1 ? "" : "s", frames);
}

}  // namespace calib
