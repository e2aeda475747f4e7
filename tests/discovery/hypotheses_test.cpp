// Tracing residual signatures to ranked effect hypotheses: each effect's
// signature (a hand-made residual analysis) puts that effect first with its
// evidence in numbers; no residual, no hypothesis; effects already in the
// model are left out; merging weighs recordings by applicability; the
// result is deterministic; JSON round-trips and a bad document names the key.

#include "calib/core/effects.h"
#include "calib/discovery/hypotheses.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace calib {
namespace {

// A residual worth explaining (about 2.5 px thick along a 400 px outline)
// that points at nothing in particular: no push, no release, no oscillation.
ResidualAnalysis Plain(const std::string& name = "rec") {
  ResidualAnalysis a;
  a.recording = name;
  a.fps = 30.0;
  a.num_frames = a.frames_analysed = 90;
  a.rest_area_px = 10000.0;
  a.rest_perimeter_px = 400.0;
  a.rest_radius_of_gyration_px = 30.0;
  a.mean_xor_px = 1000.0;
  a.mean_aligned_xor_px = 1000.0;  // shifting the mesh removes none of it
  a.xor_sum = 90000;
  a.mean_iou = 0.9;
  a.residual_thickness_px = 2.5;
  a.p90_thickness_px = 3.0;
  a.motion.mean_offset_px = Vec2(0.1, 0.1);
  a.motion.mean_abs_offset_px = 0.3;
  a.motion.max_abs_offset_px = 0.5;
  a.motion.offset_consistency = 0.2;
  return a;
}

// A push with a hold and a release, elastic (no persistent residual).
ResidualAnalysis Pushed(const std::string& name = "rec") {
  ResidualAnalysis a = Plain(name);
  a.push.has_push = true;
  a.push.push_axis = Vec2(0.0, 1.0);
  a.push.stopped_frames = 20;
  a.push.hold_force_change = 0.0;
  a.push.contact_zone_radius_px = 12.0;
  a.persistence.released = true;
  a.persistence.released_frames = 40;
  a.persistence.before_xor_px = 300.0;
  a.persistence.loaded_xor_px = 1500.0;
  a.persistence.released_xor_px = 320.0;
  a.persistence.released_early_xor_px = 330.0;
  a.persistence.released_late_xor_px = 310.0;
  a.persistence.persistent_ratio = 0.01;
  a.persistence.fading_ratio = 0.02;
  a.strain.num_frames = 60;
  return a;
}

const Hypothesis& Find(const std::vector<Hypothesis>& hs, const std::string& effect) {
  const auto it = std::find_if(hs.begin(), hs.end(), [&](const Hypothesis& h) { return h.effect == effect; });
  EXPECT_NE(it, hs.end()) << effect;
  return *it;
}

const Evidence& FindEvidence(const Hypothesis& h, const std::string& signature) {
  const auto it = std::find_if(h.evidence.begin(), h.evidence.end(),
                               [&](const Evidence& e) { return e.signature == signature; });
  EXPECT_NE(it, h.evidence.end()) << h.effect << ": " << signature;
  return *it;
}

TEST(Hypotheses, EveryEffectOfTheCatalogueHasOneSignatureInItsOrder) {
  std::vector<std::string> catalogue;
  for (const EffectInfo& info : EffectTermCatalogue()) catalogue.push_back(info.name);
  EXPECT_EQ(TracedEffects(), catalogue);
}

TEST(Hypotheses, EveryTracedEffectIsScoredOnceAndRankedByConfidence) {
  const auto hs = TraceHypotheses(Pushed(), {});
  ASSERT_EQ(hs.size(), TracedEffects().size());
  for (const std::string& effect : TracedEffects()) Find(hs, effect);
  for (size_t i = 1; i < hs.size(); ++i) EXPECT_GE(hs[i - 1].confidence, hs[i].confidence);
  for (const Hypothesis& h : hs) {
    EXPECT_GE(h.confidence, 0.0);
    EXPECT_LE(h.confidence, 1.0);
    EXPECT_FALSE(h.summary.empty());
    ASSERT_FALSE(h.evidence.empty());
    // The first piece of evidence is always the residual's size.
    EXPECT_EQ(h.evidence.front().signature, "residual_thickness");
    EXPECT_DOUBLE_EQ(h.evidence.front().value, 3.0);
  }
}

TEST(Hypotheses, NoResidualWorthExplainingGivesNoConfidence) {
  ResidualAnalysis a = Pushed();
  // The same signatures, but the residual is as thin as segmentation noise.
  a.residual_thickness_px = 0.4;
  a.p90_thickness_px = 0.6;
  a.persistence.persistent_ratio = 0.9;
  a.persistence.released_late_xor_px = 1400.0;
  for (const Hypothesis& h : TraceHypotheses(a, {})) EXPECT_EQ(h.confidence, 0.0) << h.effect;
}

// After the release of Pushed() (loaded 1500 px/frame over a 300 px/frame
// floor): the residual early and late in the release, and the share of it
// near the contact with that zone's concentration.
void ResidualAfterRelease(ResidualAnalysis& a, double early, double late, double contact_fraction,
                          double contact_concentration) {
  a.persistence.released_xor_px = 0.5 * (early + late);
  a.persistence.released_early_xor_px = early;
  a.persistence.released_late_xor_px = late;
  a.persistence.persistent_ratio = (late - 300.0) / (1500.0 - 300.0);
  a.persistence.contact_fraction = contact_fraction;
  a.persistence.contact_concentration = contact_concentration;
}

TEST(Hypotheses, PermanentDentAtTheContactIsPlasticity) {
  ResidualAnalysis a = Pushed();
  ResidualAfterRelease(a, 1320.0, 1280.0, 0.6, 4.0);
  a.persistence.fading_ratio = 0.03;
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "plasticity");
  EXPECT_GT(hs.front().confidence, 0.5);
  const Evidence& e = FindEvidence(hs.front(), "persistent_ratio");
  EXPECT_DOUBLE_EQ(e.value, a.persistence.persistent_ratio);
  EXPECT_GT(e.support, 0.9);
  // The statement states the numbers.
  EXPECT_NE(e.statement.find("1280 px/frame"), std::string::npos) << e.statement;
  EXPECT_NE(e.statement.find("82%"), std::string::npos) << e.statement;
  // A persistent residual is not elastic: uneven stiffness and stiffening
  // are discounted.
  EXPECT_LT(Find(hs, "uneven_stiffness").confidence, 0.1);
  EXPECT_LT(Find(hs, "strain_stiffening").confidence, 0.1);
}

