// The first-order step implicit in the springs (implicit_step.h): its
// stiffness against differences of the model's forces, the rigid motions
// it leaves free (and the turn it does not make at a deformed shape),
// agreement with the explicit step for small steps, the same equilibrium,
// and stability where the explicit step fails.

#include "calib/core/constraints.h"
#include "calib/core/effects.h"
#include "calib/core/implicit_assembly.h"
#include "calib/core/implicit_step.h"
#include "calib/core/ldlt_solve.h"
#include "calib/core/simulator.h"

#include "support/test_support.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

namespace calib {
namespace {

using calib::testing::MakeGridMesh;
using calib::testing::OneDiscScene;

ModelParameters Mixed() {
  ModelParameters p = calib::testing::StiffTestParameters();
  p.k_distance = 50.0;
  p.k_area = 20.0;
  p.k_angle = 5.0;
  p.k_damping = 0.5;
  return p;
}

Eigen::VectorXd Flat(const std::vector<Vec2>& field) {
  Eigen::VectorXd v(2 * field.size());
  for (size_t i = 0; i < field.size(); ++i) v.segment<2>(2 * i) = field[i];
  return v;
}

std::vector<Vec2> RandomField(size_t n, double amount, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<Vec2> field(n);
  for (Vec2& p : field) p = Vec2(u(rng), u(rng));
  return field;
}

TEST(ImplicitStep, StiffnessIsTheForcesDerivativeAtRest) {
  const Mesh mesh = MakeGridMesh(5, 3, 10.0, Vec2(40, 60));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  const ImplicitFirstOrderStep step(model, movable);
  const ModelParameters p = Mixed();
  const Eigen::SparseMatrix<double> k = step.Stiffness(p);
  ASSERT_EQ(k.rows(), 2 * mesh.NumNodes());
  EXPECT_LT((Eigen::MatrixXd(k) - Eigen::MatrixXd(k).transpose()).norm(), 1e-9 * k.norm());

  // K u = -(F(X + e u) - F(X - e u)) / 2e for a random direction u (the
  // springs without damping, at zero velocity).
  ModelParameters springs = p;
  springs.k_damping = 0.0;
  const std::vector<Vec2> u = RandomField(mesh.NumNodes(), 1.0, 7);
  const double e = 1e-4;
  std::vector<Vec2> plus(mesh.rest_positions), minus(mesh.rest_positions);
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    plus[i] += e * u[i];
    minus[i] -= e * u[i];
  }
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  std::vector<Vec2> f_plus(mesh.NumNodes()), f_minus(mesh.NumNodes());
  model.ComputeForces(springs, plus, zero, f_plus);
  model.ComputeForces(springs, minus, zero, f_minus);
  const Eigen::VectorXd expected = (Flat(f_minus) - Flat(f_plus)) / (2.0 * e);
  const Eigen::VectorXd got = k * Flat(u);
  EXPECT_LT((got - expected).norm(), 1e-6 * expected.norm()) << "|K u| = " << got.norm();
}

// A stiffness field over the rest shape (uneven_stiffness, which declares
// rest_stiffness), its gradient towards +x at 30 deg.
std::unique_ptr<EffectTerm> UnevenField(const Mesh& mesh, const ModelParameters& base,
                                        double gradient) {
  std::unique_ptr<EffectTerm> effect = MakeEffect("uneven_stiffness");
  EXPECT_TRUE(effect->hooks().rest_stiffness);
  effect->Bind(mesh);
  effect->Configure({{"uneven_gradient", gradient}, {"uneven_angle_deg", 30.0}}, base);
  return effect;
}

TEST(ImplicitStep, AnEffectsStiffnessIsItsForcesDerivativeAtRest) {
  const Mesh mesh = MakeGridMesh(6, 4, 10.0, Vec2(40, 60));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  ImplicitFirstOrderStep step(model, movable);
  const ModelParameters p = Mixed();
  const std::unique_ptr<EffectTerm> field = UnevenField(mesh, p, 0.8);
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  const ImplicitFirstOrderStep::ExtraForces forces = [&](std::span<const Vec2> x,
                                                        std::span<Vec2> f) {
    field->AddForces(x, zero, f, nullptr);
  };
  std::string error;
  ASSERT_TRUE(step.Configure(p, 1.0 / 300.0, &forces, &error)) << error;
  const Eigen::SparseMatrix<double> k = step.ExtraStiffness();
  ASSERT_GT(k.norm(), 0.0);
  EXPECT_LT((Eigen::MatrixXd(k) - Eigen::MatrixXd(k).transpose()).norm(), 1e-9 * k.norm());
  // K u = -(F(X + e u) - F(X - e u)) / 2e of the effect's forces, for
  // random directions u: every column, probed in groups, is its own.
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const std::vector<Vec2> u = RandomField(mesh.NumNodes(), 1.0, seed);
    const double e = 1e-4;
    std::vector<Vec2> plus(mesh.rest_positions), minus(mesh.rest_positions);
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      plus[i] += e * u[i];
      minus[i] -= e * u[i];
    }
    std::vector<Vec2> f_plus(mesh.NumNodes(), Vec2::Zero()), f_minus(mesh.NumNodes(), Vec2::Zero());
    forces(plus, f_plus);
    forces(minus, f_minus);
    const Eigen::VectorXd expected = (Flat(f_minus) - Flat(f_plus)) / (2.0 * e);
    EXPECT_LT((k * Flat(u) - expected).norm(), 1e-6 * expected.norm()) << "seed " << seed;
  }
  // Configured without it, the step holds no extra stiffness.
  ASSERT_TRUE(step.Configure(p, 1.0 / 300.0, &error)) << error;
  EXPECT_EQ(step.ExtraStiffness().nonZeros(), 0);
}

