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
    if (!result.ok() && out.status == CandidateStatus::kOk) {
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
      frames_total_ += prepared->scene.num_frames;
    }
    results_.reserve(recordings.size());
  }

  ObjectiveResult Evaluate(const ParameterValues& values) override {
    results_.clear();
    for (Evaluator& evaluator : evaluators_) {
      results_.push_back(evaluator.Evaluate(values));
      if (!results_.back().ok()) break;  // the candidate has failed: spare the rest
    }
    ObjectiveResult result = CombineRecordingResults(results_, names_);
    result.iou.frames_total = frames_total_;  // also the recordings spared
    return result;
  }

 private:
  std::vector<Evaluator> evaluators_;
  std::vector<std::string> names_;
  std::vector<EvaluationResult> results_;
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
