#include "pack/page_occupancy.hpp"

#include <algorithm>
#include <cmath>

namespace atlas {
namespace {

constexpr int kBlock = 64;            // rows / columns summarised together
constexpr int kRectangleClasses = 40; // free rectangle sides 2^(k/2), k < 40
constexpr int kBoundingClasses = 64;  // bounding box sides 2^(k/4), k < 64

// Rectangle size class of a side: the largest k with rectangle_side(k) <= side.
int rectangle_class(int side) {
  return std::min(kRectangleClasses - 1, static_cast<int>(2.0 * std::log2(side)));
}
int rectangle_side(int k) { return static_cast<int>(std::pow(2.0, 0.5 * k)); }

int bounding_class(const TexelMask& mask) {
  auto side_class = [](int side) {
    return std::min(kBoundingClasses - 1, static_cast<int>(4.0 * std::log2(side)));
  };
  return side_class(mask.width) * kBoundingClasses + side_class(mask.height);
}

// Shortest run listed in run tier k, and the tier to search for a run.
int tier_length(int tier) { return 1 << (2 * tier); }
int tier_for(int length, int tiers) {
  int tier = 0;
  while (tier + 1 < tiers && tier_length(tier + 1) <= length) ++tier;
  return tier;
}

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

// Replaces the runs meeting [lo, hi) by the runs of `fresh` (which lies
// inside it) at least min_length long. They overwrite the old ones in place,
// so the runs after them move once at most (a placed run splits a free run
// in two, or removes one).
void replace_runs(std::vector<Span>& runs, int lo, int hi, const std::vector<Span>& fresh,
                  int min_length) {
  auto first = std::lower_bound(runs.begin(), runs.end(), lo,
                                [](const Span& s, int x) { return s.end <= x; });
  auto last = std::lower_bound(first, runs.end(), hi,
                               [](const Span& s, int x) { return s.begin < x; });
  for (const Span& s : fresh) {
    if (s.end - s.begin < min_length) continue;
    if (first != last) {
      *first++ = s;
    } else {
      first = last = std::next(runs.insert(first, s));
    }
  }
  runs.erase(first, last);
}

}  // namespace

PageOccupancy::PageOccupancy(int width, int height)
    : width_(width),
      height_(height),
      words_per_row_((width + 63) / 64),
      longest_free_run_(height, width),
      block_longest_free_run_((height + kBlock - 1) / kBlock, width),
      horizon_(width, 0),
      block_lowest_horizon_((width + kBlock - 1) / kBlock, 0),
      rectangle_floor_(kRectangleClasses * kRectangleClasses, 0),
      resume_row_(kBoundingClasses * kBoundingClasses, 0) {}

// Everything above the horizon is free, so the shape dropped at column x
// rests at y(x) = max over its columns i of horizon[x + i] - column_bottom[i].
// Any subset of columns bounds y(x) from below; with the lowest horizon per
// block of columns this bounds a whole block of x at once. Blocks are visited
// by increasing bound and the search stops when no block can beat the best.
std::optional<Eigen::Vector2i> PageOccupancy::lowest_drop(const PlacementShape& shape,
                                                          int top_limit) const {
  if (shape.mask.width > width_) return std::nullopt;
  const int x_count = width_ - shape.mask.width + 1;
  const int last_block = (width_ - 1) / kBlock;
  block_bounds_.clear();
  for (int b = 0; b * kBlock < x_count; ++b) {
    int bound = 0;
    for (int i : shape.key_columns) {
      // Columns x + i for x in block b lie in these two horizon blocks.
      const int lowest =
          std::min(block_lowest_horizon_[b + i / kBlock],
                   block_lowest_horizon_[std::min(last_block, b + (i + kBlock - 1) / kBlock)]);
      bound = std::max(bound, lowest - shape.column_bottom[i]);
    }
    block_bounds_.push_back({bound, b});
  }
  std::sort(block_bounds_.begin(), block_bounds_.end());
  int best_y = std::min(height_, top_limit) - shape.mask.height + 1, best_x = -1;
  for (const auto& [bound, b] : block_bounds_) {
    if (bound >= best_y) break;
    // The column that ruled a spot out usually rules out the next one too:
    // it is tested first.
    int blocker = shape.column_order.front();
    for (int x = b * kBlock; x < std::min(x_count, (b + 1) * kBlock); ++x) {
      int y = std::max(bound, horizon_[x + blocker] - shape.column_bottom[blocker]);
      for (size_t k = 0; y < best_y && k < shape.column_order.size(); ++k) {
        const int i = shape.column_order[k];
        y = std::max(y, horizon_[x + i] - shape.column_bottom[i]);
        if (y >= best_y) blocker = i;
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

// Rows are first filtered in O(1) by their longest free runs, and only rows
// that pass are tested exactly. Rows above the stored ones are free, so the
// scan ends there at the latest.
std::optional<Eigen::Vector2i> PageOccupancy::first_fit(const PlacementShape& shape,
                                                        int top_limit) const {
  if (shape.mask.width > width_) return std::nullopt;
  const int y_last = std::min(height_, top_limit) - shape.mask.height;
  const int widest = shape.widest_row;
  int& resume = resume_row_[bounding_class(shape.mask)];
  for (int y = std::max(resume, core_floor(shape) - shape.core_bottom); y <= y_last; ++y) {
    // The widest chart run needs a free run at least as long under it.
    const int row = next_row_with_free_run(y + widest, shape.longest_run[widest]);
    if (row < 0 || row - widest > y_last) break;
    y = row - widest;
    if (!rows_have_long_free_runs(shape, y)) continue;
    const int x = leftmost_fit_in_row(shape, y);
    if (x >= 0) {
      resume = y;
      return Eigen::Vector2i(x, y);
    }
  }
  resume = std::max(resume, y_last + 1);
  return std::nullopt;
}

// Lowest row on which a free rectangle as large as the shape's core could
// stand. Sides are rounded down to a size class (2^(k/2)) so that the answer
// is cached and reused by later charts; a class's floor is at least those of
// the classes one step smaller in either side.
int PageOccupancy::core_floor(const PlacementShape& shape) const {
  const int w_class = rectangle_class(shape.core_columns.end - shape.core_columns.begin);
  const int h_class = rectangle_class(shape.core_height);
  int& floor = rectangle_floor_[w_class * kRectangleClasses + h_class];
  if (w_class > 0)
    floor = std::max(floor, rectangle_floor_[(w_class - 1) * kRectangleClasses + h_class]);
  if (h_class > 0)
    floor = std::max(floor, rectangle_floor_[w_class * kRectangleClasses + h_class - 1]);
  floor = next_free_rectangle_row(rectangle_side(w_class), rectangle_side(h_class), floor);
  return floor;
}

// Lowest row >= from on which a free width x height rectangle stands (rows
// above the stored ones are free). A row under the rectangle without a free
// run that long rules out every bottom row up to it.
int PageOccupancy::next_free_rectangle_row(int width, int height, int from) const {
  const Span run = {0, width};
  const int tier = tier_for(width, kRunTiers);
  for (int y = from; y < used_height_;) {
    const int rows = std::min(height, used_height_ - y);
    int blocked = rows - 1;
    while (blocked >= 0 && longest_free_run_[y + blocked] >= width) --blocked;
    if (blocked >= 0) {
      y += blocked + 1;
      continue;
    }
    candidates_.assign(1, {0, width_ - width + 1});
    for (int r = 0; r < rows && !candidates_.empty(); ++r) {
      keep_offsets_inside(rows_[y + r][tier], run, candidates_, kept_);
      candidates_.swap(kept_);
    }
    if (!candidates_.empty()) return y;
    ++y;
  }
  return std::max(from, used_height_);
}

// Leftmost x at which the shape fits with its bottom on row y, or -1. Starts
// from every x keeping the mask on the page and keeps, run by run, the offsets
// at which that run lies on free texels (exact: the runs are the whole mask).
int PageOccupancy::leftmost_fit_in_row(const PlacementShape& shape, int y) const {
  candidates_.assign(1, {0, width_ - shape.mask.width + 1});
  const int stored_rows = std::min(shape.mask.height, used_height_ - y);  // rows above are free
  for (int r : shape.row_order) {
    if (r >= stored_rows) continue;
    const FreeRow& row = rows_[y + r];
    for (int i = shape.row_start[r]; i < shape.row_start[r + 1]; ++i) {
      const Span run = shape.runs[i];
      keep_offsets_inside(row[tier_for(run.end - run.begin, kRunTiers)], run, candidates_, kept_);
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

// First row >= from whose longest free run is >= length, or -1.
int PageOccupancy::next_row_with_free_run(int from, int length) const {
  for (int row = from; row < height_;) {
    if (row % kBlock == 0 && block_longest_free_run_[row / kBlock] < length) {
      row += kBlock;
      continue;
    }
    if (longest_free_run_[row] >= length) return row;
    ++row;
  }
  return -1;
}

void PageOccupancy::occupy(const TexelMask& mask, int x, int y) {
  if (y + mask.height > used_height_) {
    used_height_ = y + mask.height;
    words_.resize(static_cast<size_t>(used_height_) * words_per_row_, 0);
    FreeRow empty;
    empty.fill({{0, width_}});
    rows_.resize(used_height_, empty);
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
    update_row(y + r, x, x + mask.width);
  }
  for (int b = y / kBlock; b <= (y + mask.height - 1) / kBlock; ++b) {
    const auto first = longest_free_run_.begin() + b * kBlock;
    const auto last = longest_free_run_.begin() + std::min(height_, (b + 1) * kBlock);
    block_longest_free_run_[b] = *std::max_element(first, last);
  }
  update_horizon(mask, x, y);
}

// Row y changed inside [x_begin, x_end): rebuilds only the free runs that met
// that range, from the row's bits.
void PageOccupancy::update_row(int y, int x_begin, int x_end) {
  FreeRow& row = rows_[y];
  const std::vector<Span>& all = row[0];
  const auto first = std::lower_bound(all.begin(), all.end(), x_begin,
                                      [](const Span& s, int x) { return s.end <= x; });
  const auto last = std::lower_bound(first, all.end(), x_end,
                                     [](const Span& s, int x) { return s.begin < x; });
  if (first == last) return;
  const int lo = first->begin, hi = std::prev(last)->end;
  bool lost_longest = false;
  for (auto s = first; s != last; ++s) lost_longest |= s->end - s->begin == longest_free_run_[y];

  const std::uint64_t* bits = words_.data() + static_cast<size_t>(y) * words_per_row_;
  std::vector<Span>& fresh = kept_;
  fresh.clear();
  for (int x = find_bit(bits, lo, hi, false); x < hi;) {
    const int end = find_bit(bits, x, hi, true);
    fresh.push_back({x, end});
    x = find_bit(bits, end, hi, false);
  }
  for (int tier = 0; tier < kRunTiers; ++tier)
    replace_runs(row[tier], lo, hi, fresh, tier_length(tier));
  // Runs only shrink, so the longest changes only if one of the longest went.
  if (lost_longest) {
    int longest = 0;
    for (const Span& s : all) longest = std::max(longest, s.end - s.begin);
    longest_free_run_[y] = longest;
  }
}

void PageOccupancy::update_horizon(const TexelMask& mask, int x, int y) {
  const std::vector<int> top = first_set_row_per_column(mask, true);
  for (int i = 0; i < mask.width; ++i)
    if (top[i] >= 0) horizon_[x + i] = std::max(horizon_[x + i], y + top[i] + 1);
  for (int b = x / kBlock; b <= (x + mask.width - 1) / kBlock; ++b) {
    const auto first = horizon_.begin() + b * kBlock;
    const auto last = horizon_.begin() + std::min(width_, (b + 1) * kBlock);
    block_lowest_horizon_[b] = *std::min_element(first, last);
  }
}

}  // namespace atlas