TEST(Hypotheses, SlowRecoveryAfterReleaseIsViscoelastic) {
  ResidualAnalysis a = Pushed();
  a.persistence.released_early_xor_px = 1000.0;
  a.persistence.released_late_xor_px = 350.0;
  a.persistence.persistent_ratio = (350.0 - 300.0) / 1200.0;
  a.persistence.fading_ratio = (1000.0 - 350.0) / 1200.0;
  a.persistence.recovery = {true, 320.0, 700.0, 0.5, 0.95};
  a.persistence.object_settle_s = 1.2;
  a.persistence.mesh_settle_s = 0.1;
  a.push.hold_force_change = -0.3;
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "viscoelastic");
  const Evidence& fade = FindEvidence(hs.front(), "slow_recovery");
  EXPECT_DOUBLE_EQ(fade.value, 0.5);
  EXPECT_GT(fade.support, 0.9);
  const Evidence& relax = FindEvidence(hs.front(), "force_relaxes_in_hold");
  EXPECT_DOUBLE_EQ(relax.value, -0.3);
  EXPECT_DOUBLE_EQ(relax.support, 1.0);
  EXPECT_NE(relax.statement.find("-30%"), std::string::npos) << relax.statement;
  EXPECT_LT(Find(hs, "plasticity").confidence, 0.1);
}

TEST(Hypotheses, AnObjectThatSwingsAloneIsInertia) {
  ResidualAnalysis a = Plain();
  a.fps = 240.0;
  a.oscillation.object_motion = {true, 48.0, 0.2, 0.8, 12.0, 1.0, 4.0};
  a.oscillation.offset = {true, 48.0, 0.2, 0.8, 12.0, 1.0, 4.0};
  a.motion.object_motion_rms_px = 8.0;
  a.motion.mesh_motion_rms_px = 0.2;
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "inertia");
  EXPECT_GT(hs.front().confidence, 0.8);
  EXPECT_DOUBLE_EQ(FindEvidence(hs.front(), "offset_oscillation").value, 0.2);
  EXPECT_DOUBLE_EQ(FindEvidence(hs.front(), "moves_without_load").value, 8.0);
  // Without a push, push-related effects cannot show.
  EXPECT_EQ(Find(hs, "table_friction").confidence, 0.0);
  EXPECT_EQ(Find(hs, "table_friction").applicability, 0.0);
  EXPECT_EQ(Find(hs, "push_relaxation").confidence, 0.0);
}

