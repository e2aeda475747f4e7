#include "calib/jobs/runner.h"

#include "calib/jobs/checkpoint.h"
#include "calib/jobs/pruning.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <utility>

namespace calib {

bool RunControl::IsValid(std::string* error) const {
  if (batch_size < 1) {
    *error = fmt::format("RunControl::batch_size = {}. Violated: batch_size >= 1.", batch_size);
    return false;
  }
  if (wall_time_s && !(*wall_time_s > 0.0)) {
    *error = fmt::format("RunControl::wall_time_s = {}. Violated: wall_time_s > 0.", *wall_time_s);
    return false;
  }
  if (!(tick_s > 0.0)) {
    *error = fmt::format("RunControl::tick_s = {}. Violated: tick_s > 0.", tick_s);
    return false;
  }
  return true;
}

std::string RunSummary::BriefReport() const {
  std::string text = fmt::format("status: {}{}\n", ToString(status),
                                 stop_reason.empty() ? "" : " (" + stop_reason + ")");
  text += fmt::format("evaluations: {} ({} failed{}); this run: {} simulated, {} reused",
                      evaluations, failed, pruned > 0 ? fmt::format(", {} pruned", pruned) : "",
                      evaluated_now, reused);
  if (resumed_from_checkpoint) text += fmt::format(", resumed from checkpoint {}", *resumed_from_checkpoint);
  text += '\n';
  if (best) {
    text += fmt::format("best: score {} (mean IoU {:.4f}), evaluation {}\n", best->score,
                        best->mean_iou, best->id);
  } else {
    text += "best: none (no evaluation succeeded)\n";
  }
  text += fmt::format("time: {:.1f} s this run, {:.1f} s over the job\n", seconds, job_seconds);
  return text;
}

namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

bool SameBits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

EvaluationRecord ToRecord(const FinishedCandidate& done, const search::Candidate& candidate,
                          const ParameterValues& values) {
  const ObjectiveResult& r = done.result;
  EvaluationRecord rec;
  rec.id = done.id;
  rec.parameters = values;
  rec.x = candidate.x;
  rec.ok = r.ok();
  // A failed candidate has no score and no IoU summary: its IoU over the
  // frames before the failure (0.99 over 1 frame of 330) would rank it above
  // every candidate that simulated the whole video. The partial figures go
  // to the detail.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  rec.score = r.ok() ? r.score : nan;
  rec.mean_iou = r.ok() ? r.iou.mean : nan;
  rec.iou_min = r.ok() ? r.iou.min : nan;
  rec.iou_max = r.ok() ? r.iou.max : nan;
  rec.failure_frame = r.ok() ? -1 : r.failure_frame;
  rec.reason = r.reason;
  rec.eval_time_s = r.eval_seconds;
  rec.worker = done.worker;
  rec.attempt = done.attempts;
  rec.detail = {{"frames_scored", r.iou.frames_scored},
                {"frames_total", r.iou.frames_total},
                {"worst_recording", r.iou.worst_recording},
                {"worst_frame", r.iou.worst_frame}};
  if (!r.ok()) {
    rec.detail["partial_score"] = r.score;
    rec.detail["partial_mean_iou"] = r.iou.mean;
    rec.detail["failure_recording"] = r.failure_recording;
  }
  return rec;
}

// A finished candidate that pruning.h's rule prunes at `at`, its bound being
// `factor` x the score of evaluation `best`. What it did after that frame
// (ran on, stopped at a looser bound, failed later) depends on the run and
// is left out: only the frames up to `at` and what follows from them.
EvaluationRecord ToPrunedRecord(const FinishedCandidate& done, const search::Candidate& candidate,
                                const ParameterValues& values, const PrunePoint& at,
                                double factor, const EvaluationRecord& best) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EvaluationRecord rec;
  rec.id = done.id;
  rec.parameters = values;
  rec.x = candidate.x;
  rec.pruned = true;
  rec.score = at.score;
  rec.mean_iou = nan;
  rec.iou_min = nan;
  rec.iou_max = nan;
  rec.pruned_recording = at.recording;
  rec.pruned_frame = at.frame;
  rec.reason = fmt::format(
      "pruned at recording {} frame {}: score so far {} > {} x {} (the best before it, "
      "evaluation {})",
      at.recording, at.frame, at.score, factor, best.score, best.id);
  rec.eval_time_s = done.result.eval_seconds;
  rec.worker = done.worker;
  // Retries of a simulation that failed after the pruning frame are not part
  // of the history (a run stopped before the failure made none).
  rec.attempt = 1;
  rec.detail = {{"frames_scored", at.frames}, {"frames_total", done.result.iou.frames_total}};
  return rec;
}

