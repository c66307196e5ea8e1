// Sparse Cholesky factorization A = L L^T for the SLIM and SCAF systems, whose
// unknowns come in pairs: (x, y) of a vertex at rows 2v and 2v + 1, with one
// 2x2 block per vertex pair. Two such rows have the same pattern in L but for
// L(2v+1, 2v), so they are computed together: one elimination-tree walk and
// one pass over each column of L serve both rows.
//
// The arithmetic is that of Eigen's SimplicialLLT with natural ordering (the
// up-looking algorithm of Davis' LDL, "Algorithm 849", 2005): every entry of L
// and of the solution receives the same operations in the same order, so the
// results are bit-identical to it. Rows that do not pair up are computed one
// at a time.
#pragma once
#include <Eigen/SparseCore>
#include <vector>

#include "flatten/elimination_tree.hpp"

namespace atlas {

class PairCholesky {
 public:
  // a: n x n, compressed, column-major, upper triangle stored (the lower one
  // is ignored), diagonal stored; tree: its elimination_tree. Finds the
  // pattern of L; factorize then takes any matrix with this pattern.
  void analyze(const Eigen::SparseMatrix<double>& a, const EliminationTree& tree);
  void analyze(const Eigen::SparseMatrix<double>& a) { analyze(a, elimination_tree(a)); }
  // Numeric factorization of a (same pattern as in analyze). False when a is
  // not positive definite at working precision (a pivot <= 0).
  bool factorize(const Eigen::SparseMatrix<double>& a);
  // x = A^-1 b, after a successful factorize; b and x have n rows.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;

 private:
  void factorize_row(const Eigen::SparseMatrix<double>& a, int k, double& pivot);
  void factorize_pair(const Eigen::SparseMatrix<double>& a, int k, double& pivot0, double& pivot1);
  void record_row_patterns(const Eigen::SparseMatrix<double>& a);
  void scatter_column(const Eigen::SparseMatrix<double>& a, int k);

  std::vector<int> parent_;         // elimination tree, -1 at a root
  std::vector<int> column_start_;   // n + 1: where column j of L starts in rows_ / values_
  std::vector<int> column_filled_;  // entries of column j written so far (during factorize)
  std::vector<char> pairs_next_;    // row k pairs with row k + 1 (see pairs_with_next)
  std::vector<int> rows_;           // row index of each entry of L, column by column
  std::vector<double> values_;      // the entries of L; the diagonal first in each column
  // The pattern of row k of L, in the order factorize visits its columns:
  // patterns_[pattern_start_[k] .. pattern_start_[k + 1]) (empty for the
  // second row of a pair, which follows the first's).
  std::vector<int> pattern_start_, patterns_;
  // Work space of factorize: the dense row(s) being computed (interleaved for a pair).
  std::vector<double> work_;
};

}  // namespace atlas
