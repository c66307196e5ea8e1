#include "flatten/pair_cholesky.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>

namespace atlas {
namespace {

// Row indices of the upper triangle of column k of a, in increasing order.
struct ColumnRows {
  const int* begin;
  const int* end;
};

ColumnRows column_rows(const Eigen::SparseMatrix<double>& a, int k) {
  return {a.innerIndexPtr() + a.outerIndexPtr()[k], a.innerIndexPtr() + a.outerIndexPtr()[k + 1]};
}

// Rows k and k + 1 pair up when column k + 1 of the upper triangle holds the
// rows of column k above k, then k: the walks up the elimination tree that
// give row k + 1's pattern are then row k's, and the first of them goes on
// through k (whose parent is k + 1). So row k + 1's pattern, in the order
// the walks give it, is row k's followed by k.
bool pairs_with_next(const Eigen::SparseMatrix<double>& a, int k) {
  ColumnRows lower = column_rows(a, k), upper = column_rows(a, k + 1);
  for (; lower.begin != lower.end && *lower.begin < k; ++lower.begin, ++upper.begin)
    if (upper.begin == upper.end || *upper.begin != *lower.begin) return false;
  return upper.begin != upper.end && *upper.begin == k;
}

}  // namespace

// The layout of L from the column counts (Eigen's analyzePattern_preordered).
void PairCholesky::analyze(const Eigen::SparseMatrix<double>& a, const EliminationTree& tree) {
  const int n = static_cast<int>(a.rows());
  parent_ = tree.parent;
  const std::vector<int>& counts = tree.counts;
  column_start_.assign(n + 1, 0);
  long long entries = 0;
  for (int k = 0; k < n; ++k) {
    entries += counts[k] + 1;  // + the diagonal
    // int positions address L: a factor past them would not fit in memory either.
    if (entries > std::numeric_limits<int>::max()) throw std::bad_alloc();
    column_start_[k + 1] = static_cast<int>(entries);
  }
  rows_.resize(column_start_[n]);
  values_.resize(column_start_[n]);
  column_filled_.assign(n, 0);
  pairs_next_.assign(n, 0);
  for (int k = 0; k + 1 < n; ++k) pairs_next_[k] = pairs_with_next(a, k);
  work_.assign(2 * static_cast<size_t>(n), 0.0);
  record_row_patterns(a);
}

// Row k of L holds every node reached from the rows i < k of A(:, k) by
// walking up the tree, each node before its ancestors. That depends on the
// pattern alone, so it is found here once for every row factorize walks
// (a pair's second row it does not) and factorize only reads it.
void PairCholesky::record_row_patterns(const Eigen::SparseMatrix<double>& a) {
  const int n = static_cast<int>(a.rows());
  std::vector<int> tags(n, -1), walk(n), pattern(n);
  pattern_start_.assign(n + 1, 0);
  patterns_.clear();
  for (int k = 0; k < n; ++k) {
    pattern_start_[k] = static_cast<int>(patterns_.size());
    int top = n;
    tags[k] = k;
    const ColumnRows rows = column_rows(a, k);
    for (const int* row = rows.begin; row != rows.end; ++row) {
      if (*row > k) continue;
      int length = 0;
      for (int i = *row; tags[i] != k; i = parent_[i]) {
        walk[length++] = i;
        tags[i] = k;
      }
      while (length > 0) pattern[--top] = walk[--length];
    }
    patterns_.insert(patterns_.end(), pattern.begin() + top, pattern.end());
    if (pairs_next_[k]) pattern_start_[++k] = static_cast<int>(patterns_.size());
  }
  pattern_start_[n] = static_cast<int>(patterns_.size());
}

// Adds A(0:k, k) into the even work_ slots, A(i, k) at 2i.
void PairCholesky::scatter_column(const Eigen::SparseMatrix<double>& a, int k) {
  const ColumnRows rows = column_rows(a, k);
  const double* value = a.valuePtr() + a.outerIndexPtr()[k];
  for (const int* row = rows.begin; row != rows.end; ++row, ++value)
    if (*row <= k) work_[2 * *row] += *value;
}

// Row k of L: the sparse triangular solve L(0:k, 0:k) l = A(0:k, k), column
// by column of L along the pattern; pivot = A(k,k) - |l|^2.
void PairCholesky::factorize_row(const Eigen::SparseMatrix<double>& a, int k, double& pivot) {
  work_[2 * k] = 0;
  column_filled_[k] = 0;
  scatter_column(a, k);
  pivot = work_[2 * k];
  work_[2 * k] = 0;
  for (int at = pattern_start_[k]; at < pattern_start_[k + 1]; ++at) {
    const int i = patterns_[at];
    const double l = work_[2 * i] / values_[column_start_[i]];
    work_[2 * i] = 0;
    const int end = column_start_[i] + column_filled_[i];
    for (int p = column_start_[i] + 1; p < end; ++p) work_[2 * rows_[p]] -= values_[p] * l;
    pivot -= l * l;
    rows_[end] = k;
    values_[end] = l;
    ++column_filled_[i];
  }
}

// Rows k and k + 1 at once (pairs_with_next(k)): the second row is kept at
// the odd work_ slots. Along row k's pattern both rows read the same column
// of L; then row k + 1 meets L(k, i), just appended, and finally column k.
void PairCholesky::factorize_pair(const Eigen::SparseMatrix<double>& a, int k, double& pivot0, double& pivot1) {
  work_[2 * k] = 0;
  column_filled_[k] = 0;
  column_filled_[k + 1] = 0;
  scatter_column(a, k);
  // Column k + 1 scattered into the odd slots; its pattern is not needed.
  const ColumnRows rows = column_rows(a, k + 1);
  const double* value = a.valuePtr() + a.outerIndexPtr()[k + 1];
  for (const int* row = rows.begin; row != rows.end; ++row, ++value)
    if (*row <= k + 1) work_[2 * *row + 1] += *value;
  pivot0 = work_[2 * k];
  work_[2 * k] = 0;
  pivot1 = work_[2 * (k + 1) + 1];
  work_[2 * (k + 1) + 1] = 0;
  for (int at = pattern_start_[k]; at < pattern_start_[k + 1]; ++at) {
    const int i = patterns_[at];
    const double diagonal = values_[column_start_[i]];
    const double l0 = work_[2 * i] / diagonal, l1 = work_[2 * i + 1] / diagonal;
    work_[2 * i] = work_[2 * i + 1] = 0;
    const int end = column_start_[i] + column_filled_[i];
    // Entries of consecutive rows (a pair, most of them) update four
    // consecutive work_ slots: one index load and one contiguous block for both.
    for (int p = column_start_[i] + 1; p < end; ++p) {
      const double value = values_[p];  // loaded once: the stores to y could alias it
      double* y = &work_[2 * rows_[p]];
      y[0] -= value * l0;
      y[1] -= value * l1;
      if (p + 1 == end || rows_[p + 1] != rows_[p] + 1) continue;
      const double next = values_[++p];
      y[2] -= next * l0;
      y[3] -= next * l1;
    }
    work_[2 * k + 1] -= l0 * l1;
    pivot0 -= l0 * l0;
    pivot1 -= l1 * l1;
    rows_[end] = k, values_[end] = l0;
    rows_[end + 1] = k + 1, values_[end + 1] = l1;
    column_filled_[i] += 2;
  }
}

bool PairCholesky::factorize(const Eigen::SparseMatrix<double>& a) {
  const int n = static_cast<int>(a.rows());
  // Store L(k,k) = sqrt(pivot) first in column k.
  auto store_diagonal = [&](int k, double pivot) {
    const int p = column_start_[k] + column_filled_[k]++;
    rows_[p] = k;
    if (!(pivot > 0)) return false;
    values_[p] = std::sqrt(pivot);
    return true;
  };
  // A failed factorization leaves work_ dirty.
  std::fill(work_.begin(), work_.end(), 0.0);
  for (int k = 0; k < n; ++k) {
    if (!pairs_next_[k]) {
      double pivot;
      factorize_row(a, k, pivot);
      if (!store_diagonal(k, pivot)) return false;
      continue;
    }
    double pivot0, pivot1;
    factorize_pair(a, k, pivot0, pivot1);
    if (!store_diagonal(k, pivot0)) return false;
    // Row k + 1's last pattern node: k, whose column holds only its diagonal yet.
    const double l = work_[2 * k + 1] / values_[column_start_[k]];
    work_[2 * k + 1] = 0;
    pivot1 -= l * l;
    const int end = column_start_[k] + column_filled_[k]++;
    rows_[end] = k + 1, values_[end] = l;
    ++k;
    if (!store_diagonal(k, pivot1)) return false;
  }
  return true;
}

// L y = b column by column, then L^T x = y row by row (Eigen's sparse
// triangular solves; a zero entry of y skips its column there too).
void PairCholesky::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  const int n = static_cast<int>(b.size());
  x = b;
  for (int i = 0; i < n; ++i) {
    if (x[i] == 0) continue;
    x[i] /= values_[column_start_[i]];
    for (int p = column_start_[i] + 1; p < column_start_[i + 1]; ++p) x[rows_[p]] -= x[i] * values_[p];
  }
  for (int i = n - 1; i >= 0; --i) {
    double sum = x[i];
    for (int p = column_start_[i] + 1; p < column_start_[i + 1]; ++p) sum -= values_[p] * x[rows_[p]];
    x[i] = sum / values_[column_start_[i]];
  }
}

}  // namespace atlas
