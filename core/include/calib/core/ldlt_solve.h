#pragma once
// Solves with the factor A = L D L^T of Eigen's SimplicialLDLT (natural
// ordering) over its raw arrays (the implicit step's).
//
// SolveInPlace is SimplicialLDLT::solve's sequence of IEEE operations, in
// its order: forward substitution by columns of L, skipping a zero entry of
// the right-hand side as Eigen does; multiplication by 1 / D; backward
// substitution by rows of L^T, each a running difference in storage order.
// So it gives the same bits (tests/core/implicit_step_test.cpp checks this
// on the step's own factors), without the expression templates' iterator
// set-up per column.
//
// SolveInPlace2 solves for two right-hand sides in one pass over L, each
// with exactly its own single solve's operations: the backward substitution
// is a chain of dependent subtractions per row, so two chains side by side
// cost little more than one.

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <vector>

namespace calib::ldlt {

/// L's strictly lower part (column-major, compressed) and 1 / D, each of
/// size n.
struct FactorView {
  int n = 0;
  const int* outer = nullptr;  ///< #n + 1: column k's entries [outer[k], outer[k + 1])
  const int* inner = nullptr;  ///< row of each entry (> its column)
  const double* value = nullptr;
  const double* inverse_d = nullptr;
};

/// x <- A^-1 x (x: #n).
void SolveInPlace(const FactorView& factor, double* x);

/// x <- A^-1 x and y <- A^-1 y (#n each); `scratch` holds 2 n values.
void SolveInPlace2(const FactorView& factor, double* x, double* y, double* scratch);

/// A view of `solver`'s factor, after a successful factorisation with
/// natural ordering; `inverse_d` receives 1 / D and must outlive the view.
template <class Solver>
FactorView ViewOf(const Solver& solver, std::vector<double>* inverse_d) {
  const auto& l = solver.matrixL().nestedExpression();
  eigen_assert(l.isCompressed());
  const auto& d = solver.vectorD();
  inverse_d->resize(static_cast<size_t>(d.size()));
  for (Eigen::Index i = 0; i < d.size(); ++i) (*inverse_d)[i] = 1.0 / d[i];
  FactorView view;
  view.n = static_cast<int>(l.cols());
  view.outer = l.outerIndexPtr();
  view.inner = l.innerIndexPtr();
  view.value = l.valuePtr();
  view.inverse_d = inverse_d->data();
  return view;
}

}  // namespace calib::ldlt