TEST(ImplicitStep, AStiffFieldInTheMatrixDoesNotOvershoot) {
  // A stiff mesh (K >> m / h), deformed, relaxed by one step with the
  // field's forces in F. With the field's stiffness in the matrix the step
  // lands near the rest shape; with it left explicit the stiff side
  // overshoots by the field's share (up to 0.9 of its deformation).
  const Mesh mesh = MakeGridMesh(6, 4, 10.0, Vec2(40, 60));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  ModelParameters p = Mixed();
  p.k_distance *= 1e5;
  p.k_area *= 1e5;
  p.k_angle *= 1e5;
  p.k_damping = 0.0;
  const std::unique_ptr<EffectTerm> field = UnevenField(mesh, p, 0.9);
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  const ImplicitFirstOrderStep::ExtraForces forces = [&](std::span<const Vec2> x,
                                                        std::span<Vec2> f) {
    field->AddForces(x, zero, f, nullptr);
  };
  const std::vector<Vec2> x0 = calib::testing::Jittered(mesh.rest_positions, 0.05, 5);
  const auto residual_force = [&](const std::vector<Vec2>& x) {
    std::vector<Vec2> f(mesh.NumNodes());
    model.ComputeForces(p, x, zero, f);
    forces(x, f);
    return Flat(f).norm();
  };
  const auto relaxed = [&](const ImplicitFirstOrderStep::ExtraForces* extra) {
    ImplicitFirstOrderStep step(model, movable);
    std::string error;
    EXPECT_TRUE(step.Configure(p, 1.0 / 300.0, extra, &error)) << error;
    std::vector<Vec2> f(mesh.NumNodes());
    model.ComputeForces(p, x0, zero, f);
    forces(x0, f);
    std::vector<Vec2> x = x0;
    step.Step(f, x);
    return residual_force(x) / residual_force(x0);
  };
  const double with_field = relaxed(&forces);
  const double explicit_field = relaxed(nullptr);
  EXPECT_LT(with_field, 0.05);
  EXPECT_GT(explicit_field, 0.3) << "with the field in the matrix: " << with_field;
}

// Strain stiffening (shape_stiffness) with coefficient k3 on `mesh`.
std::unique_ptr<EffectTerm> Stiffening(const Mesh& mesh, const ModelParameters& base, double k3) {
  std::unique_ptr<EffectTerm> effect = MakeEffect("strain_stiffening");
  EXPECT_TRUE(effect->hooks().shape_stiffness);
  effect->Bind(mesh);
  effect->Configure({{"stiffening_k3", k3}}, base);
  return effect;
}

// The edge stiffness an effect reports, assembled densely over 2N
// coordinates.
class DenseEdgeStiffness final : public EdgeStiffnessSink {
 public:
  explicit DenseEdgeStiffness(const Mesh& mesh)
      : mesh_(mesh), k_(Eigen::MatrixXd::Zero(2 * mesh.NumNodes(), 2 * mesh.NumNodes())) {}
  void AddEdgeStiffness(int edge, double k, const Vec2& u) override {
    const auto [i, j] = mesh_.edges[edge];
    const Eigen::Matrix2d block = k * u * u.transpose();
    k_.block<2, 2>(2 * i, 2 * i) += block;
    k_.block<2, 2>(2 * j, 2 * j) += block;
    k_.block<2, 2>(2 * i, 2 * j) -= block;
    k_.block<2, 2>(2 * j, 2 * i) -= block;
  }
  const Eigen::MatrixXd& matrix() const { return k_; }

 private:
  const Mesh& mesh_;
  Eigen::MatrixXd k_;
};

// A grid squeezed by 25 % along y and jittered: every edge strained.
std::vector<Vec2> Squeezed(const Mesh& mesh) {
  std::vector<Vec2> x = calib::testing::Jittered(mesh.rest_positions, 0.5, 11);
  for (Vec2& p : x) p.y() = 60.0 + 0.75 * (p.y() - 60.0);
  return x;
}

TEST(ImplicitStep, AStiffeningSpringsShapeStiffnessIsItsForcesAxialDerivative) {
  // The axial stiffness the effect reports, plus each spring's geometric
  // stiffness across its axis (tension / length), is the Jacobian of its
  // forces at a strained shape, by central differences.
  const Mesh mesh = MakeGridMesh(5, 4, 10.0, Vec2(40, 60));
  const double k3 = 300.0;
  const std::unique_ptr<EffectTerm> effect = Stiffening(mesh, Mixed(), k3);
  const std::vector<Vec2> x = Squeezed(mesh);
  DenseEdgeStiffness axial(mesh);
  effect->AddShapeStiffness(x, axial);
  ASSERT_GT(axial.matrix().norm(), 0.0);
  Eigen::MatrixXd geometric = Eigen::MatrixXd::Zero(2 * mesh.NumNodes(), 2 * mesh.NumNodes());
  for (int e = 0; e < mesh.NumEdges(); ++e) {
    const auto [i, j] = mesh.edges[e];
    const Vec2 d = x[j] - x[i];
    const double length = d.norm(), rest = mesh.rest_length_px[e];
    const double strain = length / rest - 1.0;
    const double tension = k3 * strain * strain * strain / rest;
    const Vec2 u = d / length;
    const Eigen::Matrix2d block = (tension / length) * (Eigen::Matrix2d::Identity() - u * u.transpose());
    geometric.block<2, 2>(2 * i, 2 * i) += block;
    geometric.block<2, 2>(2 * j, 2 * j) += block;
    geometric.block<2, 2>(2 * i, 2 * j) -= block;
    geometric.block<2, 2>(2 * j, 2 * i) -= block;
  }
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  Eigen::MatrixXd jacobian(2 * mesh.NumNodes(), 2 * mesh.NumNodes());
  const double e = 1e-5;
  for (int c = 0; c < 2 * mesh.NumNodes(); ++c) {
    std::vector<Vec2> plus(x), minus(x);
    plus[c / 2][c % 2] += e;
    minus[c / 2][c % 2] -= e;
    std::vector<Vec2> f_plus(mesh.NumNodes(), Vec2::Zero()), f_minus(mesh.NumNodes(), Vec2::Zero());
    effect->AddForces(plus, zero, f_plus, nullptr);
    effect->AddForces(minus, zero, f_minus, nullptr);
    jacobian.col(c) = (Flat(f_minus) - Flat(f_plus)) / (2.0 * e);
  }
  EXPECT_LT((axial.matrix() + geometric - jacobian).norm(), 1e-6 * jacobian.norm());
  // Positive semi-definite (what keeps the step's matrix definite).
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(axial.matrix()).eigenvalues().minCoeff(),
            -1e-9 * axial.matrix().norm());
  // At rest the springs have no stiffness of their own.
  DenseEdgeStiffness at_rest(mesh);
  effect->AddShapeStiffness(mesh.rest_positions, at_rest);
  EXPECT_EQ(at_rest.matrix().norm(), 0.0);
}

