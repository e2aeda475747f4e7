// The keep criterion of the closed loop (keep_criterion.h) and the
// KeepCriterion that judges an effect (loop_stages.h).

#include "calib/discovery/keep_criterion.h"

#include "loop_stages.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace calib {

double SegmentationNoisePx(const std::vector<BitMask>& masks) {
  if (masks.size() < 3) return 0.0;
  std::vector<double> flicker;
  for (size_t f = 1; f + 1 < masks.size(); ++f) {
    const auto& a = masks[f - 1].words();
    const auto& b = masks[f].words();
    const auto& c = masks[f + 1].words();
    if (a.size() != b.size() || b.size() != c.size()) {
      throw std::invalid_argument(
          fmt::format("segmentation noise: masks {} .. {} differ in shape", f - 1, f + 1));
    }
    int64_t n = 0;
    for (size_t w = 0; w < b.size(); ++w) n += std::popcount((a[w] ^ b[w]) & ~(a[w] ^ c[w]));
    flicker.push_back(static_cast<double>(n));
  }
  double sum = 0.0;
  for (double v : flicker) sum += v;
  return sum / static_cast<double>(flicker.size());
}

namespace {

// The successful evaluations with a finite score, lowest score first; ties
// keep the order of `evaluations`.
std::vector<const EvaluationRecord*> SucceededBestFirst(const std::vector<EvaluationRecord>& evaluations) {
  std::vector<const EvaluationRecord*> ok;
  for (const EvaluationRecord& e : evaluations) {
    if (e.ok && std::isfinite(e.score)) ok.push_back(&e);
  }
  std::stable_sort(ok.begin(), ok.end(),
                   [](const EvaluationRecord* a, const EvaluationRecord* b) { return a->score < b->score; });
  return ok;
}

}  // namespace

std::vector<ParameterValues> RankedByTrainingScore(const std::vector<EvaluationRecord>& evaluations,
                                                   const ParameterValues& excluded, int limit) {
  std::vector<ParameterValues> out;
  for (const EvaluationRecord* e : SucceededBestFirst(evaluations)) {
    if (static_cast<int>(out.size()) >= limit) break;
    if (e->parameters == excluded || std::find(out.begin(), out.end(), e->parameters) != out.end()) continue;
    out.push_back(e->parameters);
  }
  return out;
}

std::vector<ParameterValues> SelectEquallyGoodFits(const std::vector<EvaluationRecord>& evaluations,
                                                   double tolerance, int limit) {
  const std::vector<const EvaluationRecord*> ok = SucceededBestFirst(evaluations);
  if (ok.empty() || limit <= 0) return {};
  const double cutoff = ok.front()->score + std::max(tolerance, 0.0);
  std::vector<const ParameterValues*> distinct;
  for (const EvaluationRecord* e : ok) {
    if (e->score > cutoff) break;
    const bool seen = std::any_of(distinct.begin(), distinct.end(),
                                  [&](const ParameterValues* p) { return *p == e->parameters; });
    if (!seen) distinct.push_back(&e->parameters);
  }
  std::vector<ParameterValues> out;
  const size_t n = distinct.size();
  const size_t take = std::min(n, static_cast<size_t>(limit));
  for (size_t i = 0; i < take; ++i) {
    // Ranks 0, ..., n - 1 spread evenly: i (n - 1) / (take - 1), rounded down.
    const size_t rank = take == 1 ? 0 : i * (n - 1) / (take - 1);
    out.push_back(*distinct[rank]);
  }
  return out;
}

