// Occupied texels of one page under construction, and the searches for a spot
// where a chart's dilated mask fits without touching any of them.
#pragma once
#include <Eigen/Core>
#include <array>
#include <optional>
#include <vector>

#include "pack/placement_shape.hpp"

namespace atlas {

class PageOccupancy {
 public:
  PageOccupancy(int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }
  // Extent of everything placed so far: x in [0, used_width), y in [0, used_height).
  int used_width() const { return used_width_; }
  int used_height() const { return used_height_; }

  // Both searches return the offset of mask texel (0, 0) at which no set
  // texel of the shape lands on an occupied one and y + mask.height <= top_limit.
  //
  // The lowest spot where the shape, dropped straight down, comes to rest on
  // the horizon. Costs about width / 64 plus a few blocks of 64 columns.
  std::optional<Eigen::Vector2i> lowest_drop(const PlacementShape& shape, int top_limit) const;
  // A low spot anywhere, holes under the horizon included, scanning rows
  // upwards: the lowest one, except that rows where the last shape of a
  // similar size found nothing are skipped (see resume_row_).
  std::optional<Eigen::Vector2i> first_fit(const PlacementShape& shape, int top_limit) const;

  // Marks the mask's set texels, mask texel (0, 0) at page texel (x, y).
  void occupy(const TexelMask& mask, int x, int y);

 private:
  static constexpr int kRunTiers = 4;
  // Free runs of one stored row, left to right, in tiers: tier k lists only
  // runs at least 4^k long, since a chart run of length L need only be
  // tried against the highest tier with 4^k <= L.
  using FreeRow = std::array<std::vector<Span>, kRunTiers>;

  int core_floor(const PlacementShape& shape) const;
  int next_free_rectangle_row(int width, int height, int from) const;
  int leftmost_fit_in_row(const PlacementShape& shape, int y) const;
  bool rows_have_long_free_runs(const PlacementShape& shape, int y) const;
  int next_row_with_free_run(int from, int length) const;
  void update_row(int y, int x_begin, int x_end);
  void update_horizon(const TexelMask& mask, int x, int y);

  int width_, height_, words_per_row_;
  int used_width_ = 0, used_height_ = 0;
  // Rows [0, used_height_) only: every row above is empty.
  std::vector<std::uint64_t> words_;
  std::vector<FreeRow> rows_;
  // Longest free run of every row (width_ above used_height_), and its maximum
  // per block of rows: rows that cannot take a chart's widest run are skipped.
  std::vector<int> longest_free_run_;
  std::vector<int> block_longest_free_run_;
  // Per column, one above its highest occupied texel: all texels above are
  // free. Its minimum per block of columns lets the drop skip whole blocks.
  std::vector<int> horizon_;
  std::vector<int> block_lowest_horizon_;
  // Caches of the searches; occupying only removes free texels, so both only rise.
  // Per size class of a free rectangle: no such rectangle stands lower.
  mutable std::vector<int> rectangle_floor_;
  // Per size class of a shape's bounding box: the row where the last
  // first_fit of such a shape ended. Rows below did not take that shape and
  // rarely take one of a similar size, so the next search starts there.
  mutable std::vector<int> resume_row_;
  // Scratch. The searches are const but reuse these buffers, so a page must
  // not be searched from two threads at once.
  mutable std::vector<Span> candidates_, kept_;
  mutable std::vector<std::pair<int, int>> block_bounds_;
};

}  // namespace atlas
