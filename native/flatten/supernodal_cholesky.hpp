// Sparse Cholesky factorization A = L L^T by supernodes (left-looking, after
// Ng and Peyton 1993 and CHOLMOD): columns of L that share their pattern
// below the diagonal form a supernode, stored as one dense column-major
// panel, so the updates between supernodes are dense products. On meshes
// whose factor fills in much (regular grids, scaffolds) most of the work
// lies in wide supernodes, where dense products run several times faster
// than the entry-by-entry updates of a simplicial factorization.
#pragma once
#include <Eigen/SparseCore>
#include <cstddef>
#include <vector>

#include "flatten/elimination_tree.hpp"

namespace atlas {

class SupernodalCholesky {
 public:
  // a: n x n, compressed, column-major, upper triangle stored (the lower one
  // is ignored), diagonal stored; tree: its elimination_tree. Finds the
  // supernodes and the rows of each; factorize then takes any matrix with
  // this pattern.
  void analyze(const Eigen::SparseMatrix<double>& a, const EliminationTree& tree);
  void analyze(const Eigen::SparseMatrix<double>& a) { analyze(a, elimination_tree(a)); }
  // Numeric factorization of a (same pattern as in analyze). False when a is
  // not positive definite at working precision.
  bool factorize(const Eigen::SparseMatrix<double>& a);
  // x = A^-1 b, after a successful factorize; b and x have n rows.
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;

 private:
  struct Supernode {
    int first, width;     // columns first .. first + width - 1
    int row_start, rows;  // its rows: rows_[row_start .. row_start + rows), the diagonal block's first
    size_t value_start;   // panel rows x width, column-major, at values_[value_start]
  };
  void record_lower_triangle(const Eigen::SparseMatrix<double>& a);
  void find_supernodes(const std::vector<int>& parent, const std::vector<int>& counts);
  void find_rows(const std::vector<int>& parent);
  void scatter_matrix(const Eigen::SparseMatrix<double>& a, const Supernode& s, double* panel) const;
  void update_from(const Supernode& k, int from, int to, const Supernode& s, double* panel);
  bool factorize_panel(const Supernode& s, double* panel) const;

  int n_ = 0;
  std::vector<Supernode> supernodes_;
  std::vector<int> column_supernode_;  // the supernode each column belongs to
  std::vector<int> rows_;
  std::vector<double> values_;
  // The lower triangle of A by column: rows lower_rows_[lower_start_[j] ..
  // lower_start_[j + 1]) below the diagonal, their values at a.valuePtr()[lower_slot_[.]];
  // the diagonal of column j at diagonal_slot_[j].
  std::vector<int> lower_start_, lower_rows_, lower_slot_, diagonal_slot_;
  // Work space of factorize.
  std::vector<int> relative_, next_position_, head_, next_;
  std::vector<double> product_;
};

}  // namespace atlas