// A squeezed mesh whose stiffening springs dominate its base springs,
// relaxed by one step with every force in F. With the springs' stiffness at
// this shape in the matrix the step is a Newton step towards the rest
// shape; without it the stiffening force is explicit and overshoots.
TEST(ImplicitStep, AStiffenedMeshRelaxesWhenItsSpringsAreReLinearisedAtItsShape) {
  const Mesh mesh = MakeGridMesh(6, 4, 10.0, Vec2(40, 60));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  const ModelParameters p = [] {
    ModelParameters undamped = Mixed();
    undamped.k_damping = 0.0;
    return undamped;
  }();
  const std::unique_ptr<EffectTerm> effect = Stiffening(mesh, p, 1e6);
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  const std::vector<Vec2> x0 = Squeezed(mesh);
  const auto forces = [&](const std::vector<Vec2>& x) {
    std::vector<Vec2> f(mesh.NumNodes());
    model.ComputeForces(p, x, zero, f);
    effect->AddForces(x, zero, f, nullptr);
    return f;
  };
  const auto relaxed = [&](bool relinearise) {
    ImplicitFirstOrderStep step(model, movable, true);
    std::string error;
    EXPECT_TRUE(step.Configure(p, 1.0 / 300.0, &error)) << error;
    if (relinearise) {
      step.BeginShapeStiffness();
      effect->AddShapeStiffness(x0, step);
      EXPECT_TRUE(step.FinishShapeStiffness(&error)) << error;
    }
    std::vector<Vec2> x = x0;
    step.Step(forces(x0), x);
    return Flat(forces(x)).norm() / Flat(forces(x0)).norm();
  };
  const double relinearised = relaxed(true);
  const double explicit_springs = relaxed(false);
  EXPECT_LT(relinearised, 0.5);
  EXPECT_GT(explicit_springs, 10.0) << "re-linearised: " << relinearised;

  // Back to the configured matrix, the step is the plain one (to rounding:
  // the re-linearised matrix is factorised from its upper triangle).
  ImplicitFirstOrderStep plain(model, movable, true), again(model, movable, true);
  std::string error;
  ASSERT_TRUE(plain.Configure(p, 1.0 / 300.0, &error)) << error;
  ASSERT_TRUE(again.Configure(p, 1.0 / 300.0, &error)) << error;
  again.BeginShapeStiffness();
  effect->AddShapeStiffness(x0, again);
  ASSERT_TRUE(again.FinishShapeStiffness(&error)) << error;
  again.BeginShapeStiffness();
  ASSERT_TRUE(again.FinishShapeStiffness(&error)) << error;
  std::vector<Vec2> x_plain = x0, x_again = x0;
  plain.Step(forces(x0), x_plain);
  again.Step(forces(x0), x_again);
  double largest_move = 0.0, largest_difference = 0.0;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    largest_move = std::max(largest_move, (x_plain[i] - x0[i]).norm());
    largest_difference = std::max(largest_difference, (x_plain[i] - x_again[i]).norm());
  }
  ASSERT_GT(largest_move, 0.0);
  EXPECT_LT(largest_difference, 1e-9 * largest_move);
}

