// The model's vectorised force kernels: every instruction-set kernel gives
// the same bits as the others and as a plain scalar loop over the mesh (the
// model's sums before vectorisation), on small and large deformations (the
// atan series and its std::atan2 fallback) and with a collapsed edge.

#include "calib/core/energy_terms.h"
#include "calib/core/mesher.h"
#include "calib/core/model.h"

#include "support/test_support.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace calib {
namespace {

using calib::testing::MakeGridMesh;

ModelParameters Stiff() { return calib::testing::StiffTestParameters(); }

using calib::testing::Jittered;

// The model's sums as one scalar loop per element kind, the order of
// operations of the vectorised kernels: edges (forces[j] += f,
// forces[i] -= f) then triangles, in index order. With scales, each
// element's constants times its scale (Model::ComputeScaledForces, a
// weighted model's ComputeForces; the angle springs by angle_scale where
// given, else by triangle_scale).
std::vector<Vec2> ScalarForces(const Mesh& mesh, const ModelParameters& base,
                               const std::vector<Vec2>& x, const std::vector<Vec2>& v,
                               const std::vector<double>* edge_scale = nullptr,
                               const std::vector<double>* triangle_scale = nullptr,
                               const std::vector<double>* angle_scale = nullptr) {
  ModelParameters p = base;
  using energy_terms_detail::Atan2;
  using energy_terms_detail::Wrap;
  std::vector<Vec2> f(x.size(), Vec2::Zero());
  std::vector<double> inv_sq(mesh.edges.size());
  std::map<std::pair<int, int>, int> edge_index;
  for (int e = 0; e < mesh.NumEdges(); ++e) {
    const auto [i, j] = mesh.edges[e];
    edge_index[{i, j}] = e;
    const Vec2 d = x[j] - x[i];
    const double length_sq = d.squaredNorm();
    if (!(length_sq > 0.0)) continue;
    const double length = std::sqrt(length_sq);
    const double inv_length = 1.0 / length;
    const double inv_rest = 1.0 / mesh.rest_length_px[e];
    inv_sq[e] = inv_length * inv_length;
    if (edge_scale != nullptr) {
      p.k_distance = base.k_distance * (*edge_scale)[e];
      p.k_damping = base.k_damping * (*edge_scale)[e];
    }
    const double strain = (length - mesh.rest_length_px[e]) * inv_rest;
    const double along = -p.k_distance * strain * inv_rest * inv_length -
                         p.k_damping * inv_rest * inv_rest * (v[j] - v[i]).dot(d) * inv_sq[e];
    f[j] += along * d;
    f[i] -= along * d;
  }
  auto edge_of = [&](int from, int to) {
    return edge_index.at({std::min(from, to), std::max(from, to)});
  };
  for (int t = 0; t < mesh.NumTriangles(); ++t) {
    const auto [a, b, c] = mesh.triangles[t];
    if (triangle_scale != nullptr) {
      const std::vector<double>& angle = angle_scale != nullptr ? *angle_scale : *triangle_scale;
      p.k_area = base.k_area * (*triangle_scale)[t];
      p.k_angle = base.k_angle * angle[t];
    }
    const Vec2 ab = x[b] - x[a], bc = x[c] - x[b], ca = x[a] - x[c];
    const double inv_rest_area = 1.0 / mesh.rest_area_px2[t];
    const double rel = (-0.5 * Cross(ab, ca) - mesh.rest_area_px2[t]) * inv_rest_area;
    const double s = -0.5 * p.k_area * rel * inv_rest_area;
    Vec2 f_a = s * Vec2(-bc.y(), bc.x());
    Vec2 f_b = s * Vec2(-ca.y(), ca.x());
    Vec2 f_c = s * Vec2(-ab.y(), ab.x());
    const double i_ab = inv_sq[edge_of(a, b)], i_bc = inv_sq[edge_of(b, c)];
    const double i_ca = inv_sq[edge_of(c, a)];
    if (p.k_angle != 0.0 && i_ab > 0.0 && i_bc > 0.0 && i_ca > 0.0) {
      const double ca0 = std::cos(mesh.rest_angle_rad[t][0]);
      const double sa0 = std::sin(mesh.rest_angle_rad[t][0]);
      const double cb0 = std::cos(mesh.rest_angle_rad[t][1]);
      const double sb0 = std::sin(mesh.rest_angle_rad[t][1]);
      const Vec2 ra(ca0 * ab.x() - sa0 * ab.y(), sa0 * ab.x() + ca0 * ab.y());
      const Vec2 rb(cb0 * bc.x() - sb0 * bc.y(), sb0 * bc.x() + cb0 * bc.y());
      const double d_a = Atan2(-Cross(ra, ca), -ra.dot(ca));
      const double d_b = Atan2(-Cross(rb, ab), -rb.dot(ab));
      const double d_c = Wrap(-(d_a + d_b));
      const Vec2 p_ab = i_ab * Vec2(ab.y(), -ab.x());
      const Vec2 p_bc = i_bc * Vec2(bc.y(), -bc.x());
      const Vec2 p_ca = i_ca * Vec2(ca.y(), -ca.x());
      const double w_a = -p.k_angle * (d_a - d_c);
      const double w_b = -p.k_angle * (d_b - d_c);
      f_a += (w_b - w_a) * p_ab - w_a * p_ca;
      f_b += (w_a - w_b) * p_ab - w_b * p_bc;
      f_c += w_a * p_ca + w_b * p_bc;
    }
    f[a] += f_a;
    f[b] += f_b;
    f[c] += f_c;
  }
  return f;
}

void ExpectSameModelBits(const std::vector<Vec2>& expected, const std::vector<Vec2>& actual,
                    const std::string& what) {
  ASSERT_EQ(expected.size(), actual.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    for (int d = 0; d < 2; ++d) {
      EXPECT_EQ(std::bit_cast<uint64_t>(expected[i][d]), std::bit_cast<uint64_t>(actual[i][d]))
          << what << ": node " << i << " component " << d << ": " << expected[i][d] << " vs "
          << actual[i][d];
    }
  }
}

constexpr ForceKernel kKernels[] = {ForceKernel::kBaseline, ForceKernel::kAvx2,
                                    ForceKernel::kAvx512, ForceKernel::kAuto};

// Deformations from near rest (every angle on the atan series) to large
// (many on std::atan2, some triangles inverted).
TEST(Model, EveryKernelGivesTheBitsOfTheScalarSums) {
  const Mesh mesh = MakeGridMesh(13, 9, 10.0, Vec2(3, 4));
  const Model model(mesh);
  const ModelParameters p = Stiff();
  ForceWorkspace ws = model.MakeWorkspace();
  for (const double amount : {0.01, 0.3, 2.0, 6.0}) {
    const auto x = Jittered(mesh.rest_positions, amount, 7);
    const auto v = Jittered(std::vector<Vec2>(x.size(), Vec2::Zero()), 3.0, 8);
    const std::vector<Vec2> expected = ScalarForces(mesh, p, x, v);
    std::vector<Vec2> f(x.size());
    const double baseline_energy = model.ComputeForces(p, x, v, f, ws, ForceKernel::kBaseline);
    for (const ForceKernel kernel : kKernels) {
      if (!Model::IsAvailable(kernel)) {
        std::cout << "kernel " << ToString(kernel) << " not available on this CPU\n";
        continue;
      }
      const std::string what = ToString(kernel) + " at jitter " + std::to_string(amount);
      std::fill(f.begin(), f.end(), Vec2(1e300, -1e300));  // overwritten, not added to
      const double energy = model.ComputeForces(p, x, v, f, ws, kernel);
      ExpectSameModelBits(expected, f, what);
      EXPECT_EQ(std::bit_cast<uint64_t>(energy), std::bit_cast<uint64_t>(baseline_energy))
          << what << ": energy " << energy << " vs " << baseline_energy;
    }
  }
}

// The scaled stiffnesses (a stiffness field): each element's terms with its
// stiffnesses times its scale, negative scales included, no damping, from
// every kernel with the bits of the scalar sums.
TEST(Model, ScaledStiffnessesGiveTheBitsOfTheScaledScalarSums) {
  const Mesh mesh = MakeGridMesh(13, 9, 10.0, Vec2(3, 4));
  const Model model(mesh);
  ModelParameters p = Stiff();
  ForceWorkspace ws = model.MakeWorkspace();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> scale(-0.9, 0.9);
  std::vector<double> edge_scale(mesh.NumEdges()), triangle_scale(mesh.NumTriangles());
  for (double& e : edge_scale) e = scale(rng);
  for (double& t : triangle_scale) t = scale(rng);
  for (const double amount : {0.01, 2.0, 6.0}) {
    const auto x = Jittered(mesh.rest_positions, amount, 7);
    ModelParameters undamped = p;
    undamped.k_damping = 0.0;
    const std::vector<Vec2> zero(x.size(), Vec2::Zero());
    const std::vector<Vec2> expected =
        ScalarForces(mesh, undamped, x, zero, &edge_scale, &triangle_scale);
    std::vector<Vec2> f(x.size());
    for (const ForceKernel kernel : kKernels) {
      if (!Model::IsAvailable(kernel)) continue;
      const std::string what = ToString(kernel) + " at jitter " + std::to_string(amount);
      std::fill(f.begin(), f.end(), Vec2(1e300, -1e300));  // overwritten, not added to
      model.ComputeScaledForces(p, edge_scale, triangle_scale, x, f, ws, kernel);
      ExpectSameModelBits(expected, f, what);
    }
    // Unit scales: the model's own forces without damping.
    std::vector<Vec2> plain(x.size());
    const double plain_energy = model.ComputeForces(undamped, x, zero, plain, ws);
    const std::vector<double> ones_e(mesh.NumEdges(), 1.0), ones_t(mesh.NumTriangles(), 1.0);
    const double energy = model.ComputeScaledForces(p, ones_e, ones_t, x, f, ws);
    ExpectSameModelBits(plain, f, "unit scales at jitter " + std::to_string(amount));
    EXPECT_EQ(energy, plain_energy);
  }
}

TEST(Model, WeightedElementsGiveTheBitsOfTheWeightedScalarSums) {
  const Mesh mesh = MakeGridMesh(13, 9, 10.0, Vec2(3, 4));
  Model model(mesh);
  const ModelParameters p = Stiff();
  ForceWorkspace ws = model.MakeWorkspace();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> weight(0.2, 3.0);
  std::vector<double> edge_weight(mesh.NumEdges()), triangle_weight(mesh.NumTriangles()),
      angle_weight(mesh.NumTriangles());
  for (double& e : edge_weight) e = weight(rng);
  for (double& t : triangle_weight) t = weight(rng);
  for (double& t : angle_weight) t = weight(rng);
  const auto x = Jittered(mesh.rest_positions, 2.0, 7);
  const auto v = Jittered(std::vector<Vec2>(x.size(), Vec2::Zero()), 3.0, 8);
  std::vector<Vec2> plain(x.size()), f(x.size());
  const double plain_energy = model.ComputeForces(p, x, v, plain, ws);

  model.SetElementWeights(edge_weight, triangle_weight, angle_weight);
  const std::vector<Vec2> expected =
      ScalarForces(mesh, p, x, v, &edge_weight, &triangle_weight, &angle_weight);
  for (const ForceKernel kernel : kKernels) {
    if (!Model::IsAvailable(kernel)) continue;
    std::fill(f.begin(), f.end(), Vec2(1e300, -1e300));
    model.ComputeForces(p, x, v, f, ws, kernel);
    ExpectSameModelBits(expected, f, "weighted, " + ToString(kernel));
  }
  // The weighted energy is what the weighted forces are the gradient of.
  ModelParameters undamped = p;
  undamped.k_damping = 0.0;
  const std::vector<Vec2> zero(x.size(), Vec2::Zero());
  model.ComputeForces(undamped, x, zero, f, ws);
  const double h = 1e-6;
  for (const int node : {0, 17, 60}) {
    for (int axis = 0; axis < 2; ++axis) {
      auto shifted = x;
      shifted[node][axis] += h;
      const double up = model.Energy(undamped, shifted);
      shifted[node][axis] -= 2.0 * h;
      const double down = model.Energy(undamped, shifted);
      EXPECT_NEAR(-(up - down) / (2.0 * h), f[node][axis], 1e-5 * (1.0 + std::abs(f[node][axis])))
          << "node " << node << " axis " << axis;
    }
  }

  // Empty weights: the plain model again, bit for bit.
  model.SetElementWeights({}, {}, {});
  EXPECT_EQ(model.ComputeForces(p, x, v, f, ws), plain_energy);
  ExpectSameModelBits(plain, f, "unweighted again");
}

TEST(Model, BadElementWeightsAreRefusedNamingTheElement) {
  const Mesh mesh = MakeGridMesh(3, 2, 10.0);
  Model model(mesh);
  const std::vector<double> edges(mesh.NumEdges(), 1.0), triangles(mesh.NumTriangles(), 1.0);
  auto expect_refused = [&](const std::vector<double>& e, const std::vector<double>& t,
                            const std::string& needle) {
    try {
      model.SetElementWeights(e, t, triangles);
      ADD_FAILURE() << "accepted; expected a message with '" << needle << "'";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find(needle), std::string::npos) << error.what();
    }
  };
  expect_refused(std::vector<double>(edges.size() - 1, 1.0), triangles, "edge weights for");
  expect_refused(edges, {}, "0 triangle weights for");
  std::vector<double> bad = edges;
  bad[4] = 0.0;
  expect_refused(bad, triangles, "edge 4's edge weight is 0");
  bad = triangles;
  bad[2] = std::nan("");
  expect_refused(edges, bad, "triangle 2's triangle weight is nan");
  try {
    model.SetElementWeights(edges, triangles, bad);
    ADD_FAILURE() << "accepted a NaN angle weight";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("triangle 2's angle weight is nan"), std::string::npos)
        << error.what();
  }
}

