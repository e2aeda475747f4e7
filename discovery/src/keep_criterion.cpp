// The keep criterion of the closed loop (keep_criterion.h) and the
// KeepCriterion that judges an effect (loop_stages.h).

#include "calib/discovery/keep_criterion.h"

#include "loop_stages.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <cmath>
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

double IouTolerance(double margin_px, const std::vector<const std::vector<BitMask>*>& held_out_masks) {
  double object_px = 0.0;
  for (const std::vector<BitMask>* masks : held_out_masks) {
    for (const BitMask& m : *masks) object_px += static_cast<double>(m.Count());
  }
  return object_px > 0.0 ? std::max(margin_px, 0.0) / object_px : 0.0;
}

std::vector<ParameterValues> SelectEquallyGoodFits(const std::vector<EvaluationRecord>& evaluations,
                                                   double tolerance, int limit) {
  std::vector<const EvaluationRecord*> ok;
  for (const EvaluationRecord& e : evaluations) {
    if (e.ok && std::isfinite(e.score)) ok.push_back(&e);
  }
  if (ok.empty() || limit <= 0) return {};
  std::stable_sort(ok.begin(), ok.end(),
                   [](const EvaluationRecord* a, const EvaluationRecord* b) { return a->score < b->score; });
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
    if (recs[r].train == train) s += results[r].ok() ? results[r].xor_sum : INT64_MAX / 64;
  }
  return s;
}

bool Fit::AllOk() const {
  return std::all_of(results.begin(), results.end(), [](const EvaluationResult& e) { return e.ok(); });
}

bool KeepCriterion::HasHoldout() const {
  return std::any_of(recs_.begin(), recs_.end(), [](const LoopRecording& r) { return !r.train; });
}

double KeepCriterion::NoiseBudget(bool train) const {
  double b = 0.0;
  for (const LoopRecording& r : recs_) {
    if (r.train == train) b += r.noise_px * r.prepared->scene.num_frames;
  }
  return b;
}

double KeepCriterion::Margin(bool train, int extra_parameters, double before) const {
  return std::max(o_.noise_factor * (1 + extra_parameters) * NoiseBudget(train),
                  o_.min_relative_gain * before);
}

std::vector<const std::vector<BitMask>*> KeepCriterion::HeldOutMasks() const {
  std::vector<const std::vector<BitMask>*> out;
  for (const LoopRecording& r : recs_) {
    if (!r.train) out.push_back(&r.prepared->object_masks);
  }
  return out;
}