TEST(Hypotheses, MeshSlidingOnAfterThePusherStopsIsPushRelaxation) {
  ResidualAnalysis a = Pushed();
  a.push.mesh_travel_after_stop_px = 6.0;
  a.push.object_travel_after_stop_px = 0.5;
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "push_relaxation");
  const Evidence& e = FindEvidence(hs.front(), "mesh_moves_after_stop");
  EXPECT_DOUBLE_EQ(e.value, 5.5);
  EXPECT_DOUBLE_EQ(e.support, 1.0);
}

TEST(Hypotheses, PlacementDriftingWithThePushIsTableFriction) {
  ResidualAnalysis a = Pushed();
  a.phases.push_back({});
  a.phases.back().phase = LoadPhase::kLoading;
  a.phases.back().num_frames = 30;
  a.phases.back().mean_xor_px = 1500.0;
  a.phases.back().mean_aligned_xor_px = 300.0;  // 80 % of it is placement
  a.push.offset_push_correlation = 0.95;
  a.push.push_distance_px = 40.0;
  a.motion.max_abs_offset_px = 8.0;
  a.push.mean_offset_along_push_px = 4.0;
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "table_friction");
  EXPECT_NEAR(FindEvidence(hs.front(), "placement_share").value, 0.8, 1e-12);
}

TEST(Hypotheses, DeformationHeldAfterReleaseAwayFromTheContactIsTableFriction) {
  // The residual persists after the release, as a permanent dent's does,
  // but spread over the body: the table holds what the springs would undo.
  ResidualAnalysis a = Pushed();
  ResidualAfterRelease(a, 1000.0, 1480.0, 0.05, 1.0);
  auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "table_friction");
  const Evidence& held = FindEvidence(hs.front(), "held_after_release");
  EXPECT_GT(held.support, 0.9);
  EXPECT_GT(hs.front().confidence, Find(hs, "plasticity").confidence);
  // At the contact the same persistence is a permanent dent.
  a.persistence.contact_fraction = 0.6;
  a.persistence.contact_concentration = 4.0;
  hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "plasticity");
  EXPECT_LT(FindEvidence(Find(hs, "table_friction"), "held_after_release").support, 0.05);
  // A residual that fades after the release is a slow recovery, not held.
  a.persistence.contact_fraction = 0.05;
  a.persistence.released_early_xor_px = 2960.0;  // late / early = 0.5
  EXPECT_EQ(FindEvidence(Find(TraceHypotheses(a, {}), "table_friction"), "held_after_release").support,
            0.0);
  // Without a release long enough to tell, no support.
  a.persistence.released_early_xor_px = 1000.0;
  a.persistence.released_frames = 3;
  EXPECT_EQ(FindEvidence(Find(TraceHypotheses(a, {}), "table_friction"), "held_after_release").support,
            0.0);
}

TEST(Hypotheses, ResidualGrowingFasterThanDeformationIsStrainStiffening) {
  ResidualAnalysis a = Pushed();
  a.strain.correlation = 0.95;
  a.strain.exponent = 2.5;
  a.strain.convexity = 4.0;
  a.strain.deformation = {0.01, 0.03, 0.06};
  a.strain.xor_px = {300.0, 500.0, 1500.0};
  a.strain.signed_share = {-0.4, 0.0, 0.5};
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "strain_stiffening");
  EXPECT_DOUBLE_EQ(FindEvidence(hs.front(), "error_grows_superlinearly").value, 2.5);
  EXPECT_NEAR(FindEvidence(hs.front(), "sign_flip").value, 0.45, 1e-12);
}

// Pushed(), with the sensor's force growing as the pusher's travel^exponent
// over 80 loading frames with correlation r.
ResidualAnalysis ForceGrowingAs(double exponent, double r) {
  ResidualAnalysis a = Pushed();
  a.push.force_travel_exponent = exponent;
  a.push.force_travel_correlation = r;
  a.push.force_travel_frames = 80;
  return a;
}

