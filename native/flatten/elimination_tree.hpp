// The elimination tree of a sparse symmetric matrix and the column counts of
// its Cholesky factor L (Liu 1986): what the factorizations' symbolic
// analyses share, and what tells how much work a factorization is.
#pragma once
#include <Eigen/SparseCore>
#include <vector>

namespace atlas {

struct EliminationTree {
  std::vector<int> parent;  // n: the parent of column j, -1 at a root
  std::vector<int> counts;  // n: the entries of column j of L below the diagonal
  // sum_j counts[j]^2: proportional to the multiply-adds of a factorization.
  double work() const;
};

// a: n x n, compressed, column-major, upper triangle stored (the lower one is
// ignored). Row k of L holds every node reached from the rows i < k of
// A(:, k) by walking up the tree; the first row to reach a node without a
// parent is its parent.
EliminationTree elimination_tree(const Eigen::SparseMatrix<double>& a);

}  // namespace atlas