// The re-linearised matrix is refactorised only where it moved by more than
// the shape tolerance from the one factorised last; a kept factor is that
// matrix's, and a mesh relaxed with kept factors reaches the same
// equilibrium as with a factor at every frame.
TEST(ImplicitStep, KeepsItsFactorWhileTheShapeStiffnessMovesLittle) {
  const Mesh mesh = MakeGridMesh(6, 4, 10.0, Vec2(40, 60));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  const ModelParameters p = Mixed();
  // Springs that stiffen as far as a step with a frame-old stiffness stays
  // stable through a relaxation from the squeeze (at 1e6 the stretch that
  // the squeeze's release makes across it outruns a frame-old matrix).
  const std::unique_ptr<EffectTerm> effect = Stiffening(mesh, p, 1e5);
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  const auto forces = [&](const std::vector<Vec2>& x) {
    std::vector<Vec2> f(mesh.NumNodes());
    model.ComputeForces(p, x, zero, f);
    effect->AddForces(x, zero, f, nullptr);
    return f;
  };
  const auto at = [&](ImplicitFirstOrderStep& step, const std::vector<Vec2>& x) {
    step.BeginShapeStiffness();
    effect->AddShapeStiffness(x, step);
    std::string error;
    EXPECT_TRUE(step.FinishShapeStiffness(&error)) << error;
  };
  const auto stepped = [&](ImplicitFirstOrderStep& step, const std::vector<Vec2>& x0) {
    std::vector<Vec2> x = x0;
    step.Step(forces(x0), x);
    return x;
  };
  const double h = 1.0 / 300.0;
  std::string error;
  ImplicitFirstOrderStep step(model, movable, true);
  EXPECT_EQ(step.shape_tolerance(), ImplicitFirstOrderStep::kDefaultShapeTolerance);
  ASSERT_TRUE(step.Configure(p, h, &error)) << error;

  // At rest the springs add nothing: the configured factor stays.
  at(step, mesh.rest_positions);
  EXPECT_EQ(step.shape_factorizations(), 0);
  // Squeezed, they dominate: refactorised, and the same shape again keeps
  // that factor, whose step is a freshly factorised step's bit for bit.
  const std::vector<Vec2> squeezed = Squeezed(mesh);
  at(step, squeezed);
  EXPECT_EQ(step.shape_factorizations(), 1);
  at(step, squeezed);
  EXPECT_EQ(step.shape_factorizations(), 1);
  ImplicitFirstOrderStep fresh(model, movable, true);
  ASSERT_TRUE(fresh.Configure(p, h, &error)) << error;
  fresh.set_shape_tolerance(0.0);
  at(fresh, squeezed);
  ASSERT_EQ(fresh.shape_factorizations(), 1);
  EXPECT_EQ(Flat(stepped(step, squeezed)), Flat(stepped(fresh, squeezed)));

  // A shape a hundredth of a pixel away: kept at the default tolerance,
  // refactorised at 0.
  std::vector<Vec2> nudged = squeezed;
  for (Vec2& q : nudged) q.x() += 1e-4 * (q.y() - 60.0) / 30.0;
  at(step, nudged);
  EXPECT_EQ(step.shape_factorizations(), 1);
  at(fresh, nudged);
  EXPECT_EQ(fresh.shape_factorizations(), 2);
  // A new candidate starts from its configured matrix.
  ASSERT_TRUE(step.Configure(p, h, &error)) << error;
  EXPECT_EQ(step.shape_factorizations(), 0);

  // Relaxed from the squeeze over 40 frames of 10 steps, re-linearised
  // every frame: both come as close to the rest shape's equilibrium and to
  // each other, the kept factors with far fewer factorisations.
  const auto relax = [&](double tolerance, int* factorizations) {
    ImplicitFirstOrderStep s(model, movable, true);
    s.set_shape_tolerance(tolerance);
    std::string e;
    EXPECT_TRUE(s.Configure(p, h, &e)) << e;
    std::vector<Vec2> x = squeezed;
    for (int frame = 0; frame < 40; ++frame) {
      at(s, x);
      for (int k = 0; k < 10; ++k) x = stepped(s, x);
    }
    *factorizations = s.shape_factorizations();
    return x;
  };
  int every = 0, kept = 0;
  const std::vector<Vec2> x_every = relax(0.0, &every);
  const std::vector<Vec2> x_kept = relax(ImplicitFirstOrderStep::kDefaultShapeTolerance, &kept);
  EXPECT_EQ(every, 40);
  EXPECT_LT(kept, every / 2);
  EXPECT_LT(Flat(forces(x_every)).norm(), 1e-4 * Flat(forces(squeezed)).norm());
  EXPECT_LT(Flat(forces(x_kept)).norm(), 1e-4 * Flat(forces(squeezed)).norm());
  double largest_difference = 0.0;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    largest_difference = std::max(largest_difference, (x_every[i] - x_kept[i]).norm());
  }
  EXPECT_LT(largest_difference, 1e-3);
}

TEST(ImplicitStep, RigidMotionsAreFreeAndEveryOtherMotionIsResisted) {
  const Mesh mesh = MakeGridMesh(5, 3, 10.0, Vec2(40, 60));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  const ImplicitFirstOrderStep step(model, movable);
  const Eigen::SparseMatrix<double> k = step.Stiffness(Mixed());
  Vec2 centre = Vec2::Zero();
  for (const Vec2& p : mesh.rest_positions) centre += p / mesh.NumNodes();
  std::vector<Vec2> along_x(mesh.NumNodes(), Vec2(1, 0)), turn(mesh.NumNodes());
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    const Vec2 r = mesh.rest_positions[i] - centre;
    turn[i] = Vec2(-r.y(), r.x());
  }
  const double scale = k.norm();
  EXPECT_LT((k * Flat(along_x)).norm(), 1e-9 * scale * Flat(along_x).norm());
  EXPECT_LT((k * Flat(turn)).norm(), 1e-9 * scale * Flat(turn).norm());
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    const Eigen::VectorXd u = Flat(RandomField(mesh.NumNodes(), 1.0, seed));
    EXPECT_GT(u.dot(k * u), 0.0) << "seed " << seed;
  }
}

TEST(ImplicitStep, AgreesWithTheExplicitStepToFirstOrderInTheStep) {
  // One step from a deformed state: x + (m/h + K0)^-1 F against x + (h/m) F.
  // Their difference relative to the step shrinks in proportion to h.
  const Mesh mesh = MakeGridMesh(5, 3, 10.0, Vec2(40, 60));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  ImplicitFirstOrderStep step(model, movable);
  ModelParameters p = Mixed();
  p.k_damping = 0.0;
  const std::vector<Vec2> x0 = calib::testing::Jittered(mesh.rest_positions, 0.5, 3);
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  std::vector<Vec2> f(mesh.NumNodes());
  model.ComputeForces(p, x0, zero, f);
  double previous_ratio = 0.0;
  for (double h : {1e-3, 1e-4, 1e-5}) {
    std::string error;
    ASSERT_TRUE(step.Configure(p, h, &error)) << error;
    std::vector<Vec2> x = x0;
    step.Step(f, x);
    double difference = 0.0, explicit_step = 0.0;
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      const Vec2 explicit_move = (h / p.mass) * f[i];
      difference += (x[i] - x0[i] - explicit_move).squaredNorm();
      explicit_step += explicit_move.squaredNorm();
    }
    const double ratio = std::sqrt(difference / explicit_step);
    if (previous_ratio > 0.0) {
      EXPECT_NEAR(ratio / previous_ratio, 0.1, 0.02) << "h = " << h;
    }
    previous_ratio = ratio;
  }
  EXPECT_LT(previous_ratio, 1e-3);
}