TEST(Hypotheses, ForceGrowingFasterThanThePushIsStrainStiffening) {
  // The pixels show nothing against deformation (a stiff fit absorbs the
  // shape); the sensor's force grows as travel^1.6.
  ResidualAnalysis a = ForceGrowingAs(1.6, 0.99);
  const std::vector<Hypothesis> hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "strain_stiffening");
  const Evidence& force = FindEvidence(hs.front(), "force_stiffens");
  EXPECT_DOUBLE_EQ(force.value, 1.6);
  EXPECT_DOUBLE_EQ(force.support, 1.0);
  EXPECT_EQ(FindEvidence(hs.front(), "error_grows_superlinearly").support, 0.0);
  EXPECT_GT(hs.front().confidence, 0.5);

  // A linear material (force ~ travel) and a scattered relation say nothing.
  a.push.force_travel_exponent = 1.05;
  EXPECT_EQ(FindEvidence(Find(TraceHypotheses(a, {}), "strain_stiffening"), "force_stiffens").support,
            0.0);
  a.push.force_travel_exponent = 1.6;
  a.push.force_travel_correlation = 0.6;
  EXPECT_EQ(Find(TraceHypotheses(a, {}), "strain_stiffening").confidence, 0.0);
  // A residual as thin as what the base model leaves where it is the
  // truth's match: nothing to explain.
  a.push.force_travel_correlation = 0.99;
  a.residual_thickness_px = 0.3;
  a.p90_thickness_px = 0.35;
  EXPECT_EQ(Find(TraceHypotheses(a, {}), "strain_stiffening").confidence, 0.0);
  // Under the pixel signatures' significance floor (0.8 px), the force
  // still counts.
  a.p90_thickness_px = 0.75;
  const std::vector<Hypothesis> thin = TraceHypotheses(a, {});
  EXPECT_EQ(thin.front().effect, "strain_stiffening");
  EXPECT_GT(thin.front().confidence, 0.5);
  // Without a force to read, the evidence says so.
  a.push.force_travel_exponent = NAN;
  const std::vector<Hypothesis> unmeasured = TraceHypotheses(a, {});
  const Evidence& none = FindEvidence(Find(unmeasured, "strain_stiffening"), "force_stiffens");
  EXPECT_EQ(none.support, 0.0);
  EXPECT_NE(none.statement.find("no force"), std::string::npos) << none.statement;
}

// Missed pixels on one side of the push line, extra on the other.
void MakeLopsided(ResidualAnalysis& a) {
  a.regions.side_asymmetry = 0.9;
  a.regions.side_imbalance = 0.5;
  a.regions.side_dipole = 0.5;
  a.regions.signed_dipole = Vec2(0.5, 0.0);
}

TEST(Hypotheses, LopsidedElasticResidualIsUnevenStiffness) {
  ResidualAnalysis a = Pushed();
  MakeLopsided(a);
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "uneven_stiffness");
  EXPECT_DOUBLE_EQ(FindEvidence(hs.front(), "side_asymmetry").value, 0.9);
  // A centroid offset as large as the residual is thick does not discount
  // it by itself: a soft side that dents deeper moves the centroid too.
  a.motion.mean_abs_offset_px = 2.5;
  a.phases.push_back({});
  a.phases.back().phase = LoadPhase::kLoading;
  a.phases.back().num_frames = 30;
  a.phases.back().mean_xor_px = 1500.0;
  a.phases.back().mean_aligned_xor_px = 1470.0;  // shifting removes 2 %
  const double lopsided = Find(TraceHypotheses(a, {}), "uneven_stiffness").confidence;
  EXPECT_GT(lopsided, 0.5);
  EXPECT_NEAR(FindEvidence(Find(TraceHypotheses(a, {}), "uneven_stiffness"), "not_a_shift").value,
              0.02, 1e-12);
  // The same lopsidedness that a shift of the mesh removes is a placement
  // error, discounted to nothing.
  a.phases.back().mean_aligned_xor_px = 300.0;
  EXPECT_LT(Find(TraceHypotheses(a, {}), "uneven_stiffness").confidence, 0.01);
  // Without loaded frames the whole video's aligned residual decides.
  ResidualAnalysis free = Plain();
  free.regions = a.regions;
  EXPECT_GT(Find(TraceHypotheses(free, {}), "uneven_stiffness").confidence, 0.3);
  free.mean_aligned_xor_px = 200.0;  // of 1000
  EXPECT_NEAR(FindEvidence(Find(TraceHypotheses(free, {}), "uneven_stiffness"), "not_a_shift").value,
              0.8, 1e-12);
  EXPECT_LT(Find(TraceHypotheses(free, {}), "uneven_stiffness").confidence, 0.01);
}

