// Occupied texels of one page under construction, and the search for a spot
// where a dilated chart mask fits without touching any of them.
#pragma once
#include <Eigen/Core>
#include <optional>
#include <vector>

#include "placement_shape.hpp"

namespace atlas {

class PageOccupancy {
 public:
  PageOccupancy(int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }
  // Extent of everything placed so far: x in [0, used_width), y in [0, used_height).
  int used_width() const { return used_width_; }
  int used_height() const { return used_height_; }

  // Offset of mask texel (0, 0) at which no set texel of the shape lands on an
  // occupied one and y + mask.height <= top_limit: the lowest (then leftmost)
  // spot where the shape, dropped straight down, comes to rest on the
  // horizon, unless a bounded scan of the holes below it finds a lower one.
  std::optional<Eigen::Vector2i> find_spot(const PlacementShape& shape, int top_limit) const;

  // Marks the shape's set texels, mask texel (0, 0) at page texel (x, y).
  void occupy(const PlacementShape& shape, int x, int y);

 private:
  std::optional<Eigen::Vector2i> lowest_drop(const PlacementShape& shape, int top_limit) const;
  std::optional<Eigen::Vector2i> first_fit_in_holes(const PlacementShape& shape,
                                                    int top_limit) const;
  int leftmost_fit_in_row(const PlacementShape& shape, int y) const;
  bool rows_have_long_free_runs(const PlacementShape& shape, int y) const;
  int previous_row_with_free_run(int from, int length) const;
  void update_row(int y);

  int width_, height_, words_per_row_;
  int used_width_ = 0, used_height_ = 0;
  // Rows [0, used_height_) only: every row above is empty.
  std::vector<std::uint64_t> words_;
  std::vector<std::vector<Span>> free_runs_;  // per stored row, left to right
  // Longest free run of every row (width_ above used_height_), and its maximum
  // per block of rows: rows that cannot take a chart's widest run are skipped.
  std::vector<int> longest_free_run_;
  std::vector<int> block_longest_free_run_;
  // Per column, one above its highest occupied texel: all texels above are
  // free. Its minimum per block of columns lets the drop skip whole blocks.
  std::vector<int> horizon_;
  std::vector<int> block_lowest_horizon_;
  // Scratch for one row scan. The search is const but reuses these buffers,
  // so a page must not be searched from two threads at once.
  mutable std::vector<Span> candidates_, kept_;
  mutable std::vector<std::pair<int, int>> block_bounds_;
};

}  // namespace atlas
