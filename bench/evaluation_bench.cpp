// Speed of the evaluation hot loop on the reference scene (see
// reference_scene.h): one full evaluation (simulate and score all frames),
// one substep, and one frame's scoring (rasterise + compare, by the score's
// coverage rule and by the centre rule it replaced); the preparation's
// mesh registration onto an outline and its nearest-segment queries.
//
//   build/bench/calib_bench --benchmark_min_time=1

#include "reference_scene.h"

#include "calib/evaluator/contour.h"
#include "calib/evaluator/nearest_segment.h"
#include "calib/evaluator/shape_tracking.h"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace calib::bench {
namespace {

void SetMeshCounters(benchmark::State& state) {
  const Mesh& mesh = ReferenceScene().mesh;
  state.counters["nodes"] = mesh.NumNodes();
  state.counters["edges"] = mesh.NumEdges();
  state.counters["triangles"] = mesh.NumTriangles();
}

// Argument: 0 the paper's contact (obstacles push nodes), 1 outline
// contact (obstacles also push the boundary edges, constraints.h).
// Arguments: outline contact (0 / 1), implicit step (0 / 1).
void BM_FullEvaluation(benchmark::State& state) {
  SimulationOptions options;
  options.outline_contact = state.range(0) != 0;
  if (state.range(1) != 0) options.integrator = IntegratorKind::kImplicitFirstOrder;
  Evaluator evaluator(ReferenceScene(), options);
  const ModelParameters params = ReferenceParameters();
  for (auto _ : state) {
    const EvaluationResult result = evaluator.Evaluate(params);
    if (!result.ok()) state.SkipWithError(result.failure_reason.c_str());
    benchmark::DoNotOptimize(result.xor_sum);
  }
  SetMeshCounters(state);
  state.counters["frames"] = ReferenceScene().scene.num_frames;
}
BENCHMARK(BM_FullEvaluation)
    ->ArgNames({"outline_contact", "implicit"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond);

// Argument: implicit step (0 / 1).
void BM_Substep(benchmark::State& state) {
  SimulationOptions options;
  if (state.range(0) != 0) options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator simulator(ReferenceScene().mesh, ReferenceScene().scene, options);
  simulator.Reset(ReferenceParameters());
  // Move to a loaded frame so the finger is in contact.
  for (int f = 0; f < 100; ++f) simulator.Advance();
  for (auto _ : state) {
    if (!simulator.Substep(0)) state.SkipWithError(simulator.failure_reason().c_str());
    benchmark::DoNotOptimize(simulator.positions().data());
  }
  SetMeshCounters(state);
}
BENCHMARK(BM_Substep)->ArgName("implicit")->DenseRange(0, 1)->Unit(benchmark::kMicrosecond);

// What the implicit step adds per candidate: the matrix's factorisation in
// Reset (the unit matrices are assembled once, in the constructor).
void BM_ImplicitReset(benchmark::State& state) {
  SimulationOptions options;
  options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator simulator(ReferenceScene().mesh, ReferenceScene().scene, options);
  const ModelParameters params = ReferenceParameters();
  for (auto _ : state) {
    simulator.Reset(params);
    benchmark::DoNotOptimize(simulator.positions().data());
  }
  SetMeshCounters(state);
}
BENCHMARK(BM_ImplicitReset)->Unit(benchmark::kMicrosecond);

// The internal forces alone, with a workspace as the simulator keeps one
// (no allocation per call), on the kernel kAuto picks.
void ForcesWithKernel(benchmark::State& state, ForceKernel kernel) {
  const Mesh& mesh = ReferenceScene().mesh;
  const Model model(mesh);
  ForceWorkspace workspace = model.MakeWorkspace();
  std::vector<Vec2> x = mesh.rest_positions, v(x.size(), Vec2(0.1, -0.2)), f(x.size());
  for (size_t i = 0; i < x.size(); ++i) x[i] += Vec2(0.3 * std::sin(i), 0.2 * std::cos(i));
  const ModelParameters params = ReferenceParameters();
  for (auto _ : state) {
    benchmark::DoNotOptimize(model.ComputeForces(params, x, v, f, workspace, kernel));
  }
  SetMeshCounters(state);
}

void BM_ForcesOnly(benchmark::State& state) { ForcesWithKernel(state, ForceKernel::kAuto); }
BENCHMARK(BM_ForcesOnly)->Unit(benchmark::kMicrosecond);

// Each instruction-set kernel (0 baseline, 1 AVX2, 2 AVX-512); one the CPU
// lacks is skipped.
void BM_ForcesKernel(benchmark::State& state) {
  constexpr ForceKernel kKernels[] = {ForceKernel::kBaseline, ForceKernel::kAvx2,
                                      ForceKernel::kAvx512};
  const ForceKernel kernel = kKernels[state.range(0)];
  if (!Model::IsAvailable(kernel)) {
    state.SkipWithError(("kernel " + ToString(kernel) + " not available").c_str());
    for (auto _ : state) {
    }
    return;
  }
  state.SetLabel(ToString(kernel));
  ForcesWithKernel(state, kernel);
}
BENCHMARK(BM_ForcesKernel)->DenseRange(0, 2)->Unit(benchmark::kMicrosecond);

// One frame's scoring on the reference scene. Arguments: coverage (0 the
// centre rule: RasterizeMesh, a bit mask, CompareMasks, the score before
// sub-pixel coverage; 1 the score's rule: RasterizeMeshCoverage,
// CompareCoverage) and dented (0 the rest mesh shifted off the pixel grid by
// (1.3, -0.7) px, its sides along rows and columns; 1 the mesh the finger
// has dented by frame 100, as evaluations see it).
void BM_ScoreFrame(benchmark::State& state) {
  const PreparedRecording& prepared = ReferenceScene();
  const bool coverage = state.range(0) != 0;
  std::vector<Vec2> x = prepared.mesh.rest_positions;
  if (state.range(1) != 0) {
    Simulator simulator(prepared.mesh, prepared.scene, SimulationOptions{});
    simulator.Reset(ReferenceParameters());
    for (int f = 0; f < 100; ++f) simulator.Advance();
    x = simulator.positions();
  } else {
    for (Vec2& p : x) p += Vec2(1.3, -0.7);
  }
  Rasterizer rasterizer;
  BitMask mesh_mask(prepared.object_masks[0]);
  std::vector<PixelCoverage> boundary;
  for (auto _ : state) {
    FrameScore score;
    if (coverage) {
      rasterizer.RasterizeMeshCoverage(prepared.mesh, x, mesh_mask, boundary);
      score = CompareCoverage(prepared.object_masks[0], mesh_mask, boundary);
    } else {
      rasterizer.RasterizeMesh(prepared.mesh, x, mesh_mask);
      score = CompareMasks(prepared.object_masks[0], mesh_mask);
    }
    benchmark::DoNotOptimize(score.xor_px);
  }
  state.SetLabel(coverage ? "coverage" : "centre rule");
  state.counters["pixels"] = mesh_mask.width() * mesh_mask.height();
  state.counters["partly_covered"] = static_cast<double>(boundary.size());
}
BENCHMARK(BM_ScoreFrame)
    ->ArgNames({"coverage", "dented"})
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMicrosecond);

// The preparation's registration of a mesh onto an outline (RegisterMesh,
// as tracking does it for each frame): the reference mesh, its rest shape
// shifted by (3, -2) px, onto the outline of frame 100 (the finger's dent).
void BM_RegisterMesh(benchmark::State& state) {
  const PreparedRecording& prepared = ReferenceScene();
  const Mesh& mesh = prepared.mesh;
  const std::vector<uint8_t> free_nodes(mesh.NumNodes(), 0);
  std::vector<Vec2> start = mesh.rest_positions;
  for (Vec2& p : start) p += Vec2(3.0, -2.0);
  for (auto _ : state) {
    const MeshRegistration registered =
        RegisterMesh(mesh, free_nodes, start, mesh.rest_positions, prepared.object_masks[100]);
    benchmark::DoNotOptimize(registered.outline_distance_px);
  }
}
BENCHMARK(BM_RegisterMesh)->Unit(benchmark::kMillisecond);

// Its nearest-point queries, those of the mesh's outline term: frame 100's
// outline sampled every pixel against the mesh's boundary segments (rest
// shape shifted as above), by the grid (grid:1) or by scanning every
// segment (grid:0), the same answers.
void BM_NearestSegment(benchmark::State& state) {
  const PreparedRecording& prepared = ReferenceScene();
  const Mesh& mesh = prepared.mesh;
  std::vector<std::pair<Vec2, Vec2>> segments;
  for (const std::vector<int>& loop : mesh.boundary_loops) {
    for (size_t k = 0; k < loop.size(); ++k) {
      segments.emplace_back(mesh.rest_positions[loop[k]] + Vec2(3.0, -2.0),
                            mesh.rest_positions[loop[(k + 1) % loop.size()]] + Vec2(3.0, -2.0));
    }
  }
  NearestSegment index;
  index.Build(static_cast<int>(segments.size()), [&](int k) { return segments[k]; });
  const std::vector<Vec2> outline = ObjectOutline(prepared.object_masks[100], 0.5);
  std::vector<Vec2> queries;
  for (size_t k = 0; k < outline.size(); ++k) {
    const Vec2 a = outline[k], b = outline[(k + 1) % outline.size()];
    const int pieces = std::max(1, static_cast<int>(std::ceil((b - a).norm())));
    for (int p = 0; p < pieces; ++p) queries.push_back(a + (b - a) * (static_cast<double>(p) / pieces));
  }
  const bool grid = state.range(0) != 0;
  for (auto _ : state) {
    double sum = 0.0;
    for (const Vec2& p : queries) {
      sum += (grid ? index.Nearest(p) : index.NearestByScan(p)).distance2;
    }
    benchmark::DoNotOptimize(sum);
  }
  state.counters["segments"] = index.size();
  state.counters["queries"] = static_cast<double>(queries.size());
}
BENCHMARK(BM_NearestSegment)->ArgName("grid")->DenseRange(0, 1)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace calib::bench

BENCHMARK_MAIN();