// After the release the residual stays, but the mesh laid rigidly onto the
// object removes it: the body was left turned (the stiff side of an uneven
// object turned it otherwise than the model), its shape recovered. No
// permanent set, no held deformation, and the lopsided residual stays
// elastic: uneven stiffness.
TEST(Hypotheses, APoseLeftWrongAfterReleaseIsNotAPersistentDeformation) {
  ResidualAnalysis a = Pushed();
  MakeLopsided(a);
  ResidualAfterRelease(a, 2400.0, 2600.0, 0.1, 1.0);  // 192 % of the loaded residual stays
  const double plastic_raw = Find(TraceHypotheses(a, {}), "plasticity").confidence;
  const double uneven_raw = Find(TraceHypotheses(a, {}), "uneven_stiffness").confidence;
  EXPECT_LT(uneven_raw, 0.1) << "counted on the whole residual, it is persistent, not elastic";

  a.persistence.before_rigid_xor_px = 280.0;
  a.persistence.loaded_rigid_xor_px = 1100.0;
  a.persistence.released_late_rigid_xor_px = 300.0;
  a.persistence.shape_persistent_ratio = (300.0 - 280.0) / (1100.0 - 280.0);
  const auto hs = TraceHypotheses(a, {});
  EXPECT_EQ(hs.front().effect, "uneven_stiffness");
  EXPECT_GT(hs.front().confidence, 0.5);
  const Evidence& e = FindEvidence(Find(hs, "plasticity"), "persistent_ratio");
  EXPECT_DOUBLE_EQ(e.value, a.persistence.shape_persistent_ratio);
  EXPECT_EQ(e.support, 0.0);
  EXPECT_NE(e.statement.find("laid rigidly onto the object"), std::string::npos) << e.statement;
  EXPECT_LT(Find(hs, "plasticity").confidence, plastic_raw);
  EXPECT_LT(Find(hs, "table_friction").confidence, 0.05);

  // A shape error that stays (a dent) is persistent on either count.
  a.persistence.released_late_rigid_xor_px = 1000.0;
  a.persistence.shape_persistent_ratio = (1000.0 - 280.0) / (1100.0 - 280.0);
  EXPECT_GT(FindEvidence(Find(TraceHypotheses(a, {}), "plasticity"), "persistent_ratio").support, 0.9);
  EXPECT_LT(Find(TraceHypotheses(a, {}), "uneven_stiffness").confidence, 0.1);
}

TEST(Hypotheses, EffectsAlreadyInTheModelAreLeftOut) {
  const auto hs = TraceHypotheses(Pushed(), {"inertia", "viscoelastic"});
  EXPECT_EQ(hs.size(), TracedEffects().size() - 2);
  for (const Hypothesis& h : hs) {
    EXPECT_NE(h.effect, "inertia");
    EXPECT_NE(h.effect, "viscoelastic");
  }
}

TEST(Hypotheses, MergingWeighsRecordingsByApplicability) {
  // One recording shows a permanent dent; the other has no release, so it
  // cannot say anything about plasticity and must not dilute it.
  ResidualAnalysis dent = Pushed("dent");
  dent.persistence.released_late_xor_px = 1280.0;
  dent.persistence.released_early_xor_px = 1300.0;
  dent.persistence.persistent_ratio = 0.8;
  dent.persistence.contact_fraction = 0.6;
  dent.persistence.contact_concentration = 4.0;
  ResidualAnalysis held = Pushed("held");
  held.persistence = {};
  const auto a = TraceHypotheses(dent, {});
  const auto b = TraceHypotheses(held, {});
  EXPECT_EQ(Find(b, "plasticity").applicability, 0.0);
  const auto merged = MergeHypotheses({a, b});
  ASSERT_EQ(merged.size(), TracedEffects().size());
  const Hypothesis& p = Find(merged, "plasticity");
  EXPECT_DOUBLE_EQ(p.confidence, Find(a, "plasticity").confidence);
  EXPECT_EQ(merged.front().effect, "plasticity");
  EXPECT_EQ(p.recordings, (std::vector<std::string>{"dent", "held"}));
  // Evidence is kept from both, each statement naming its recording.
  EXPECT_EQ(p.evidence.size(), Find(a, "plasticity").evidence.size() +
                                   Find(b, "plasticity").evidence.size());
  EXPECT_EQ(p.evidence.front().statement.rfind("dent: ", 0), 0u);
  EXPECT_EQ(p.evidence.back().statement.rfind("held: ", 0), 0u);
}

