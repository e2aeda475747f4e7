// Speed of a full evaluation of the reference scene (reference_scene.h) with
// each effect of the catalogue on, beside BM_FullEvaluation (the base model):
//
//   BM_FullEvaluationWithEffect/none     the base model through named values
//   BM_FullEvaluationWithEffect/<effect> the base model plus that effect
//   BM_FullEvaluationWithEffect/all      every effect at once
//   BM_FullEvaluationWithEffect/implicit/<none, uneven_stiffness,
//     strain_stiffening>  with the implicit first-order step (the loop's):
//     what the rest-stiffness probe and the per-frame re-linearisation of
//     the stiffening springs cost
//   BM_FullEvaluationWithEffect/loop/<none, effect>  with the loop's
//     simulation options (LoopSimulationDefaults: the implicit step,
//     contacts held in its solve with friction, outline contact): each
//     effect's cost where the loop adds it (issue: at most 1.5 times
//     loop/none). With inertia the step is the effect's own second-order one.
//
//   build/bench/calib_bench --benchmark_filter=WithEffect

#include <benchmark/benchmark.h>

#include "calib/core/effects.h"
#include "calib/discovery/loop.h"
#include "reference_scene.h"

namespace calib::bench {
namespace {

// The reference parameters plus a value for every effect's parameters under
// which each effect does something on the reference scene and the run ends
// ok (a top view: no gravity; the push peaks at 2 force units).
ParameterValues EffectValues() {
  ParameterValues values = ReferenceParameters().ToValues();
  values.insert({{"inertia_damping_per_s", 5.0},
                 {"gravity_px_s2", 0.0},
                 {"gravity_angle_deg", 90.0},
                 {"friction_force", 1.0},
                 {"plastic_yield_strain", 0.05},
                 {"plastic_rate_per_s", 2.0},
                 {"uneven_gradient", 0.5},
                 {"uneven_angle_deg", 0.0},
                 {"stiffening_k3", 2000.0},
                 {"visco_share", 0.3},
                 {"visco_time_s", 1.0},
                 {"push_friction_force", 1.0}});
  return values;
}

// Only the values the model takes.
ParameterValues ValuesFor(const ModelDefinition& model) {
  const ParameterValues all = EffectValues();
  ParameterValues values;
  for (const ParameterSpec& spec : ModelParameterSpecs(model))
    values[spec.name] = all.at(spec.name);
  return values;
}

void FullEvaluationWithEffects(benchmark::State& state, const ModelDefinition& model,
                               const SimulationOptions& options) {
  Evaluator evaluator(ReferenceScene(), options, model);
  const ParameterValues values = ValuesFor(model);
  for (auto _ : state) {
    const EvaluationResult result = evaluator.Evaluate(values);
    if (!result.ok()) state.SkipWithError(result.failure_reason.c_str());
    benchmark::DoNotOptimize(result.xor_sum);
  }
  state.counters["frames"] = ReferenceScene().scene.num_frames;
  state.counters["nodes"] = ReferenceScene().mesh.NumNodes();
}

const bool kRegistered = [] {
  const auto add = [](const std::string& label, ModelDefinition model,
                      SimulationOptions options = {}) {
    benchmark::RegisterBenchmark(
        ("BM_FullEvaluationWithEffect/" + label).c_str(),
        [model, options](benchmark::State& state) {
          FullEvaluationWithEffects(state, model, options);
        })
        ->Unit(benchmark::kMillisecond);
  };
  add("none", ModelDefinition{});
  ModelDefinition all;
  for (const EffectInfo& info : EffectTermCatalogue()) {
    add(info.name, ModelDefinition{{info.name}});
    all.effects.push_back(info.name);
  }
  add("all", all);
  SimulationOptions implicit;
  implicit.integrator = IntegratorKind::kImplicitFirstOrder;
  add("implicit/none", ModelDefinition{}, implicit);
  add("implicit/uneven_stiffness", ModelDefinition{{"uneven_stiffness"}}, implicit);
  add("implicit/strain_stiffening", ModelDefinition{{"strain_stiffening"}}, implicit);
  const SimulationOptions loop = LoopSimulationDefaults();
  add("loop/none", ModelDefinition{}, loop);
  for (const EffectInfo& info : EffectTermCatalogue()) {
    add("loop/" + info.name, ModelDefinition{{info.name}}, loop);
  }
  return true;
}();

}  // namespace
}  // namespace calib::bench