// What the optimiser is told for a recorded evaluation (fresh or reused
// alike, so a resumed run tells exactly what an uninterrupted one did). A
// pruned one: its score so far at the pruning frame, a lower bound of its
// score and already worse than the best before it by the prune factor.
search::Evaluation ToTold(const EvaluationRecord& rec, const FailurePolicy& policy) {
  search::Evaluation e;
  e.id = rec.id;
  e.x = rec.x;
  if (rec.ok || rec.pruned) {
    e.value = rec.score;
  } else if (policy.penalty_score) {
    e.value = *policy.penalty_score;
  } else {
    e.value = std::numeric_limits<double>::quiet_NaN();
    e.failed = true;
  }
  return e;
}

// Failed, as the failure policy counts: a pruned evaluation is not.
bool Failed(const EvaluationRecord& rec) { return !rec.ok && !rec.pruned; }

// Lowest score among ok evaluations, ties to the lowest id (as the store
// and the optimiser rank).
void UpdateBest(std::optional<EvaluationRecord>& best, const EvaluationRecord& rec) {
  if (!rec.ok) return;
  if (!best || rec.score < best->score || (rec.score == best->score && rec.id < best->id)) {
    best = rec;
  }
}

class Run {
 public:
  Run(const CalibrationRequest& request, ResultStore& store, int64_t job, BatchEvaluator& evaluator,
      const RunControl& control, RunObserver* observer)
      : spec_(request),
        store_(store),
        job_(job),
        evaluator_(evaluator),
        control_(control),
        observer_(observer ? observer : &silent_),
        space_(request),
        optimizer_(MakeRequestOptimizer(request)),
        start_(Clock::now()),
        last_checkpoint_time_(start_) {
    if (request.budget.prune_factor) {
      prune_ = std::make_unique<PruneBounds>(*request.budget.prune_factor);
    }
  }

  RunSummary Go() {
    Restore();
    store_.SetJobStatus(job_, JobStatus::kRunning);
    observer_->OnStart(Progress(), fmt::format("{} ({}), {} evaluations budget, {}",
                                               spec_.name, optimizer_.name(),
                                               spec_.budget.evaluations, evaluator_.Describe()));
    AskTellCycle();
    Finish();
    return summary_;
  }

 private:
  void Restore() {
    LatestCheckpointResult latest = store_.LatestCheckpoint(job_);
    for (const std::string& w : latest.warnings) Warn(w);
    if (latest.checkpoint) {
      const CheckpointRecord& record = *latest.checkpoint;
      RunnerCheckpoint cp;
      try {
        cp = RunnerCheckpoint::FromJson(record.state);
        if (cp.seed != spec_.seed) {
          throw std::invalid_argument(
              fmt::format("it was taken with seed {}, the spec says {}", cp.seed, spec_.seed));
        }
        optimizer_.RestoreState(cp.optimizer);
      } catch (const std::exception& e) {
        throw std::runtime_error(fmt::format(
            "{}: job '{}': checkpoint {} does not fit the job spec: {}", store_.path().string(),
            spec_.name, record.sequence, e.what()));
      }
      if (optimizer_.told_count() != cp.told) {
        throw std::runtime_error(fmt::format(
            "{}: job '{}': checkpoint {} says {} evaluations were told, its optimiser {}",
            store_.path().string(), spec_.name, record.sequence, cp.told,
            optimizer_.told_count()));
      }
      told_ = cp.told;
      failed_ = cp.failed;
      previous_seconds_ = cp.run_seconds;
      summary_.resumed_from_checkpoint = record.sequence;
      told_at_checkpoint_ = told_;
    }
    // The best so far and the check that nothing before the checkpoint is
    // missing; then everything recorded after it, to reuse.
    std::vector<EvaluationRecord> all = store_.Evaluations(job_);
    int64_t before = 0;
    for (EvaluationRecord& rec : all) {
      if (rec.id < told_) {
        ++before;
        if (rec.pruned) ++pruned_;
        UpdateBest(best_, rec);
      } else {
        const int64_t id = rec.id;
        reusable_.emplace(id, std::move(rec));
      }
    }
    if (before != told_) {
      throw std::runtime_error(fmt::format(
          "{}: job '{}': the checkpoint covers evaluations 0..{} but the store holds {} of them",
          store_.path().string(), spec_.name, told_ - 1, before));
    }
    if (prune_ && best_) prune_->AddCompleted(best_->id, best_->score);
  }