TEST(Hypotheses, Deterministic) {
  ResidualAnalysis a = Pushed();
  a.strain.correlation = 0.5;
  a.strain.exponent = 1.5;
  a.regions.side_asymmetry = 0.3;
  const auto first = TraceHypotheses(a, {});
  const auto second = TraceHypotheses(a, {});
  ASSERT_EQ(first.size(), second.size());
  for (size_t i = 0; i < first.size(); ++i) EXPECT_EQ(ToJson(first[i]), ToJson(second[i]));
  EXPECT_EQ(HypothesesReport(first), HypothesesReport(second));
  // Ties (all zero here) keep the catalogue's order.
  ResidualAnalysis none = Pushed();
  none.residual_thickness_px = none.p90_thickness_px = 0.1;
  const auto ties = TraceHypotheses(none, {});
  for (size_t i = 0; i < ties.size(); ++i) EXPECT_EQ(ties[i].effect, TracedEffects()[i]);
}

TEST(Hypotheses, ReportNamesEachEffectWithItsConfidence) {
  const auto hs = TraceHypotheses(Pushed(), {});
  const std::string text = HypothesesReport(hs);
  for (const Hypothesis& h : hs) EXPECT_NE(text.find(h.effect), std::string::npos) << h.effect;
  EXPECT_NE(text.find("1. "), std::string::npos);
  EXPECT_NE(text.find("confidence"), std::string::npos);
}

TEST(Hypotheses, JsonRoundTripKeepsEveryNumberAndNanAsNull) {
  ResidualAnalysis a = Pushed();
  a.persistence.contact_concentration = NAN;
  for (const Hypothesis& h : TraceHypotheses(a, {})) {
    const nlohmann::json j = ToJson(h);
    const Hypothesis back = HypothesisFromJson(nlohmann::json::parse(j.dump()));
    EXPECT_EQ(ToJson(back), j);
    EXPECT_EQ(back.effect, h.effect);
    EXPECT_EQ(back.confidence, h.confidence);
    ASSERT_EQ(back.evidence.size(), h.evidence.size());
    for (size_t i = 0; i < h.evidence.size(); ++i) {
      if (std::isnan(h.evidence[i].value)) {
        EXPECT_TRUE(j["evidence"][i]["value"].is_null());
        EXPECT_TRUE(std::isnan(back.evidence[i].value));
      } else {
        EXPECT_EQ(back.evidence[i].value, h.evidence[i].value);
      }
    }
  }
}

TEST(Hypotheses, BadJsonNamesTheKey) {
  const nlohmann::json good = ToJson(TraceHypotheses(Pushed(), {}).front());
  auto message = [](const nlohmann::json& doc) {
    try {
      HypothesisFromJson(doc);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  nlohmann::json j = good;
  j.erase("confidence");
  EXPECT_NE(message(j).find("'confidence': missing"), std::string::npos) << message(j);
  j = good;
  j["effect"] = 3;
  EXPECT_NE(message(j).find("'effect': expected a string"), std::string::npos) << message(j);
  j = good;
  j["evidence"][0]["support"] = "high";
  EXPECT_NE(message(j).find("'support': expected a number"), std::string::npos) << message(j);
  j = good;
  j["evidence"] = 1;
  EXPECT_NE(message(j).find("'evidence': expected an array"), std::string::npos) << message(j);
  j = good;
  j["recordings"] = {1};
  EXPECT_NE(message(j).find("'recordings'"), std::string::npos) << message(j);
  EXPECT_NE(message(nlohmann::json::array()).find("(root)"), std::string::npos);
}

}  // namespace
}  // namespace calib