TEST(ImplicitStep, StiffSpringsDoNotTurnAFreeBody) {
  // The springs' forces at a deformed shape have no torque about its
  // centroid, so a step on them alone neither moves nor turns the body
  // there (the explicit step's (h / m) F does neither either), however stiff
  // the springs: their torque about the rest shape is not the body's.
  const Mesh mesh = MakeGridMesh(6, 3, 10.0, Vec2(100, 100));
  const Model model(mesh);
  const std::vector<double> movable(mesh.NumNodes(), 1.0);
  ImplicitFirstOrderStep step(model, movable);
  ModelParameters p = Mixed();
  p.k_distance *= 1e4;
  p.k_area *= 1e4;
  p.k_angle *= 1e4;
  p.k_damping = 0.0;
  std::string error;
  ASSERT_TRUE(step.Configure(p, 1.0 / 300.0, &error)) << error;
  const std::vector<Vec2> x0 = calib::testing::Jittered(mesh.rest_positions, 2.0, 11);
  const std::vector<Vec2> zero(mesh.NumNodes(), Vec2::Zero());
  std::vector<Vec2> f(mesh.NumNodes());
  model.ComputeForces(p, x0, zero, f);
  std::vector<Vec2> x = x0;
  step.Step(f, x);
  Vec2 centre = Vec2::Zero(), shift = Vec2::Zero();
  for (const Vec2& q : x0) centre += q / mesh.NumNodes();
  double turn = 0.0, turn_norm_sq = 0.0, move_sq = 0.0;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    const Vec2 dx = x[i] - x0[i], r = x0[i] - centre, t(-r.y(), r.x());
    shift += dx;
    turn += dx.dot(t);
    turn_norm_sq += t.squaredNorm();
    move_sq += dx.squaredNorm();
  }
  ASSERT_GT(move_sq, 0.0) << "the step should move the deformed nodes";
  const double move = std::sqrt(move_sq);
  EXPECT_LT(shift.norm(), 1e-9 * move * mesh.NumNodes());
  EXPECT_LT(std::abs(turn) / std::sqrt(turn_norm_sq), 1e-9 * move)
      << "turn about the centroid, relative to the step";
}

// A strip clamped at its top row, pulled at its bottom corner by a constant
// force (the sensor on a disc far from the mesh, nearest to that corner).
Scene PulledStrip(const Mesh& mesh, int frames) {
  Vec2 corner = mesh.rest_positions[0];
  for (const Vec2& p : mesh.rest_positions) {
    if (p.y() > corner.y() || (p.y() == corner.y() && p.x() > corner.x())) corner = p;
  }
  Scene scene = OneDiscScene(
      frames, 30.0, [&](int) { return Disc{corner + Vec2(60, 60), 1.0}; },
      [](int) { return Vec2(3.0, 1.0); });
  scene.clamps.push_back({0.0, 0.0, 1000.0, 1.0});
  return scene;
}

TEST(ImplicitStep, ReachesTheExplicitStepsEquilibrium) {
  const Mesh mesh = MakeGridMesh(3, 6, 10.0, Vec2(20, 0));
  const Scene scene = PulledStrip(mesh, 200);
  ModelParameters p = Mixed();
  SimulationOptions explicit_options;
  explicit_options.substeps = 40;  // stable and settled with these stiffnesses
  SimulationOptions implicit_options;
  implicit_options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator explicit_sim(mesh, scene, explicit_options), implicit_sim(mesh, scene, implicit_options);
  explicit_sim.Reset(p);
  implicit_sim.Reset(p);
  while (explicit_sim.Advance()) {
  }
  while (implicit_sim.Advance()) {
  }
  ASSERT_EQ(explicit_sim.status(), SimulationStatus::kFinished) << explicit_sim.failure_reason();
  ASSERT_EQ(implicit_sim.status(), SimulationStatus::kFinished) << implicit_sim.failure_reason();
  double deflection = 0.0, difference = 0.0;
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    EXPECT_EQ(implicit_sim.positions()[i] == mesh.rest_positions[i],
              implicit_sim.clamped()[i] != 0)
        << "node " << i << ": clamped nodes stay, the others move";
    deflection = std::max(deflection, (explicit_sim.positions()[i] - mesh.rest_positions[i]).norm());
    difference = std::max(difference, (implicit_sim.positions()[i] - explicit_sim.positions()[i]).norm());
  }
  EXPECT_GT(deflection, 1.0) << "the pull should bend the strip";
  EXPECT_LT(difference, 1e-3 * deflection);
}

TEST(ImplicitStep, StableWhereTheExplicitStepFails) {
  // A finger pushes a patch of springs 1000 times stiffer than the explicit
  // step bears at 10 substeps.
  const Mesh mesh = MakeGridMesh(10, 4, 10.0, Vec2(100, 100));
  Scene scene = OneDiscScene(40, 30.0, [](int f) {
    return Disc{Vec2(92.0 + std::min(1.0, f / 24.0) * 25.0, 120.0), 8.0};
  });
  ModelParameters p = Mixed();
  p.k_distance *= 1000.0;
  p.k_area *= 1000.0;
  p.k_angle *= 1000.0;
  Simulator explicit_sim(mesh, scene, {});
  explicit_sim.Reset(p);
  while (explicit_sim.Advance()) {
  }
  EXPECT_EQ(explicit_sim.status(), SimulationStatus::kFailed);

  SimulationOptions options;
  options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator sim(mesh, scene, options);
  sim.Reset(p);
  double moved = 0.0;
  const auto check = [&](int s) {
    ASSERT_EQ(FindNodeInsideDisc(sim.obstacles(), sim.positions(), 1e-9), -1)
        << "frame " << sim.frame() << " substep " << s;
    ASSERT_EQ(FindInvertedTriangle(mesh, sim.positions()), -1);
  };
  while (sim.Advance(check)) {
  }
  ASSERT_EQ(sim.status(), SimulationStatus::kFinished) << sim.failure_reason();
  // Stiff: the patch moves as a body ahead of the finger, barely deformed.
  double stretch = 0.0;
  for (int e = 0; e < mesh.NumEdges(); ++e) {
    const auto [a, b] = mesh.edges[e];
    const double length = (sim.positions()[a] - sim.positions()[b]).norm();
    stretch = std::max(stretch, std::abs(length / mesh.rest_length_px[e] - 1.0));
  }
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    moved = std::max(moved, sim.positions()[i].x() - mesh.rest_positions[i].x());
  }
  EXPECT_GT(moved, 10.0);
  EXPECT_LT(stretch, 0.05);
}