  bool ShouldStop() {
    if (stop_reason_.empty()) {
      if (control_.interrupted && control_.interrupted()) {
        stop_reason_ = "interrupted";
      } else if (control_.wall_time_s && Since(start_) >= *control_.wall_time_s) {
        stop_reason_ = fmt::format("wall time of {} s used", *control_.wall_time_s);
      }
    }
    return !stop_reason_.empty();
  }

  // The ask/tell cycle (top of runner.h), batch by batch, until the optimiser,
  // the budget, the wall time, an interrupt or the failure policy stops it.
  void AskTellCycle() {
    const int64_t abort_after = spec_.failure_policy.abort_after;
    if (abort_after > 0 && failed_ >= abort_after) {  // resumed after an abort
      status_ = JobStatus::kAborted;
      stop_reason_ = fmt::format("{} failed evaluations (failure policy: abort after {})",
                                 failed_, abort_after);
      return;
    }
    while (true) {
      if (optimizer_.Done()) {
        status_ = JobStatus::kFinished;
        stop_reason_ = "optimizer: " + optimizer_.StopReason();
        return;
      }
      if (ShouldStop()) {
        status_ = JobStatus::kStopped;
        return;
      }
      std::vector<search::Candidate> batch = optimizer_.Outstanding();
      if (batch.empty()) {
        const int64_t remaining = spec_.budget.evaluations - optimizer_.asked_count();
        if (remaining <= 0) {
          status_ = JobStatus::kFinished;
          stop_reason_ = fmt::format("budget of {} evaluations used", spec_.budget.evaluations);
          return;
        }
        batch = optimizer_.Ask(static_cast<int>(
            std::min<int64_t>(control_.batch_size, remaining)));
        if (batch.empty()) {
          throw std::logic_error(fmt::format(
              "optimizer {} proposed nothing, has nothing outstanding and is not done",
              optimizer_.name()));
        }
      }
      if (!RunBatch(batch)) return;  // aborted
      MaybeCheckpoint(false);
    }
  }

  // With pruning: records, in id order, the finished candidates of `batch`
  // whose predecessors are all recorded (or reused), each decided by
  // pruning.h's rule with its exact bound; they leave `finished`. Those
  // after a candidate still running wait for it.
  std::vector<EvaluationRecord> ResolvePruning(const std::vector<search::Candidate>& batch,
                                               const std::vector<ParameterValues>& values,
                                               const std::map<int64_t, EvaluationRecord>& results,
                                               std::map<int64_t, FinishedCandidate>& finished) {
    std::vector<EvaluationRecord> records;
    for (; resolved_ < batch.size(); ++resolved_) {
      const search::Candidate& c = batch[resolved_];
      if (auto reused = results.find(c.id); reused != results.end()) {
        UpdateBest(resolved_best_, reused->second);
        continue;
      }
      auto it = finished.find(c.id);
      if (it == finished.end()) break;
      const FinishedCandidate& done = it->second;
      if (done.result.ok() && done.result.trace.empty()) {
        throw std::logic_error(fmt::format(
            "evaluation {}: the objective returned no trace of its score, which pruning needs",
            c.id));
      }
      std::optional<PrunePoint> at;  // none while no evaluation before it is ok
      if (resolved_best_) {
        at = FindPrunePoint(done.result, prune_->factor() * resolved_best_->score);
      }
      if (at) {
        records.push_back(ToPrunedRecord(done, c, values[resolved_], *at, prune_->factor(),
                                         *resolved_best_));
      } else if (done.result.status == CandidateStatus::kPruned) {
        throw std::logic_error(fmt::format(
            "evaluation {} stopped early but never exceeded its bound (a worker started it with "
            "a bound below F x the best before it)",
            c.id));
      } else {
        records.push_back(ToRecord(done, c, values[resolved_]));
      }
      UpdateBest(resolved_best_, records.back());
      finished.erase(it);
    }
    return records;
  }

