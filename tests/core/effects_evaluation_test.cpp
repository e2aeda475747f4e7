// Evaluating candidates of a model with effects on the reference scene
// (bench/reference_scene.h): the named-values overload of Evaluate gives the
// old Evaluate(ModelParameters) result bit for bit when no effect is on;
// with effects, results are deterministic across evaluators and reuse, and
// bad values are errors naming the parameter.

#include <gtest/gtest.h>

#include "calib/evaluator/evaluation.h"
#include "reference_scene.h"

namespace calib {
namespace {

const PreparedRecording& Reference() { return bench::ShortReferenceScene(); }

using StateHistory = std::vector<std::vector<Vec2>>;

EvaluationResult EvaluateRecording(Evaluator& evaluator, const ParameterValues& values,
                                   StateHistory* states) {
  return evaluator.Evaluate(values, [&](int, const Simulator& sim, const BitMask&,
                                        const FrameScore&) { states->push_back(sim.positions()); });
}

void ExpectSameResult(const EvaluationResult& a, const EvaluationResult& b) {
  ASSERT_EQ(a.status, b.status);
  EXPECT_EQ(a.xor_sum, b.xor_sum);
  EXPECT_EQ(a.mean_iou, b.mean_iou);
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (size_t f = 0; f < a.frames.size(); ++f) {
    EXPECT_EQ(a.frames[f].xor_px, b.frames[f].xor_px) << "frame " << f;
    EXPECT_EQ(a.frames[f].iou, b.frames[f].iou) << "frame " << f;
  }
}

TEST(EvaluatorWithEffects, NoEffectsIsTheOldPathBitForBit) {
  for (IntegratorKind integrator : {IntegratorKind::kFirstOrder, IntegratorKind::kVerlet}) {
    SimulationOptions options;
    options.integrator = integrator;
    ModelParameters params = bench::ReferenceParameters();
    if (integrator == IntegratorKind::kVerlet) params.mass = 50.0;
    Evaluator old_path(Reference(), options);
    StateHistory old_states;
    const EvaluationResult old_result = old_path.Evaluate(
        params, [&](int, const Simulator& sim, const BitMask&, const FrameScore&) {
          old_states.push_back(sim.positions());
        });
    ASSERT_TRUE(old_result.ok()) << old_result.failure_reason;
    Evaluator named(Reference(), options, ModelDefinition{});
    StateHistory named_states;
    const EvaluationResult named_result =
        EvaluateRecording(named, params.ToValues(), &named_states);
    ExpectSameResult(old_result, named_result);
    EXPECT_EQ(old_states, named_states) << ToString(integrator);
  }
}

ParameterValues WithEffects() {
  ParameterValues v = bench::ReferenceParameters().ToValues();
  v.insert({{"friction_force", 2.0},
            {"plastic_yield_strain", 0.05},
            {"plastic_rate_per_s", 5.0},
            {"uneven_gradient", 0.4},
            {"uneven_angle_deg", 90.0},
            {"stiffening_k3", 800.0},
            {"visco_share", 0.3},
            {"visco_time_s", 1.0},
            {"push_friction_force", 0.5}});
  return v;
}

const ModelDefinition kFirstOrderEffects{{"table_friction", "plasticity", "uneven_stiffness",
                                          "strain_stiffening", "viscoelastic", "push_relaxation"}};

TEST(EvaluatorWithEffects, DeterministicAcrossEvaluatorsAndReuse) {
  Evaluator a(Reference(), {}, kFirstOrderEffects);
  Evaluator b(Reference(), {}, kFirstOrderEffects);
  StateHistory states_a, states_b, states_again;
  const EvaluationResult first = EvaluateRecording(a, WithEffects(), &states_a);
  ASSERT_TRUE(first.ok()) << first.failure_reason;
  ParameterValues other = WithEffects();
  other["plastic_yield_strain"] = 0.01;
  a.Evaluate(other);
  ExpectSameResult(first, EvaluateRecording(b, WithEffects(), &states_b));
  ExpectSameResult(first, EvaluateRecording(a, WithEffects(), &states_again));
  EXPECT_EQ(states_a, states_b);
  EXPECT_EQ(states_a, states_again);
  // The effects changed the simulation.
  Evaluator base(Reference(), {});
  EXPECT_NE(base.Evaluate(bench::ReferenceParameters()).xor_sum, first.xor_sum);
}

TEST(EvaluatorWithEffects, BadValuesAreErrorsNamingTheParameter) {
  Evaluator evaluator(Reference(), {}, kFirstOrderEffects);
  ParameterValues values = WithEffects();
  values["visco_share"] = 1.5;
  try {
    evaluator.Evaluate(values);
    FAIL() << "no exception";
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find("'visco_share' = 1.5"), std::string::npos) << e.what();
  }
  EXPECT_THROW(evaluator.Evaluate(bench::ReferenceParameters()), std::logic_error);
  EXPECT_THROW(Evaluator(Reference(), {}, ModelDefinition{{"elasticity"}}), std::invalid_argument);
}

}  // namespace
}  // namespace calib
