// Disjoint sets over 0..n-1 (union-find with path halving): how the stages
// group faces into charts and face corners into vertices.
#pragma once
#include <numeric>
#include <vector>

namespace atlas {

class UnionFind {
 public:
  explicit UnionFind(int n) : parent_(n) { std::iota(parent_.begin(), parent_.end(), 0); }

  int find(int x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }

  void unite(int a, int b) { parent_[find(a)] = find(b); }

  // Class of every element, numbered 0, 1, ... in order of first appearance.
  std::vector<int> dense_labels() {
    std::vector<int> label_of_root(parent_.size(), -1), label(parent_.size());
    int count = 0;
    for (size_t x = 0; x < parent_.size(); ++x) {
      int& l = label_of_root[find(static_cast<int>(x))];
      if (l < 0) l = count++;
      label[x] = l;
    }
    return label;
  }

 private:
  std::vector<int> parent_;
};

}  // namespace atlas