  // Evaluates the batch (reusing what the store holds), tells the longest
  // id prefix that has results. False when the failure policy aborted.
  bool RunBatch(const std::vector<search::Candidate>& batch) {
    std::map<int64_t, EvaluationRecord> results;
    std::map<int64_t, FinishedCandidate> finished;  // pruning: not yet recorded
    std::map<int64_t, size_t> index_of;
    std::vector<PendingCandidate> pending;
    std::vector<ParameterValues> values(batch.size());
    for (size_t i = 0; i < batch.size(); ++i) {
      const search::Candidate& c = batch[i];
      index_of[c.id] = i;
      values[i] = space_.ToParameters(c.x);
      auto it = reusable_.find(c.id);
      if (it != reusable_.end()) {
        if (!SameBits(it->second.x, c.x)) {
          throw std::runtime_error(fmt::format(
              "{}: job '{}': evaluation {} in the store has another x than the optimiser asks "
              "now; the spec or the program changed since it was recorded",
              store_.path().string(), spec_.name, c.id));
        }
        if (prune_ && it->second.ok) prune_->AddCompleted(c.id, it->second.score);
        results.emplace(c.id, std::move(it->second));
        reusable_.erase(it);
        ++summary_.reused;
      } else {
        pending.push_back({c.id, values[i]});
      }
    }

    const int max_attempts =
        spec_.failure_policy.mode == FailureMode::kRetry ? 1 + spec_.failure_policy.max_retries : 1;
    running_ = 0;
    running_failed_ = 0;
    running_pruned_ = 0;
    resolved_ = 0;
    resolved_best_ = best_;
    evaluator_.Evaluate(
        pending, max_attempts, prune_.get(), [this] { return ShouldStop(); },
        [&](std::vector<FinishedCandidate>&& done) {
          std::vector<EvaluationRecord> records;
          if (prune_) {
            // Recorded once decided: in id order, as their bounds become exact.
            for (FinishedCandidate& f : done) {
              prune_->AddFinished(f.id, f.result);
              const int64_t id = f.id;
              finished.emplace(id, std::move(f));
            }
            summary_.evaluated_now += static_cast<int64_t>(done.size());
            records = ResolvePruning(batch, values, results, finished);
          } else {
            // Recorded as they finish.
            records.reserve(done.size());
            for (const FinishedCandidate& f : done) {
              const size_t i = index_of.at(f.id);
              records.push_back(ToRecord(f, batch[i], values[i]));
            }
            summary_.evaluated_now += static_cast<int64_t>(records.size());
          }
          if (!records.empty()) {
            store_.RecordEvaluations(job_, records);
            running_ += static_cast<int64_t>(records.size());
            for (EvaluationRecord& rec : records) {
              if (Failed(rec)) ++running_failed_;
              if (rec.pruned) ++running_pruned_;
              UpdateBest(provisional_best_, rec);
              const int64_t id = rec.id;
              results.emplace(id, std::move(rec));
            }
          }
          observer_->OnProgress(Progress());
        },
        control_.tick_s);
    running_ = 0;
    running_failed_ = 0;
    running_pruned_ = 0;
    // Pruning: what finished after a candidate that never ran (stopped) is
    // dropped unrecorded, to be simulated again on resume.

    // Tell in id order, up to the first candidate without a result.
    std::vector<search::Evaluation> told;
    bool aborted = false;
    int64_t cut_after = -1;
    for (const search::Candidate& c : batch) {  // ascending ids
      auto it = results.find(c.id);
      if (it == results.end()) break;
      const EvaluationRecord& rec = it->second;
      told.push_back(ToTold(rec, spec_.failure_policy));
      UpdateBest(best_, rec);
      if (Failed(rec)) ++failed_;
      if (rec.pruned) ++pruned_;
      if (spec_.failure_policy.abort_after > 0 && failed_ >= spec_.failure_policy.abort_after) {
        aborted = true;
        cut_after = c.id;
        break;
      }
    }
    optimizer_.Tell(told);
    told_ += static_cast<int64_t>(told.size());
    provisional_best_ = best_;
    if (aborted) {
      // The history ends at the N-th failure, whatever else this batch held.
      summary_.deleted += store_.DeleteEvaluationsFrom(job_, cut_after + 1);
      status_ = JobStatus::kAborted;
      stop_reason_ = fmt::format("{} failed evaluation{} (failure policy: abort after {})",
                                 failed_, failed_ == 1 ? "" : "s",
                                 spec_.failure_policy.abort_after);
      return false;
    }
    observer_->OnProgress(Progress());
    return true;
  }

