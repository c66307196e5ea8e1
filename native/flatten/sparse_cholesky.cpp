#include "flatten/sparse_cholesky.hpp"

namespace atlas {
namespace {

// EliminationTree::work above which the supernodes are faster: measured on
// the SLIM and SCAF systems of real and generated scans (bench/README.md),
// with room on either side of the crossing.
constexpr double kSupernodalWork = 4e6;

}  // namespace

void SparseCholesky::analyze(const Eigen::SparseMatrix<double>& a) {
  const EliminationTree tree = elimination_tree(a);
  supernodal_ = tree.work() > kSupernodalWork;
  if (supernodal_)
    supernodes_.analyze(a, tree);
  else
    pairs_.analyze(a, tree);
}

bool SparseCholesky::factorize(const Eigen::SparseMatrix<double>& a) {
  return supernodal_ ? supernodes_.factorize(a) : pairs_.factorize(a);
}

void SparseCholesky::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  if (supernodal_)
    supernodes_.solve(b, x);
  else
    pairs_.solve(b, x);
}

}  // namespace atlas