TEST(Model, AreaWeightsShareTheAreaAndAreOneInsideTheLattice) {
  const Mesh mesh = MeshPolygon({Vec2(0, 0), Vec2(300, 0), Vec2(300, 200), Vec2(0, 200)}, {});
  const AreaWeights w = ComputeAreaWeights(mesh);
  ASSERT_EQ(w.node.size(), static_cast<size_t>(mesh.NumNodes()));
  ASSERT_EQ(w.edge.size(), static_cast<size_t>(mesh.NumEdges()));
  ASSERT_EQ(w.triangle.size(), static_cast<size_t>(mesh.NumTriangles()));
  EXPECT_EQ(w.angle, std::vector<double>(mesh.NumTriangles(), 1.0));
  const double lattice_triangle = std::sqrt(3.0) / 4.0 * 400.0;
  double nodes = 0.0, edges = 0.0, triangles = 0.0;
  for (double x : w.node) nodes += x;
  for (double x : w.edge) edges += x;
  for (double x : w.triangle) triangles += x;
  const double area = 300.0 * 200.0;
  EXPECT_NEAR(triangles * lattice_triangle, area, 1e-9 * area);
  EXPECT_NEAR(nodes * 2.0 * lattice_triangle, area, 1e-9 * area);
  EXPECT_NEAR(edges * (2.0 / 3.0) * lattice_triangle, area, 1e-9 * area);
  // A node whose six triangles are all lattice triangles weighs 1, and so
  // do they and its edges.
  int interior = 0;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    const Vec2& p = mesh.rest_positions[i];
    if (p.x() < 60 || p.x() > 240 || p.y() < 60 || p.y() > 140) continue;
    ++interior;
    EXPECT_NEAR(w.node[i], 1.0, 1e-9) << "node " << i;
  }
  EXPECT_GT(interior, 10);
  for (int e = 0; e < mesh.NumEdges(); ++e) {
    const Vec2 mid = 0.5 * (mesh.rest_positions[mesh.edges[e][0]] + mesh.rest_positions[mesh.edges[e][1]]);
    if (mid.x() < 60 || mid.x() > 240 || mid.y() < 60 || mid.y() > 140) continue;
    EXPECT_NEAR(w.edge[e], 1.0, 1e-9) << "edge " << e;
  }
}

