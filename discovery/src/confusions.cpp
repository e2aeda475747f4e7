#include "calib/discovery/confusions.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <limits>

namespace calib {
namespace {

// An off-centre push turns an even object: below this eccentricity (the
// tracer's own ramp for uneven stiffness starts here) the turn is too small
// to pass for an uneven field.
constexpr double kOffCentre = 0.2;

constexpr std::array<ConfusablePair, 3> kPairs = {{
    {"plasticity", "table_friction",
     "whether the deformation left after the release stays when the object moves again",
     "after the release, push the object again, gently, from another side (or repeat the push "
     "on a smoother table): a deformation held by table friction springs back once the object "
     "slides, a plastic dent stays"},
    {"plasticity", "viscoelastic",
     "whether the dent left after the release recovers with time",
     "hold the push as long, then record for at least 10 s after the release (three relaxation "
     "times of the slowest relaxation fitted): a viscoelastic dent recovers, a crept one stays"},
    {"uneven_stiffness", "",
     "whether the object's turn follows the side of the push",
     "push the same object through its centre and at the mirrored offset on the other side: an "
     "even object does not turn under a centred push and turns the other way under the mirrored "
     "one, an uneven object turns towards its soft side both times"},
}};

const Hypothesis* Find(const std::vector<Hypothesis>& ranked, const std::string& effect) {
  const auto it = std::find_if(ranked.begin(), ranked.end(),
                               [&](const Hypothesis& h) { return h.effect == effect; });
  return it == ranked.end() ? nullptr : &*it;
}

// The effect's stage among those tried; of several calibrations of it
// (LoopOptions::effect_restarts) a significant one before the others, then
// the largest held-out drop: the one the round would keep.
const ReportStage* Tried(const std::vector<const ReportStage*>& tried, const std::string& effect) {
  const ReportStage* best = nullptr;
  const auto rank = [](const ReportStage* s) {
    return std::make_pair(s->test.frames > 0 && s->test.significant, s->test.frames > 0 ? s->test.drop : -std::numeric_limits<double>::infinity());
  };
  for (const ReportStage* s : tried) {
    if (s->effect_tried == effect && (best == nullptr || rank(best) < rank(s))) best = s;
  }
  return best;
}

std::string TestLine(const std::string& effect, const ReportStage& s) {
  if (s.test.frames == 0) return fmt::format("{} was not tested (it failed to simulate)", effect);
  return fmt::format("{}: held-out drop {:.0f} (95% {:.0f} to {:.0f}), p = {:.4f}, {}", effect,
                     s.test.drop, s.test.drop_low, s.test.drop_high, s.test.p_value,
                     s.test.significant ? "significant" : "not significant");
}

}  // namespace

std::span<const ConfusablePair> ConfusablePairs() { return kPairs; }

std::vector<ReportConfusion> JudgeConfusions(int round, const std::vector<Hypothesis>& ranked,
                                             const std::vector<const ReportStage*>& tried,
                                             double load_eccentricity, double min_confidence) {
  std::vector<ReportConfusion> out;
  for (const ConfusablePair& pair : kPairs) {
    const std::string a = pair.effect, b = pair.confused_with;
    const Hypothesis* ha = Find(ranked, a);
    const ReportStage* sa = Tried(tried, a);
    const bool a_met = sa != nullptr || (ha != nullptr && ha->confidence >= min_confidence);
    ReportConfusion c;
    c.round = round;
    c.effect = a;
    c.confused_with = b;
    if (b.empty()) {
      // The base model's own turn under an off-centre push.
      if (!a_met || load_eccentricity < kOffCentre) continue;
      if (sa != nullptr && sa->test.frames > 0 && sa->test.significant) {
        c.separated = true;
        c.evidence = fmt::format(
            "the push is off-centre (eccentricity {:.2f}), so an even object turns too; the "
            "held-out data separate them: {}",
            load_eccentricity, TestLine(a, *sa));
      } else {
        c.evidence = fmt::format(
            "the push is off-centre (eccentricity {:.2f}): an even object turns under it as an "
            "uneven one would, and {}; these recordings cannot tell {} from the base model's "
            "turn ({})",
            load_eccentricity,
            sa != nullptr ? TestLine(a, *sa)
                          : fmt::format("{} was traced at {:.2f} but not tried", a, ha->confidence),
            a, pair.separating_evidence);
        c.proposal = pair.proposal;
      }
      out.push_back(std::move(c));
      continue;
    }
    const Hypothesis* hb = Find(ranked, b);
    const ReportStage* sb = Tried(tried, b);
    const bool b_met = sb != nullptr || (hb != nullptr && hb->confidence >= min_confidence);
    if (!a_met || !b_met || (sa == nullptr && sb == nullptr)) continue;
    const auto traced = [](const std::string& effect, const Hypothesis* h) {
      return h == nullptr ? fmt::format("{} was not traced", effect)
                          : fmt::format("{} was traced at {:.2f} but not tried", effect, h->confidence);
    };
    if (sa != nullptr && sb != nullptr && sa->test.frames > 0 && sb->test.frames > 0) {
      const bool a_sig = sa->test.significant, b_sig = sb->test.significant;
      if (a_sig != b_sig) {
        c.separated = true;
      } else if (a_sig && b_sig) {
        // Both lower the held-out error: separated where the drops' intervals
        // do not overlap.
        c.separated = sa->test.drop_low > sb->test.drop_high || sb->test.drop_low > sa->test.drop_high;
      }
      c.evidence = fmt::format("{}; {}{}", TestLine(a, *sa), TestLine(b, *sb),
                               c.separated ? ""
                               : a_sig     ? ": both lower the held-out error by amounts the "
                                             "test cannot tell apart"
                                           : ": neither lowers the held-out error");
    } else {
      c.evidence = fmt::format("{}; {}: only one of the two was tested",
                               sa != nullptr ? TestLine(a, *sa) : traced(a, ha),
                               sb != nullptr ? TestLine(b, *sb) : traced(b, hb));
    }
    if (!c.separated) {
      c.evidence += fmt::format("; what would tell them apart: {}", pair.separating_evidence);
      c.proposal = pair.proposal;
    }
    out.push_back(std::move(c));
  }
  return out;
}

}  // namespace calib
