#include "page_occupancy.hpp"

#include <algorithm>
#include <cstdlib>

namespace atlas {
namespace {

constexpr int kBlock = 64;  // rows / columns summarised together
// Rows of holes fully examined per search before settling for the drop: hole
// filling gains a few percent of page area, an unbounded scan costs a pass
// over the whole page for every chart.
constexpr int kHoleRowBudget = 32;

// Keeps the offsets x of `candidates` at which the chart run lies inside one
// free run f: f.begin <= x + run.begin and x + run.end <= f.end, i.e.
// x in [f.begin - run.begin, f.end - run.end]. Both lists are sorted and
// disjoint, so this is a single merge.
void keep_offsets_inside(const std::vector<Span>& free_runs, Span run,
                         const std::vector<Span>& candidates, std::vector<Span>& kept) {
  kept.clear();
  const int length = run.end - run.begin;
  // Free runs ending before the first candidate can reach them cannot help.
  auto f = std::lower_bound(free_runs.begin(), free_runs.end(), candidates.front().begin + run.end,
                            [](const Span& s, int end) { return s.end < end; });
  auto c = candidates.begin();
  while (f != free_runs.end() && c != candidates.end()) {
    if (f->end - f->begin < length) {
      ++f;
      continue;
    }
    const int allowed_end = f->end - run.end + 1;
    const int lo = std::max(c->begin, f->begin - run.begin), hi = std::min(c->end, allowed_end);
    if (lo < hi) kept.push_back({lo, hi});
    if (allowed_end < c->end)
      ++f;
    else
      ++c;
  }
}

}  // namespace

PageOccupancy::PageOccupancy(int width, int height)
    : width_(width),
      height_(height),
      words_per_row_((width + 63) / 64),
      longest_free_run_(height, width),
      block_longest_free_run_((height + kBlock - 1) / kBlock, width),
      horizon_(width, 0),
      block_lowest_horizon_((width + kBlock - 1) / kBlock, 0) {}

std::optional<Eigen::Vector2i> PageOccupancy::find_spot(const PlacementShape& shape,
                                                        int top_limit) const {
  if (shape.mask.width > width_) return std::nullopt;
  const auto drop = lowest_drop(shape, top_limit);
  // Only a hole strictly lower than the drop is worth taking.
  const int hole_limit = drop ? drop->y() + shape.mask.height - 1 : top_limit;
  if (const auto hole = first_fit_in_holes(shape, hole_limit)) return hole;
  return drop;
}

// Everything above the horizon is free, so the shape dropped at column x
// rests at y(x) = max over its columns i of horizon[x + i] - column_bottom[i].
// Any subset of columns bounds y(x) from below; with the lowest horizon per
// block of columns this bounds a whole block of x at once. Blocks are visited
// by increasing bound and the search stops when no block can beat the best.
std::optional<Eigen::Vector2i> PageOccupancy::lowest_drop(const PlacementShape& shape,
                                                          int top_limit) const {
  const int x_count = width_ - shape.mask.width + 1;
  const int blocks = (x_count + kBlock - 1) / kBlock, last_block = (width_ - 1) / kBlock;
  std::vector<std::pair<int, int>>& bounds = block_bounds_;  // (bound, block)
  bounds.clear();
  for (int b = 0; b < blocks; ++b) {
    int bound = 0;
    for (int i : shape.key_columns) {
      const int lowest = std::min(block_lowest_horizon_[b + i / kBlock],
                                  block_lowest_horizon_[std::min(last_block, b + (i + kBlock - 1) / kBlock)]);
      bound = std::max(bound, lowest - shape.column_bottom[i]);
    }
    bounds.push_back({bound, b});
  }
  std::sort(bounds.begin(), bounds.end());
  int best_y = std::min(height_, top_limit) - shape.mask.height + 1, best_x = -1;
  for (const auto& [bound, b] : bounds) {
    if (bound >= best_y) break;
    for (int x = b * kBlock; x < std::min(x_count, (b + 1) * kBlock); ++x) {
      int y = bound;
      for (int i : shape.column_order) {
        y = std::max(y, horizon_[x + i] - shape.column_bottom[i]);
        if (y >= best_y) break;
      }
      if (y < best_y) {
        best_y = y;
        best_x = x;
      }
    }
  }
  if (best_x < 0) return std::nullopt;
  return Eigen::Vector2i(best_x, best_y);
}

// A spot below top_limit, found by scanning rows downwards from there: the
// holes just under the horizon are the freshest and largest. Rows are first
// filtered in O(1) by their longest free runs; at most kHoleRowBudget rows
// that pass are scanned in full.
std::optional<Eigen::Vector2i> PageOccupancy::first_fit_in_holes(const PlacementShape& shape,
                                                                 int top_limit) const {
  const int widest = shape.widest_row;
  static const int kb = getenv("HB") ? atoi(getenv("HB")) : kHoleRowBudget; int budget = kb;
  for (int y = std::min(height_, top_limit) - shape.mask.height; y >= 0; --y) {
    // The widest chart run needs a free run at least as long under it.
    const int row = previous_row_with_free_run(y + widest, shape.longest_run[widest]);
    if (row < widest) return std::nullopt;
    y = row - widest;
    if (!rows_have_long_free_runs(shape, y)) continue;
    if (budget-- == 0) return std::nullopt;
    const int x = leftmost_fit_in_row(shape, y);
    if (x >= 0) return Eigen::Vector2i(x, y);
  }
  return std::nullopt;
}

// Leftmost x at which the shape fits with its bottom on row y, or -1. Starts
// from every x keeping the mask on the page and keeps, run by run, the offsets
// at which that run lies on free texels (exact: the runs are the whole mask).
int PageOccupancy::leftmost_fit_in_row(const PlacementShape& shape, int y) const {
  candidates_.assign(1, {0, width_ - shape.mask.width + 1});
  const int stored_rows = std::min(shape.mask.height, used_height_ - y);  // rows above are free
  for (int r : shape.row_order) {
    if (r >= stored_rows) continue;
    for (int i = shape.row_start[r]; i < shape.row_start[r + 1]; ++i) {
      keep_offsets_inside(free_runs_[y + r], shape.runs[i], candidates_, kept_);
      candidates_.swap(kept_);
      if (candidates_.empty()) return -1;
    }
  }
  return candidates_.front().begin;
}

// Necessary for a fit at row y, and O(1) per row: each page row has a free
// run at least as long as the longest run of the chart row over it.
bool PageOccupancy::rows_have_long_free_runs(const PlacementShape& shape, int y) const {
  const int stored_rows = std::min(shape.mask.height, used_height_ - y);
  for (int r : shape.row_order)
    if (r < stored_rows && longest_free_run_[y + r] < shape.longest_run[r]) return false;
  return true;
}

// Last row <= from whose longest free run is >= length, or -1.
int PageOccupancy::previous_row_with_free_run(int from, int length) const {
  for (int row = std::min(from, height_ - 1); row >= 0;) {
    if (row % kBlock == kBlock - 1 && block_longest_free_run_[row / kBlock] < length) {
      row -= kBlock;
      continue;
    }
    if (longest_free_run_[row] >= length) return row;
    --row;
  }
  return -1;
}

void PageOccupancy::occupy(const PlacementShape& shape, int x, int y) {
  const TexelMask& mask = shape.mask;
  if (y + mask.height > used_height_) {
    used_height_ = y + mask.height;
    words_.resize(static_cast<size_t>(used_height_) * words_per_row_, 0);
    free_runs_.resize(used_height_, std::vector<Span>{{0, width_}});
  }
  used_width_ = std::max(used_width_, x + mask.width);
  const int shift = x & 63, base = x >> 6;
  for (int r = 0; r < mask.height; ++r) {
    std::uint64_t* page = words_.data() + static_cast<size_t>(y + r) * words_per_row_;
    const std::uint64_t* bits = mask.row(r);
    for (int k = 0; k < mask.words_per_row; ++k) {
      page[base + k] |= bits[k] << shift;
      if (shift && base + k + 1 < words_per_row_) page[base + k + 1] |= bits[k] >> (64 - shift);
    }
    update_row(y + r);
  }
  for (int b = y / kBlock; b <= (y + mask.height - 1) / kBlock; ++b) {
    const auto first = longest_free_run_.begin() + b * kBlock;
    const auto last = longest_free_run_.begin() + std::min(height_, (b + 1) * kBlock);
    block_longest_free_run_[b] = *std::max_element(first, last);
  }
  for (int i = 0; i < mask.width; ++i)
    horizon_[x + i] = std::max(horizon_[x + i], y + shape.column_top[i]);
  for (int b = x / kBlock; b <= (x + mask.width - 1) / kBlock; ++b) {
    const auto first = horizon_.begin() + b * kBlock;
    const auto last = horizon_.begin() + std::min(width_, (b + 1) * kBlock);
    block_lowest_horizon_[b] = *std::min_element(first, last);
  }
}

// Rebuilds the free runs of stored row y from its bits.
void PageOccupancy::update_row(int y) {
  const std::uint64_t* row = words_.data() + static_cast<size_t>(y) * words_per_row_;
  std::vector<Span>& runs = free_runs_[y];
  runs.clear();
  int longest = 0;
  for (int x = find_bit(row, 0, width_, false); x < width_;) {
    const int end = find_bit(row, x, width_, true);
    runs.push_back({x, end});
    longest = std::max(longest, end - x);
    x = find_bit(row, end, width_, false);
  }
  longest_free_run_[y] = longest;
}

}  // namespace atlas