// Given triangle areas (an object's elements measured on another recording
// of it) weigh as a mesh resting with those areas would; a list of the wrong
// length is refused naming both counts.
TEST(Model, AreaWeightsOfGivenTriangleAreasAreThoseOfAMeshWithThem) {
  const Mesh mesh = MeshPolygon({Vec2(0, 0), Vec2(120, 0), Vec2(120, 80), Vec2(0, 80)}, {});
  Mesh other = mesh;
  for (int t = 0; t < other.NumTriangles(); ++t) other.rest_area_px2[t] *= 1.0 + 0.01 * (t % 7);
  const AreaWeights given = ComputeAreaWeights(mesh, other.rest_area_px2);
  const AreaWeights own = ComputeAreaWeights(other);
  EXPECT_EQ(given.node, own.node);
  EXPECT_EQ(given.edge, own.edge);
  EXPECT_EQ(given.triangle, own.triangle);
  EXPECT_EQ(given.angle, own.angle);
  EXPECT_NE(given.node, ComputeAreaWeights(mesh).node);
  const std::vector<double> short_list(mesh.NumTriangles() - 1, 1.0);
  try {
    ComputeAreaWeights(mesh, short_list);
    ADD_FAILURE() << "a short list of areas was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(fmt::format("{} triangle areas for a mesh of {} triangles",
                                                     short_list.size(), mesh.NumTriangles())),
              std::string::npos)
        << e.what();
  }
}