  void MaybeCheckpoint(bool force) {
    const CheckpointSpec& every = spec_.checkpoint;
    const bool by_count =
        every.every_evaluations > 0 && told_ - told_at_checkpoint_ >= every.every_evaluations;
    const bool by_time =
        every.every_seconds > 0.0 && Since(last_checkpoint_time_) >= every.every_seconds;
    if (!force && !by_count && !by_time) return;
    if (told_ == told_at_checkpoint_ && summary_.checkpoints_written > 0) return;
    RunnerCheckpoint cp;
    cp.optimizer = optimizer_.SaveState();
    cp.told = told_;
    cp.failed = failed_;
    cp.run_seconds = previous_seconds_ + Since(start_);
    cp.seed = spec_.seed;
    CheckpointRecord record;
    record.evaluations_done = told_;
    record.state = cp.ToJson();
    const int64_t sequence = store_.SaveCheckpoint(job_, record);
    ++summary_.checkpoints_written;
    told_at_checkpoint_ = told_;
    last_checkpoint_time_ = Clock::now();
    observer_->OnCheckpoint(Progress(), sequence);
  }

  void Finish() {
    if (status_ == JobStatus::kFinished) {
      // Evaluations past the history (only when the budget was lowered on
      // resume) would otherwise be reused by nothing and confuse reports.
      const int64_t extra = store_.DeleteEvaluationsFrom(job_, optimizer_.asked_count());
      if (extra > 0) {
        Warn(fmt::format("deleted {} stored evaluations past the end of the history (id >= {})",
                         extra, optimizer_.asked_count()));
        summary_.deleted += extra;
      }
    }
    MaybeCheckpoint(true);
    store_.SetJobStatus(job_, status_, stop_reason_);
    summary_.status = status_;
    summary_.stop_reason = stop_reason_;
    summary_.evaluations = told_;
    summary_.failed = failed_;
    summary_.pruned = pruned_;
    summary_.best = best_;
    summary_.seconds = Since(start_);
    summary_.job_seconds = previous_seconds_ + summary_.seconds;
    observer_->OnFinish(Progress());
  }

  void Warn(const std::string& message) {
    summary_.warnings.push_back(message);
    observer_->OnWarning(message);
  }

  RunProgress Progress() const {
    RunProgress p;
    p.evaluations = told_;
    p.budget = spec_.budget.evaluations;
    p.failed = failed_ + running_failed_;
    p.pruned = pruned_ + running_pruned_;
    p.evaluated_now = summary_.evaluated_now;
    p.running = running_;
    const std::optional<EvaluationRecord>& best = provisional_best_ ? provisional_best_ : best_;
    if (best) {
      p.best_score = best->score;
      p.best_id = best->id;
    }
    p.elapsed_s = Since(start_);
    return p;
  }

  const CalibrationRequest& spec_;
  ResultStore& store_;
  const int64_t job_;
  BatchEvaluator& evaluator_;
  const RunControl& control_;
  RunObserver silent_;
  RunObserver* observer_;
  SearchSpace space_;
  search::CheckedOptimizer optimizer_;
  const Clock::time_point start_;
  Clock::time_point last_checkpoint_time_;
  std::unique_ptr<PruneBounds> prune_;  // null: no pruning

  int64_t told_ = 0;
  int64_t failed_ = 0;
  int64_t pruned_ = 0;
  int64_t told_at_checkpoint_ = 0;
  int64_t running_ = 0;
  int64_t running_failed_ = 0;  // failed among those running_
  int64_t running_pruned_ = 0;  // pruned among those running_
  // Pruning, in the current batch: candidates [0, resolved_) are recorded
  // (or reused); resolved_best_ is the best among the history before it.
  size_t resolved_ = 0;
  std::optional<EvaluationRecord> resolved_best_;
  double previous_seconds_ = 0.0;
  std::optional<EvaluationRecord> best_;
  std::optional<EvaluationRecord> provisional_best_;  // includes the batch in flight
  std::map<int64_t, EvaluationRecord> reusable_;
  JobStatus status_ = JobStatus::kRunning;
  std::string stop_reason_;
  RunSummary summary_;
};

}  // namespace

RunSummary RunCalibration(const CalibrationRequest& request, ResultStore& store, int64_t job,
                          BatchEvaluator& evaluator, const RunControl& control,
                          RunObserver* observer) {
  std::string error;
  if (!control.IsValid(&error)) throw std::invalid_argument(error);
  return Run(request, store, job, evaluator, control, observer).Go();
}

}  // namespace calib