TEST(ImplicitStep, UniformForceTranslatesAsTheExplicitStep) {
  // Spread evenly (translation share 1), the push moves an unclamped mesh
  // rigidly by (h / m) F / N per substep under either step.
  const Mesh mesh = MakeGridMesh(6, 3, 10.0, Vec2(100, 100));
  const Scene scene = OneDiscScene(
      5, 30.0, [](int) { return Disc{Vec2(0.0, 0.0), 1.0}; }, [](int) { return Vec2(2.0, -1.0); });
  ModelParameters p = Mixed();
  p.translation = 1.0;
  SimulationOptions implicit_options;
  implicit_options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator explicit_sim(mesh, scene, {}), implicit_sim(mesh, scene, implicit_options);
  explicit_sim.Reset(p);
  implicit_sim.Reset(p);
  while (explicit_sim.Advance() && implicit_sim.Advance()) {
  }
  const Vec2 expected_shift = 4 * scene.frame_time_s * Vec2(2.0, -1.0) / (p.mass * mesh.NumNodes());
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    EXPECT_LT((explicit_sim.positions()[i] - mesh.rest_positions[i] - expected_shift).norm(), 1e-9);
    EXPECT_LT((implicit_sim.positions()[i] - mesh.rest_positions[i] - expected_shift).norm(), 1e-9);
  }
}

TEST(ImplicitStep, SameInputSameBits) {
  const Mesh mesh = MakeGridMesh(8, 4, 10.0, Vec2(100, 100));
  const Scene scene = OneDiscScene(30, 30.0, [](int f) {
    return Disc{Vec2(92.0 + f, 120.0), 8.0};
  });
  SimulationOptions options;
  options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator a(mesh, scene, options), b(mesh, scene, options);
  a.Reset(Mixed());
  b.Reset(Mixed());
  while (a.Advance()) {
  }
  while (b.Advance()) {
  }
  ASSERT_EQ(a.status(), SimulationStatus::kFinished) << a.failure_reason();
  for (int i = 0; i < mesh.NumNodes(); ++i) {
    EXPECT_EQ(a.positions()[i].x(), b.positions()[i].x());
    EXPECT_EQ(a.positions()[i].y(), b.positions()[i].y());
  }
  // A reset simulator repeats the run exactly.
  const std::vector<Vec2> first = a.positions();
  a.Reset(Mixed());
  while (a.Advance()) {
  }
  for (int i = 0; i < mesh.NumNodes(); ++i) EXPECT_EQ(a.positions()[i], first[i]);
}

// Contacts in the step: a stiff grid (7 x 3 nodes) pressed against a disc
// at the middle of its left side by a uniform force, every node a candidate
// contact (as the simulator gathers them).
struct PressedGrid {
  Mesh mesh = MakeGridMesh(6, 2, 10.0, Vec2(100, 100));
  Model model{mesh};
  std::vector<double> movable = std::vector<double>(mesh.NumNodes(), 1.0);
  ImplicitFirstOrderStep step{model, movable};
  Disc disc{Vec2(92.0, 110.0), 8.0};  // touches node (100, 110)
  std::vector<Vec2> x = mesh.rest_positions;

  PressedGrid() {
    ModelParameters p = Mixed();
    p.k_distance *= 1e3;
    p.k_area *= 1e3;
    p.k_angle *= 1e3;
    std::string error;
    EXPECT_TRUE(step.Configure(p, 1.0 / 300.0, &error)) << error;
  }

  std::vector<StepContact> Contacts(const Vec2& disc_step) const {
    std::vector<StepContact> contacts;
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      const Vec2 d = x[i] - disc.centre - disc_step;
      StepContact c;
      c.nodes = {i, -1};
      c.normal = d.normalized();
      c.gap = disc.radius_px - d.norm();
      c.obstacle_step = disc_step;
      contacts.push_back(c);
    }
    return contacts;
  }

  int NodeAt(const Vec2& p) const {
    for (int i = 0; i < mesh.NumNodes(); ++i) {
      if ((x[i] - p).norm() < 1e-9) return i;
    }
    ADD_FAILURE() << "no node at " << p.transpose();
    return 0;
  }

  // The step for a uniform force per node.
  std::vector<Vec2> Moved(const Vec2& force, std::span<const StepContact> contacts,
                          double friction) {
    const std::vector<Vec2> f(mesh.NumNodes(), force);
    std::vector<Vec2> moved = x;
    step.Step(f, moved, contacts, friction);
    return moved;
  }
};

