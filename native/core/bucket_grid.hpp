// Items bucketed on a uniform grid over a box. With about sqrt(items) cells a
// side a bucket holds about one item, which keeps the pair and containment
// tests that walk the buckets near linear. Used by the boundary crossing test
// and by the scaffold's ear clipping.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <vector>

namespace atlas {

class BucketGrid {
 public:
  BucketGrid(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, size_t items)
      : lo_(lo), n_(std::max(1, static_cast<int>(std::sqrt(static_cast<double>(items))))) {
    cell_ = ((hi - lo) / n_).cwiseMax(1e-12);
    buckets_.resize(static_cast<size_t>(n_) * n_);
  }

  // Puts the item in every cell its bounding box [lo, hi] overlaps.
  void insert(int item, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
    any_cell(lo, hi, [&](size_t cell) {
      buckets_[cell].push_back(item);
      return false;
    });
  }

  // Calls visit(item) for the items in the cells the box [lo, hi] overlaps
  // (an item in several of them comes several times); true as soon as a
  // visit returns true.
  template <class Visit>
  bool any_near(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, Visit visit) const {
    return any_cell(lo, hi, [&](size_t cell) { return std::any_of(buckets_[cell].begin(), buckets_[cell].end(), visit); });
  }

  const std::vector<std::vector<int>>& buckets() const { return buckets_; }

 private:
  // Calls visit(cell index) for the cells the box [lo, hi] overlaps.
  template <class Visit>
  bool any_cell(const Eigen::Vector2d& lo, const Eigen::Vector2d& hi, Visit visit) const {
    for (int y = axis(lo.y(), 1); y <= axis(hi.y(), 1); ++y)
      for (int x = axis(lo.x(), 0); x <= axis(hi.x(), 0); ++x)
        if (visit(static_cast<size_t>(y) * n_ + x)) return true;
    return false;
  }
  // Clamped before the cast: a query box far larger than the cells (a margin
  // of fixed texels around a chart of 1e-11 texels) would overflow an int.
  int axis(double v, int d) const {
    const double cell = (v - lo_[d]) / cell_[d];
    return cell > 0 ? static_cast<int>(std::min(cell, n_ - 1.0)) : 0;  // NaN: cell 0
  }

  Eigen::Vector2d lo_, cell_;
  int n_;
  std::vector<std::vector<int>> buckets_;
};

}  // namespace atlas
