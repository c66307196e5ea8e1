#include "flatten/elimination_tree.hpp"

namespace atlas {

double EliminationTree::work() const {
  double sum = 0;
  for (const int c : counts) sum += static_cast<double>(c) * c;
  return sum;
}

EliminationTree elimination_tree(const Eigen::SparseMatrix<double>& a) {
  const int n = static_cast<int>(a.rows());
  EliminationTree tree;
  tree.parent.assign(n, -1);
  tree.counts.assign(n, 0);
  std::vector<int> tags(n, -1);
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  for (int k = 0; k < n; ++k) {
    tags[k] = k;
    for (int p = outer[k]; p < outer[k + 1]; ++p)
      for (int i = inner[p]; i < k && tags[i] != k; i = tree.parent[i]) {
        if (tree.parent[i] == -1) tree.parent[i] = k;
        ++tree.counts[i];
        tags[i] = k;
      }
  }
  return tree;
}

}  // namespace atlas