TEST(ImplicitStepContacts, AContactTheStepWouldBreakIsHeldOnItsTangentLine) {
  PressedGrid grid;
  const std::vector<StepContact> contacts = grid.Contacts(Vec2::Zero());
  const Vec2 press(-30.0, 0.0);
  const std::vector<Vec2> free = grid.Moved(press, {}, 0.0);
  const std::vector<Vec2> held = grid.Moved(press, contacts, 0.0);
  int broken_by_free = 0, on_the_line = 0;
  for (const StepContact& c : contacts) {
    const int i = c.nodes[0];
    const double free_along = c.normal.dot(free[i] - grid.x[i]) - c.gap;
    const double held_along = c.normal.dot(held[i] - grid.x[i]) - c.gap;
    if (free_along < 0.0) ++broken_by_free;
    EXPECT_GE(held_along, -1e-9) << "node " << i;
    if (std::abs(held_along) < 1e-9) ++on_the_line;
  }
  ASSERT_GT(broken_by_free, 0) << "the free step should press a node into the disc";
  EXPECT_GE(on_the_line, 1);
  // The disc holds the whole stiff grid back, not only the node it touches.
  double free_shift = 0.0, held_shift = 0.0;
  for (int i = 0; i < grid.mesh.NumNodes(); ++i) {
    free_shift += (free[i] - grid.x[i]).x();
    held_shift += (held[i] - grid.x[i]).x();
  }
  EXPECT_LT(std::abs(held_shift), 0.5 * std::abs(free_shift));
  for (int i = 0; i < grid.mesh.NumNodes(); ++i) {
    EXPECT_GT((held[i] - grid.x[i]).x(), (free[i] - grid.x[i]).x()) << "node " << i;
  }
}

TEST(ImplicitStepContacts, ContactsTheStepKeepsAnywayChangeNothing) {
  // Pulled away from the disc, no contact pulls back: the step is the free
  // one, bit for bit.
  PressedGrid grid;
  const std::vector<StepContact> contacts = grid.Contacts(Vec2::Zero());
  const Vec2 pull(30.0, 5.0);
  const std::vector<Vec2> free = grid.Moved(pull, {}, 0.0);
  const std::vector<Vec2> with_contacts = grid.Moved(pull, contacts, 0.5);
  for (int i = 0; i < grid.mesh.NumNodes(); ++i) EXPECT_EQ(free[i], with_contacts[i]) << i;
}

TEST(ImplicitStepContacts, FrictionCarriesThePressedPointWithTheDiscUpToCoulombsLimit) {
  // The disc slides 0.5 px along the grid's side while pressing on it.
  // Frictionless, the touching node slides along the disc (the other way:
  // the disc's surface there tilts); with ample friction it moves with the
  // disc; with little, part way, more with more friction.
  PressedGrid grid;
  const Vec2 disc_step(0.0, 0.5);
  const std::vector<StepContact> contacts = grid.Contacts(disc_step);
  const Vec2 press(-30.0, 0.0);
  const int touching = grid.NodeAt(Vec2(100, 110));
  const StepContact& contact = contacts[touching];
  const Vec2 tangent(-contact.normal.y(), contact.normal.x());
  // The node's slide along the disc relative to it.
  const auto slide = [&](double friction) {
    const Vec2 dx = grid.Moved(press, contacts, friction)[touching] - grid.x[touching];
    return tangent.dot(dx - disc_step);
  };
  const double frictionless = slide(0.0), gripped = slide(100.0), some = slide(0.05);
  EXPECT_GT(std::abs(frictionless), 0.5);
  EXPECT_LT(std::abs(gripped), 1e-9);
  EXPECT_LT(std::abs(some), std::abs(frictionless) - 0.01);
  EXPECT_GT(std::abs(some), 0.01);
  EXPECT_LT(std::abs(slide(0.1)), std::abs(some));
}

TEST(ImplicitStepContacts, ANodeThatJumpsHalfAnEdgeInOneSubstepFailsTheCandidateNamingIt) {
  // A sudden load far beyond the springs (as a squeezed mesh snapping
  // through releases): the step moves the loaded node by tens of pixels.
  const Mesh mesh = MakeGridMesh(4, 2, 10.0, Vec2(100, 100));
  const Scene scene = OneDiscScene(
      5, 30.0, [](int) { return Disc{Vec2(300, 300), 1.0}; },
      [](int f) { return f < 2 ? Vec2::Zero() : Vec2(1e5, 0.0); });
  SimulationOptions options;
  options.integrator = IntegratorKind::kImplicitFirstOrder;
  Simulator sim(mesh, scene, options);
  sim.Reset(Mixed());
  while (sim.Advance()) {
  }
  ASSERT_EQ(sim.status(), SimulationStatus::kFailed);
  EXPECT_NE(sim.failure_reason().find("moved node "), std::string::npos) << sim.failure_reason();
  EXPECT_NE(sim.failure_reason().find("snapped through"), std::string::npos) << sim.failure_reason();
  EXPECT_EQ(sim.failure_frame(), 2);
}

