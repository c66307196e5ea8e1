#include "flatten/supernodal_cholesky.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <new>

namespace atlas {
namespace {

using Panel = Eigen::Map<Eigen::MatrixXd>;
using ConstBlock = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;

// Below this many multiply-adds an update runs as plain loops: a dense
// product's set-up would cost more than it saves.
constexpr double kDenseUpdateFlops = 1024;

}  // namespace

void SupernodalCholesky::analyze(const Eigen::SparseMatrix<double>& a, const EliminationTree& tree) {
  n_ = static_cast<int>(a.rows());
  record_lower_triangle(a);
  find_supernodes(tree.parent, tree.counts);
  find_rows(tree.parent);
  relative_.assign(n_, 0);
  next_position_.assign(supernodes_.size(), 0);
  head_.assign(supernodes_.size(), -1);
  next_.assign(supernodes_.size(), -1);
}

// The lower triangle, column by column: the transpose of the stored upper one.
void SupernodalCholesky::record_lower_triangle(const Eigen::SparseMatrix<double>& a) {
  lower_start_.assign(n_ + 1, 0);
  diagonal_slot_.assign(n_, -1);
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  for (int c = 0; c < n_; ++c)
    for (int p = outer[c]; p < outer[c + 1]; ++p)
      if (inner[p] < c) ++lower_start_[inner[p] + 1];
  for (int j = 0; j < n_; ++j) lower_start_[j + 1] += lower_start_[j];
  lower_rows_.resize(lower_start_[n_]);
  lower_slot_.resize(lower_start_[n_]);
  std::vector<int> fill(lower_start_.begin(), lower_start_.end() - 1);
  for (int c = 0; c < n_; ++c)
    for (int p = outer[c]; p < outer[c + 1]; ++p) {
      const int r = inner[p];
      if (r == c) diagonal_slot_[c] = p;
      if (r >= c) continue;
      lower_rows_[fill[r]] = c;
      lower_slot_[fill[r]++] = p;
    }
}

// Column j continues the supernode of j - 1 when it is j - 1's parent and its
// pattern is j - 1's without j: the two columns then form a dense block.
void SupernodalCholesky::find_supernodes(const std::vector<int>& parent, const std::vector<int>& counts) {
  supernodes_.clear();
  column_supernode_.assign(n_, 0);
  for (int j = 0; j < n_; ++j) {
    const bool continues = j > 0 && parent[j - 1] == j && counts[j - 1] == counts[j] + 1;
    if (!continues) supernodes_.push_back({j, 0, 0, counts[j] + 1, 0});
    ++supernodes_.back().width;
    column_supernode_[j] = static_cast<int>(supernodes_.size()) - 1;
  }
}

// The rows of each supernode: its own columns, then every row below them
// that A holds in its columns or that a child supernode holds below them.
void SupernodalCholesky::find_rows(const std::vector<int>& parent) {
  const int count = static_cast<int>(supernodes_.size());
  std::vector<std::vector<int>> children(count);
  for (int s = 0; s < count; ++s) {
    const int up = parent[supernodes_[s].first + supernodes_[s].width - 1];
    if (up != -1) children[column_supernode_[up]].push_back(s);
  }
  std::vector<int> mark(n_, -1);
  rows_.clear();
  size_t values = 0;
  for (int s = 0; s < count; ++s) {
    Supernode& node = supernodes_[s];
    const int last = node.first + node.width - 1;
    node.row_start = static_cast<int>(rows_.size());
    for (int j = node.first; j <= last; ++j) rows_.push_back(j);
    auto add = [&](int i) {
      if (i > last && mark[i] != s) mark[i] = s, rows_.push_back(i);
    };
    for (int j = node.first; j <= last; ++j)
      for (int q = lower_start_[j]; q < lower_start_[j + 1]; ++q) add(lower_rows_[q]);
    for (int c : children[s]) {
      const Supernode& child = supernodes_[c];
      for (int q = child.row_start + child.width; q < child.row_start + child.rows; ++q) add(rows_[q]);
    }
    // int positions address the rows: a factor past them would not fit in memory either.
    if (rows_.size() > static_cast<size_t>(std::numeric_limits<int>::max())) throw std::bad_alloc();
    std::sort(rows_.begin() + node.row_start + node.width, rows_.end());
    node.rows = static_cast<int>(rows_.size()) - node.row_start;
    node.value_start = values;
    values += static_cast<size_t>(node.rows) * node.width;
  }
  values_.resize(values);
}

// A's entries of the supernode's columns into its (zeroed) panel; relative_
// holds the panel row of each of its rows.
void SupernodalCholesky::scatter_matrix(const Eigen::SparseMatrix<double>& a, const Supernode& s,
                                        double* panel) const {
  const double* value = a.valuePtr();
  for (int t = 0; t < s.width; ++t) {
    const int j = s.first + t;
    double* column = panel + static_cast<size_t>(t) * s.rows;
    column[t] = value[diagonal_slot_[j]];
    for (int q = lower_start_[j]; q < lower_start_[j + 1]; ++q) column[relative_[lower_rows_[q]]] = value[lower_slot_[q]];
  }
}

// panel(i, j) -= sum_t L_k(i, t) L_k(j, t) for the rows i >= j of supernode k
// from position `from` on and its rows j at positions [from, to), which are
// columns of s.
void SupernodalCholesky::update_from(const Supernode& k, int from, int to, const Supernode& s, double* panel) {
  const double* source = values_.data() + k.value_start;
  const int* rows = rows_.data() + k.row_start;
  const int height = k.rows - from, width = to - from;
  if (static_cast<double>(height) * width * k.width < kDenseUpdateFlops) {
    for (int t = 0; t < k.width; ++t) {
      const double* column = source + static_cast<size_t>(t) * k.rows;
      for (int b = from; b < to; ++b) {
        const double factor = column[b];
        double* target = panel + static_cast<size_t>(relative_[rows[b]]) * s.rows;
        for (int i = b; i < k.rows; ++i) target[relative_[rows[i]]] -= column[i] * factor;
      }
    }
    return;
  }
  if (product_.size() < static_cast<size_t>(height) * width) product_.resize(static_cast<size_t>(height) * width);
  Panel product(product_.data(), height, width);
  const ConstBlock below(source + from, height, k.width, Eigen::OuterStride<>(k.rows));
  product.noalias() = below * below.topRows(width).transpose();
  for (int b = 0; b < width; ++b) {
    double* target = panel + static_cast<size_t>(relative_[rows[from + b]]) * s.rows;
    const double* column = product_.data() + static_cast<size_t>(b) * height;
    for (int i = b; i < height; ++i) target[relative_[rows[from + i]]] -= column[i];
  }
}

// The panel's diagonal block into its Cholesky factor T, and the block below
// into B T^-T. A narrow panel goes column by column (the set-up of a dense
// factorization would cost more than the work).
constexpr int kNarrowPanel = 8;
bool SupernodalCholesky::factorize_panel(const Supernode& s, double* panel) const {
  if (s.width <= kNarrowPanel) {
    for (int t = 0; t < s.width; ++t) {
      double* column = panel + static_cast<size_t>(t) * s.rows;
      for (int u = 0; u < t; ++u) {
        const double* left = panel + static_cast<size_t>(u) * s.rows;
        const double factor = left[t];
        for (int i = t; i < s.rows; ++i) column[i] -= left[i] * factor;
      }
      if (!(column[t] > 0)) return false;
      const double diagonal = column[t] = std::sqrt(column[t]);
      for (int i = t + 1; i < s.rows; ++i) column[i] /= diagonal;
    }
    return true;
  }
  Panel all(panel, s.rows, s.width);
  Eigen::Ref<Eigen::MatrixXd> top = all.topRows(s.width);
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(top);
  if (llt.info() != Eigen::Success) return false;
  if (s.rows > s.width)
    top.triangularView<Eigen::Lower>().transpose().solveInPlace<Eigen::OnTheRight>(all.bottomRows(s.rows - s.width));
  return true;
}

// Left-looking: each supernode, in order, gathers the updates of the
// supernodes below it whose rows reach its columns. head_[s] lists those
// yet to update s; next_position_[k] is where k's rows reach the next one.
bool SupernodalCholesky::factorize(const Eigen::SparseMatrix<double>& a) {
  std::fill(head_.begin(), head_.end(), -1);
  auto link = [&](int k, int position) {
    const Supernode& node = supernodes_[k];
    if (position >= node.rows) return;
    const int target = column_supernode_[rows_[node.row_start + position]];
    next_position_[k] = position;
    next_[k] = head_[target];
    head_[target] = k;
  };
  for (int s = 0; s < static_cast<int>(supernodes_.size()); ++s) {
    const Supernode& node = supernodes_[s];
    double* panel = values_.data() + node.value_start;
    std::fill(panel, panel + static_cast<size_t>(node.rows) * node.width, 0.0);
    for (int i = 0; i < node.rows; ++i) relative_[rows_[node.row_start + i]] = i;
    scatter_matrix(a, node, panel);
    const int last = node.first + node.width - 1;
    for (int k = head_[s]; k != -1;) {
      const int following = next_[k];
      const Supernode& source = supernodes_[k];
      const int from = next_position_[k];
      int to = from;
      while (to < source.rows && rows_[source.row_start + to] <= last) ++to;
      update_from(source, from, to, node, panel);
      link(k, to);
      k = following;
    }
    if (!factorize_panel(node, panel)) return false;
    link(s, node.width);
  }
  return true;
}

// L y = b, then L^T x = y, a supernode's columns at a time.
void SupernodalCholesky::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  x = b;
  for (const Supernode& s : supernodes_) {
    const double* panel = values_.data() + s.value_start;
    const int* rows = rows_.data() + s.row_start;
    for (int t = 0; t < s.width; ++t) {
      const double* column = panel + static_cast<size_t>(t) * s.rows;
      const double value = x[s.first + t] /= column[t];
      for (int i = t + 1; i < s.rows; ++i) x[rows[i]] -= column[i] * value;
    }
  }
  for (auto s = supernodes_.rbegin(); s != supernodes_.rend(); ++s) {
    const double* panel = values_.data() + s->value_start;
    const int* rows = rows_.data() + s->row_start;
    for (int t = s->width - 1; t >= 0; --t) {
      const double* column = panel + static_cast<size_t>(t) * s->rows;
      double sum = x[s->first + t];
      for (int i = t + 1; i < s->rows; ++i) sum -= column[i] * x[rows[i]];
      x[s->first + t] = sum / column[t];
    }
  }
}

}  // namespace atlas