// A collapsed edge: its spring has no direction and its triangles no angles.
TEST(Model, KernelsAgreeOnACollapsedEdge) {
  const Mesh mesh = MakeGridMesh(4, 3, 10.0);
  const Model model(mesh);
  const ModelParameters p = Stiff();
  auto x = Jittered(mesh.rest_positions, 1.0, 3);
  const auto [i, j] = mesh.edges[5];
  x[j] = x[i];
  const auto v = Jittered(std::vector<Vec2>(x.size(), Vec2::Zero()), 1.0, 4);
  const std::vector<Vec2> expected = ScalarForces(mesh, p, x, v);
  ForceWorkspace ws = model.MakeWorkspace();
  std::vector<Vec2> f(x.size());
  const double baseline_energy = model.ComputeForces(p, x, v, f, ws, ForceKernel::kBaseline);
  EXPECT_TRUE(std::isfinite(baseline_energy)) << baseline_energy;
  for (const ForceKernel kernel : kKernels) {
    if (!Model::IsAvailable(kernel)) continue;
    const double energy = model.ComputeForces(p, x, v, f, ws, kernel);
    ExpectSameModelBits(expected, f, ToString(kernel));
    EXPECT_EQ(std::bit_cast<uint64_t>(energy), std::bit_cast<uint64_t>(baseline_energy))
        << ToString(kernel);
  }
}

TEST(Model, KernelNamesAndAvailability) {
  EXPECT_EQ(ToString(ForceKernel::kAuto), "auto");
  EXPECT_EQ(ToString(ForceKernel::kBaseline), "baseline");
  EXPECT_EQ(ToString(ForceKernel::kAvx2), "avx2");
  EXPECT_EQ(ToString(ForceKernel::kAvx512), "avx512");
  EXPECT_TRUE(Model::IsAvailable(ForceKernel::kAuto));
  EXPECT_TRUE(Model::IsAvailable(ForceKernel::kBaseline));
}

}  // namespace
}  // namespace calib