// The step's solves over the factor's raw arrays (ldlt_solve.h) give
// SimplicialLDLT::solve's bits: for dense right-hand sides, for unit
// vectors (the contacts' columns: the forward pass skips zeros), and two at
// once in every combination of zero and non-zero entries.
TEST(LdltSolve, GivesTheFactorsOwnSolveBitForBitAloneAndInPairs) {
  const Mesh mesh = MakeGridMesh(9, 6, 10.0, Vec2(40, 60));
  const Model model(mesh);
  std::vector<double> movable(mesh.NumNodes(), 1.0);
  movable[3] = 0.0;
  ImplicitStepAssembly assembly(model, movable, /*edge_stiffness=*/false);
  assembly.Assemble(Mixed(), 1.0 / 300.0, nullptr);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>>
      factor(assembly.lower());
  ASSERT_EQ(factor.info(), Eigen::Success);
  ldlt::FactorExtras extras;
  const ldlt::FactorView view = ldlt::ViewOf(factor, &extras);
  const int m = assembly.num_unknowns();
  ASSERT_EQ(view.n, m);
  // The backward substitution's order: every column once, after every
  // column whose entry it reads (its ancestors), with depths of four
  // columns and more (advanced side by side).
  const ldlt::Sweep& sweep = view.backward;
  std::vector<int> depth(m, -1);
  int widest = 0;
  for (int d = 0; d < sweep.num_levels; ++d) {
    for (int r = sweep.level_begin[d]; r < sweep.level_begin[d + 1]; ++r) depth[sweep.lines[r]] = d;
    widest = std::max(widest, sweep.level_begin[d + 1] - sweep.level_begin[d]);
  }
  ASSERT_EQ(std::count(depth.begin(), depth.end(), -1), 0);
  for (int k = 0; k < m; ++k) {
    for (int p = view.outer[k]; p < view.outer[k + 1]; ++p) {
      ASSERT_LT(depth[view.inner[p]], depth[k]) << "column " << k << " reads " << view.inner[p];
    }
  }
  EXPECT_GE(widest, 4);

  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::VectorXd> rhs;
  for (int r = 0; r < 3; ++r) {
    rhs.emplace_back(m);
    for (int k = 0; k < m; ++k) rhs.back()[k] = u(rng);
  }
  for (int k : {0, m / 2, m - 1}) rhs.push_back(Eigen::VectorXd::Unit(m, k));
  Eigen::VectorXd sparse = rhs[0];  // zeros scattered among values
  for (int k = 0; k < m; k += 3) sparse[k] = 0.0;
  rhs.push_back(sparse);
  rhs.push_back(Eigen::VectorXd::Zero(m));

  const auto same_bits = [m](const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
    return std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(m)) == 0;
  };
  std::vector<double> scratch(2 * static_cast<size_t>(m));
  for (size_t i = 0; i < rhs.size(); ++i) {
    const Eigen::VectorXd expected = factor.solve(rhs[i]);
    Eigen::VectorXd got = rhs[i];
    ldlt::SolveInPlace(view, got.data());
    EXPECT_TRUE(same_bits(got, expected)) << "right-hand side " << i;
    for (size_t j = 0; j < rhs.size(); ++j) {
      Eigen::VectorXd x = rhs[i], y = rhs[j];
      ldlt::SolveInPlace2(view, x.data(), y.data(), scratch.data());
      EXPECT_TRUE(same_bits(x, expected)) << "right-hand sides " << i << " and " << j;
      EXPECT_TRUE(same_bits(y, factor.solve(rhs[j]))) << "right-hand sides " << i << " and " << j;
    }
  }
  // And the solves solve: A x = b.
  const Eigen::SparseMatrix<double> a = assembly.lower().selfadjointView<Eigen::Lower>();
  Eigen::VectorXd x = rhs[0];
  ldlt::SolveInPlace(view, x.data());
  EXPECT_LT((a * x - rhs[0]).norm(), 1e-10 * rhs[0].norm());
}

// The re-linearised matrix's numeric refactorisation (ldlt::Factorization)
// gives SimplicialLDLT's factor bit for bit, at shapes whose springs
// stiffen unevenly, and fails on a matrix that is not positive definite
// without spoiling the next factorisation.
TEST(LdltFactorization, GivesSimplicialLdltsFactorBitForBitAtEveryShape) {
  const Mesh mesh = MakeGridMesh(9, 6, 10.0, Vec2(40, 60));
  const Model model(mesh);
  std::vector<double> movable(mesh.NumNodes(), 1.0);
  movable[3] = 0.0;
  movable[4] = 0.0;
  ImplicitStepAssembly assembly(model, movable, /*edge_stiffness=*/true);
  assembly.Assemble(Mixed(), 1.0 / 300.0, nullptr);
  ldlt::Factorization factorization;
  factorization.Analyse(assembly.upper());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Upper, Eigen::NaturalOrdering<int>>
      eigen;
  eigen.analyzePattern(assembly.upper());

  const auto same_bits = [](const auto& a, const double* b, size_t n) {
    return std::memcmp(a.data(), b, sizeof(double) * n) == 0;
  };
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> stiffness(0.0, 4000.0), angle(0.0, 6.283);
  for (int shape = 0; shape < 4; ++shape) {
    assembly.BeginShapeStiffness();
    for (int e = 0; e < mesh.NumEdges(); e += 1 + shape) {
      const double a = angle(rng);
      assembly.AddEdgeStiffness(e, stiffness(rng), Vec2(std::cos(a), std::sin(a)));
    }
    eigen.factorize(assembly.upper());
    ASSERT_EQ(eigen.info(), Eigen::Success);
    ASSERT_TRUE(factorization.Factorize(assembly.upper())) << "shape " << shape;
    const auto& l = eigen.matrixL().nestedExpression();
    const int n = static_cast<int>(l.cols());
    ASSERT_EQ(factorization.view().n, n);
    ASSERT_EQ(factorization.outer(),
              std::vector<int>(l.outerIndexPtr(), l.outerIndexPtr() + n + 1));
    ASSERT_EQ(factorization.inner(),
              std::vector<int>(l.innerIndexPtr(), l.innerIndexPtr() + l.nonZeros()));
    EXPECT_TRUE(same_bits(factorization.value(), l.valuePtr(), l.nonZeros())) << "shape " << shape;
    EXPECT_TRUE(same_bits(factorization.d(), eigen.vectorD().data(), n)) << "shape " << shape;
    Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(n, -1.0, 2.0), x = b;
    ldlt::SolveInPlace(factorization.view(), x.data());
    const Eigen::VectorXd expected = eigen.solve(b);
    EXPECT_TRUE(same_bits(x, expected.data(), n)) << "shape " << shape;
  }

  // A matrix with a negative diagonal entry: refused, and the next one
  // factorised as Eigen does.
  Eigen::SparseMatrix<double> bad = assembly.upper();
  bad.coeffRef(static_cast<int>(bad.cols()) / 2, static_cast<int>(bad.cols()) / 2) = -1e6;
  EXPECT_FALSE(factorization.Factorize(bad));
  assembly.BeginShapeStiffness();
  eigen.factorize(assembly.upper());
  ASSERT_TRUE(factorization.Factorize(assembly.upper()));
  EXPECT_TRUE(same_bits(factorization.d(), eigen.vectorD().data(), factorization.d().size()));
  EXPECT_TRUE(same_bits(factorization.value(), eigen.matrixL().nestedExpression().valuePtr(),
                        factorization.value().size()));
}

}  // namespace
}  // namespace calib