namespace loop_detail {

double Fit::XorSum(const std::vector<LoopRecording>& recs, bool train) const {
  double s = 0.0;
  for (size_t r = 0; r < recs.size(); ++r) {
    if (recs[r].train != train) continue;
    if (!results[r].ok()) return std::numeric_limits<double>::infinity();
    if (recs[r].first_compared_frame == 0) {
      s += static_cast<double>(results[r].xor_sum);
    } else {
      const std::vector<FrameScore>& frames = results[r].frames;
      for (size_t f = static_cast<size_t>(recs[r].first_compared_frame); f < frames.size(); ++f) {
        s += static_cast<double>(frames[f].xor_px);
      }
    }
  }
  return s;
}

std::vector<std::vector<double>> Fit::HeldOutFrameErrors(const std::vector<LoopRecording>& recs) const {
  std::vector<std::vector<double>> out;
  for (size_t r = 0; r < recs.size(); ++r) {
    if (recs[r].train) continue;
    std::vector<double>& errors = out.emplace_back();
    const std::vector<FrameScore>& frames = results[r].frames;
    for (size_t f = static_cast<size_t>(recs[r].first_compared_frame); f < frames.size(); ++f) {
      errors.push_back(static_cast<double>(frames[f].xor_px));
    }
  }
  return out;
}

bool ComparableOnHeldOut(bool ok, int failure_frame, const Fit* reference, size_t r) {
  if (ok) return true;
  if (reference == nullptr || r >= reference->results.size()) return false;
  const EvaluationResult& e = reference->results[r];
  return !e.ok() && failure_frame >= e.failure_frame;
}

bool Fit::AllOk() const {
  return std::all_of(results.begin(), results.end(), [](const EvaluationResult& e) { return e.ok(); });
}

double KeepCriterion::TrainingNoise() const {
  double b = 0.0;
  for (const LoopRecording& r : recs_) {
    if (r.train) b += r.noise_px * r.prepared->scene.num_frames;
  }
  return b;
}

KeepCriterion::Verdict KeepCriterion::Judge(const Fit& previous, const Fit* ablation,
                                            const Fit& candidate, uint64_t seed) const {
  // The reference: the previous fit, or the ablation where it is better on
  // the training recordings.
  const Fit& current = ablation != nullptr ? *ablation : previous;
  Verdict v;
  if (!candidate.AllOk()) {
    // Named with the recording and the frame. A held-out recording where
    // the reference fails too, no later, is compared below over the frames
    // the reference simulated.
    for (size_t r = 0; r < candidate.results.size() && r < recs_.size(); ++r) {
      const EvaluationResult& e = candidate.results[r];
      if (e.ok() || (!recs_[r].train && ComparableOnHeldOut(false, e.failure_frame, &current, r))) continue;
      v.reason = fmt::format("the calibrated model fails to simulate {} ({}) from frame {}: {}",
                             recs_[r].name, recs_[r].train ? "training" : "held out",
                             e.failure_frame, e.failure_reason);
      break;
    }
    if (!v.reason.empty()) return v;
  }
  const double train_before = current.XorSum(recs_, true);
  const double train_after = candidate.XorSum(recs_, true);
  std::vector<std::vector<double>> old_errors = current.HeldOutFrameErrors(recs_);
  std::vector<std::vector<double>> new_errors = candidate.HeldOutFrameErrors(recs_);
  // The candidate simulates every held-out frame the reference does. The
  // reference may fail on a held-out recording (a base fit of one push need
  // not simulate another): then the frames it simulated are compared, and
  // the sums are over those.
  std::string compared;
  int compared_frames = 0;
  for (size_t i = 0, r = 0; r < recs_.size(); ++r) {
    if (recs_[r].train) continue;
    const EvaluationResult& e = current.results[r];
    if (!e.ok()) {
      new_errors[i].resize(std::min(new_errors[i].size(), old_errors[i].size()));
      const EvaluationResult& c = candidate.results[r];
      compared += fmt::format("{}the previous model fails on {} from frame {} ({}){}: compared over the {} "
                              "frames before",
                              compared.empty() ? "" : "; ", recs_[r].name, e.failure_frame,
                              e.failure_reason,
                              c.ok() ? "" : fmt::format(", this one from frame {}", c.failure_frame),
                              old_errors[i].size());
    }
    compared_frames += static_cast<int>(old_errors[i].size());
    ++i;
  }
  const auto sum = [](const std::vector<std::vector<double>>& errors) {
    double s = 0.0;
    for (const std::vector<double>& recording : errors) {
      for (double e : recording) s += e;
    }
    return s;
  };
  v.before = compared.empty() ? current.XorSum(recs_, false) : sum(old_errors);
  v.after = compared.empty() ? candidate.XorSum(recs_, false) : sum(new_errors);
  if (compared_frames == 0) {
    v.reason = compared + ": no held-out frame to compare";
    return v;
  }
  PairedTestOptions test;
  test.resamples = o_.test_resamples;
  test.seed = seed;
  v.test = PairedDropTest(old_errors, new_errors, o_.min_relative_drop, test);
  // The XOR sum also falls when a mesh leaves an object it overlaps poorly
  // (less than half): the held-out mean IoU must not fall.
  // Where the reference failed, over the frames compared.
  const auto compared_iou = [&](const EvaluationResult& e, size_t r, size_t frames) {
    double s = 0.0;
    const size_t first = static_cast<size_t>(recs_[r].first_compared_frame);
    for (size_t f = first; f < first + frames; ++f) s += e.frames[f].iou;
    return frames == 0 ? 0.0 : s / static_cast<double>(frames);
  };
  double iou_before = 0.0, iou_after = 0.0;
  int held = 0;
  for (size_t r = 0; r < recs_.size(); ++r) {
    if (recs_[r].train) continue;
    if (current.results[r].ok()) {
      iou_before += current.results[r].mean_iou;
      iou_after += candidate.results[r].mean_iou;
    } else {
      const size_t frames = old_errors[static_cast<size_t>(held)].size();
      iou_before += compared_iou(current.results[r], r, frames);
      iou_after += compared_iou(candidate.results[r], r, frames);
    }
    ++held;
  }
  iou_before /= std::max(held, 1);
  iou_after /= std::max(held, 1);
  const bool train_ok = train_after <= train_before;
  const bool iou_ok = iou_after >= iou_before;
  v.eligible = train_ok && iou_ok;
  auto percent = [](double b, double a) { return b > 0 ? 100.0 * (a - b) / b : 0.0; };
  std::vector<std::string> blocks;
  for (int b : v.test.block_lengths) blocks.push_back(fmt::format("{}", b));
  v.reason = fmt::format(
      "held-out XOR sum {:.0f} -> {:.0f} ({:+.1f}%, 95% interval of the drop {:.0f} to {:.0f}); "
      "paired block sign-flip test of a drop beyond {:g}% over {} frames in {} blocks of {} "
      "frames: p = {:.4f}; "
      "training XOR sum {:.0f} -> {:.0f}{}; held-out mean IoU {:.5f} -> {:.5f}{}",
      v.before, v.after, percent(v.before, v.after), v.test.total_low, v.test.total_high,
      100.0 * o_.min_relative_drop, v.test.frames, v.test.blocks, fmt::join(blocks, "/"), v.test.p_value, train_before,
      train_after, train_ok ? "" : " (rose: the fit got worse where it was fitted)", iou_before,
      iou_after, iou_ok ? "" : " (fell: the XOR drop comes from a mesh that overlaps the object less)");
  if (!compared.empty()) v.reason += "; " + compared;
  return v;
}

}  // namespace loop_detail

}  // namespace calib