KeepCriterion::Verdict KeepCriterion::Judge(const Fit& previous, const Fit* ablation, const Fit& candidate,
                          int extra_parameters) const {
  // The reference on the training recordings: the previous fit, or the
  // ablation where it is better there.
  const Fit& current = ablation != nullptr ? *ablation : previous;
  Verdict v;
  const double train_before = current.XorSum(recs_, true);
  const double train_after = candidate.XorSum(recs_, true);
  if (!candidate.AllOk()) {
    v.criterion = "every recording simulates";
    v.reason = "the calibrated model fails to simulate a recording";
    return v;
  }
  if (HasHoldout()) {
    // A model's held-out error is known only up to the spread of its
    // equally good fits, and a search that converged tightly has less
    // spread than one that did not: the effect must lower the held-out error
    // both at the best training fits and at the median over the equally
    // good fits (its best training fit where they were not measured). The
    // ablation, one more fit of the previous model, is the reference where
    // it does better on training.
    auto typical = [&](const Fit& fit) {
      return fit.equally_good.fits > 0 ? static_cast<double>(fit.equally_good.holdout_xor_median)
                                       : static_cast<double>(fit.XorSum(recs_, false));
    };
    const double best_before = static_cast<double>(current.XorSum(recs_, false));
    const double best_after = static_cast<double>(candidate.XorSum(recs_, false));
    double typical_before = typical(previous);
    if (ablation != nullptr) typical_before = std::min(typical_before, best_before);
    const double typical_after = typical(candidate);
    const double noise = NoiseBudget(false);
    // Neither model's held-out error can be read closer than a nudge of its
    // values moves it.
    const double sensitivity =
        std::max(previous.holdout_sensitivity_px, candidate.holdout_sensitivity_px);
    auto margin = [&](double before) {
      return std::max(Margin(false, extra_parameters, before), sensitivity);
    };
    // The deciding comparison: the one whose drop exceeds its margin by less.
    const double best_slack = best_before - best_after - margin(best_before);
    const double typical_slack = typical_before - typical_after - margin(typical_before);
    const bool decided_at_best = best_slack <= typical_slack;
    const double before = decided_at_best ? best_before : typical_before;
    const double after = decided_at_best ? best_after : typical_after;
    v.gain = before - after;
    v.margin = margin(before);
    v.criterion = "held-out XOR sum";
    const bool train_ok = train_after <= train_before;
    // The XOR sum also falls when the mesh leaves an object it overlaps
    // poorly (less than half): the held-out mean IoU must not fall.
    double iou_before = 0.0, iou_after = 0.0;
    int held = 0;
    for (size_t r = 0; r < recs_.size(); ++r) {
      if (recs_[r].train) continue;
      iou_before += current.results[r].mean_iou;
      iou_after += candidate.results[r].mean_iou;
      ++held;
    }
    iou_before /= std::max(held, 1);
    iou_after /= std::max(held, 1);
    // A fall the XOR margin calls insignificant is no fall.
    const double iou_tolerance = IouTolerance(v.margin, HeldOutMasks());
    const bool iou_ok = iou_after >= iou_before - iou_tolerance;
    v.pass = v.gain > v.margin && train_ok && iou_ok;
    auto spread = [](const EquallyGoodFits& g) {
      return g.fits == 0 ? std::string("not measured")
                         : fmt::format("{} fits, {:.0f} to {:.0f}", g.fits, g.holdout_xor_min, g.holdout_xor_max);
    };
    auto percent = [](double b, double a) { return b > 0 ? 100.0 * (a - b) / b : 0.0; };
    v.reason = fmt::format(
        "held-out XOR sum at the best training fits {:.0f} -> {:.0f} ({:+.1f}%), median over the "
        "equally good fits {:.0f} -> {:.0f} ({:+.1f}%) (training XOR within {:.0f} px of the best; "
        "before: {}; after: {}): the deciding drop ({}), {:.0f} px, {} the margin {:.0f} px = max({} x "
        "(1 + {} extra parameters) x segmentation noise {:.0f} px, {:.0f}% of {:.0f}, what a 0.1% "
        "nudge of either model's values moves: {:.0f} px); training "
        "XOR sum {:.0f} -> {:.0f}{}; held-out mean IoU {:.5f} -> {:.5f}{}",
        best_before, best_after, percent(best_before, best_after), typical_before, typical_after,
        percent(typical_before, typical_after), candidate.equally_good.training_tolerance_px,
        spread(previous.equally_good), spread(candidate.equally_good),
        decided_at_best ? "at the best fits" : "of the medians", v.gain,
        v.gain > v.margin ? "exceeds" : "does not exceed", v.margin, o_.noise_factor,
        extra_parameters, noise, 100.0 * o_.min_relative_gain, before, sensitivity, train_before,
        train_after,
        train_ok ? "" : " (rose: the fit got worse where it was fitted)", iou_before, iou_after,
        iou_after >= iou_before ? ""
        : iou_ok ? fmt::format(" (fell by less than the margin's {:.5f})", iou_tolerance)
                 : fmt::format(" (fell by more than the margin's {:.5f}: the XOR drop comes from "
                               "a mesh that overlaps the object less)",
                               iou_tolerance));
    return v;
  }
  // No held-out recording: BIC on the per-frame errors of the training
  // recordings (Gaussian per-frame XOR), plus the noise margin.
  auto sse = [&](const Fit& fit, int64_t* n) {
    double s = 0.0;
    *n = 0;
    for (size_t r = 0; r < recs_.size(); ++r) {
      if (!recs_[r].train) continue;
      for (const FrameScore& f : fit.results[r].frames) {
        s += static_cast<double>(f.xor_px) * f.xor_px;
        ++*n;
      }
    }
    return s;
  };
  int64_t n = 0;
  const double sse_before = sse(current, &n);
  const double sse_after = sse(candidate, &n);
  SearchScales scales = scales_;
  scales.reference = current.values;
  const int k_before = SearchSpace(StageParameterSettings(current.effects, scales)).dimension();
  const int k_after = k_before + extra_parameters;
  auto bic = [&](double s, int k) {
    return n * std::log(std::max(s, 1.0) / std::max<int64_t>(n, 1)) + k * std::log(std::max<int64_t>(n, 2));
  };
  const double b0 = bic(sse_before, k_before), b1 = bic(sse_after, k_after);
  v.gain = static_cast<double>(train_before - train_after);
  v.margin = Margin(true, extra_parameters, static_cast<double>(train_before));
  v.criterion = "BIC of per-frame training XOR";
  v.pass = b1 < b0 && v.gain > v.margin;
  v.reason = fmt::format(
      "no held-out recording: BIC {:.1f} -> {:.1f} over {} frames ({} -> {} parameters); training "
      "XOR sum {} -> {}, drop {:.0f} px {} the margin {:.0f} px",
      b0, b1, n, k_before, k_after, train_before, train_after, v.gain,
      v.gain > v.margin ? "exceeds" : "does not exceed", v.margin);
  return v;
}

}  // namespace loop_detail

}  // namespace calib
