// The sparse Cholesky factorization of the SLIM and SCAF systems: by
// supernodes where the factor fills in much (long dense updates pay for
// their set-up), by vertex pairs where it stays sparse (most charts of
// real scans, whose results then stay those of Eigen's SimplicialLLT).
#pragma once
#include <Eigen/SparseCore>

#include "flatten/pair_cholesky.hpp"
#include "flatten/supernodal_cholesky.hpp"

namespace atlas {

class SparseCholesky {
 public:
  // The same contract as PairCholesky's and SupernodalCholesky's.
  void analyze(const Eigen::SparseMatrix<double>& a);
  bool factorize(const Eigen::SparseMatrix<double>& a);
  void solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const;
  bool supernodal() const { return supernodal_; }

 private:
  bool supernodal_ = false;
  PairCholesky pairs_;
  SupernodalCholesky supernodes_;
};

}  // namespace atlas
