#pragma once
// Solves with the factor A = L D L^T of Eigen's SimplicialLDLT (natural
// ordering) over its raw arrays (the implicit step's).
//
// SolveInPlace makes, for each entry of the solution, SimplicialLDLT::solve's
// IEEE operations in its order, so it gives the same bits
// (tests/core/implicit_step_test.cpp checks this on the step's factors):
// forward substitution by columns of L, skipping a zero entry of the
// right-hand side as Eigen does; multiplication by 1 / D; backward
// substitution, x[k] minus L(i, k) x[i] over the entries of column k in
// storage order.
//
// Only the order in which the backward substitution computes the entries
// differs. Column k of L holds ancestors of k in the elimination tree
// (Liu, "The role of elimination trees in sparse factorization", 1990), so
// the columns of one depth need only entries of smaller depths: they are
// independent, and their running differences, each a chain of dependent
// subtractions that waits on the floating-point latency, advance side by
// side, four at a time (about 9 % of an implicit evaluation on the
// reference scene). The forward substitution's scatter has no such chain.
//
// SolveInPlace2 solves for two right-hand sides in one pass over L, each
// with exactly its own single solve's operations.
//
// Factorization factorises matrices of one sparsity pattern again and
// again (the implicit step's matrix re-linearised at the frames' shapes), with
// SimplicialLDLT::factorize's IEEE operations in its order, so it gives the
// same factor, bit for bit (tested). Eigen's up-looking factorisation finds
// the pattern of each row of L in the elimination tree as it goes; that
// depends only on the matrix's pattern, so Analyse finds it once, and each
// Factorize is the arithmetic alone: for each row, the sparse triangular
// solve over the row's pattern in Eigen's (topological) order.

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include <vector>

namespace calib::ldlt {

/// Lines of L (its columns) with their entries [begin[l], begin[l + 1]),
/// the entries' rows and values, and an order of the lines in levels of
/// independent ones: level v's lines are lines[level_begin[v] ..
/// level_begin[v + 1]).
struct Sweep {
  const int* begin = nullptr;
  const int* index = nullptr;
  const double* value = nullptr;
  const int* lines = nullptr;
  const int* level_begin = nullptr;
  int num_levels = 0;
};

/// L's strictly lower part (column-major, compressed), 1 / D and the
/// backward substitution's order.
struct FactorView {
  int n = 0;
  const int* outer = nullptr;  ///< #n + 1: column k's entries [outer[k], outer[k + 1])
  const int* inner = nullptr;  ///< row of each entry (> its column)
  const double* value = nullptr;
  const double* inverse_d = nullptr;  ///< #n
  Sweep backward;  ///< L's columns by depth in the elimination tree
};

/// What a view holds besides the factor's own arrays.
struct FactorExtras {
  std::vector<double> inverse_d;
  std::vector<int> backward_lines, backward_levels;
  std::vector<int> depth;  // each column's
};

/// x <- A^-1 x (x: #n).
void SolveInPlace(const FactorView& factor, double* x);

/// x <- A^-1 x and y <- A^-1 y (#n each); `scratch` holds 2 n values.
void SolveInPlace2(const FactorView& factor, double* x, double* y, double* scratch);

/// Fills `extras` for the factor L (outer, inner, value: as FactorView's,
/// each column's rows ascending) and D, and returns the view. Allocates nothing
/// when `extras` already holds a factor of the same size.
FactorView MakeView(int n, const int* outer, const int* inner, const double* value,
                    const double* d, FactorExtras* extras);

/// A view of `solver`'s factor, after a successful factorisation with
/// natural ordering; `extras` and the factor must outlive the view.
template <class Solver>
FactorView ViewOf(const Solver& solver, FactorExtras* extras) {
  const auto& l = solver.matrixL().nestedExpression();
  eigen_assert(l.isCompressed());
  return MakeView(static_cast<int>(l.cols()), l.outerIndexPtr(), l.innerIndexPtr(), l.valuePtr(),
                  solver.vectorD().data(), extras);
}

/// LDL^T factorisations of symmetric matrices of one pattern, each given as
/// its upper triangle compressed by columns, with natural ordering: the
/// factor SimplicialLDLT<SparseMatrix, Upper, NaturalOrdering> computes,
/// bit for bit. Analyse allocates; Factorize allocates nothing.
class Factorization {
 public:
  using SparseMatrix = Eigen::SparseMatrix<double>;

  /// The symbolic work for matrices with the pattern of `upper` (entries
  /// below the diagonal are ignored, as Eigen's Upper view does).
  void Analyse(const SparseMatrix& upper);

  /// Factorises `upper` (the analysed pattern). False where a pivot is zero
  /// (where Eigen stops with NumericalIssue) or negative; the view is then
  /// not to be used.
  bool Factorize(const SparseMatrix& upper);

  /// The last factorisation, for SolveInPlace; valid until the next
  /// Factorize or Analyse.
  const FactorView& view() const { return view_; }
  /// D of L D L^T (#n).
  const std::vector<double>& d() const { return d_; }
  /// L's strictly lower part, as FactorView's outer, inner and value.
  const std::vector<int>& outer() const { return outer_; }
  const std::vector<int>& inner() const { return inner_; }
  const std::vector<double>& value() const { return value_; }

 private:
  int n_ = 0;
  std::vector<int> outer_, inner_;  // L's pattern (rows ascending in each column)
  std::vector<double> value_, d_;
  // Row k of L: its entries' columns and their positions in value_, in the
  // order Eigen computes them: [row_begin_[k], row_begin_[k + 1]).
  std::vector<int> row_begin_, row_column_, row_position_;
  std::vector<double> y_;  // the row being solved, zero between rows
  FactorExtras extras_;
  FactorView view_;
};

}  // namespace calib::ldlt
