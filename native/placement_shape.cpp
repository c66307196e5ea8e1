#include "placement_shape.hpp"

#include <algorithm>
#include <numeric>

namespace atlas {
namespace {

constexpr size_t kKeyColumns = 8;

// Widest row first, then rows spread over the height (0, h-1, h/2, h/4,
// 3h/4, ...): an obstacle anywhere under the chart is met after few tests.
std::vector<int> spread_row_order(int height, int widest_row) {
  std::vector<int> order;
  std::vector<char> queued(height, 0);
  auto queue = [&](int r) {
    if (r < height && !queued[r]) {
      queued[r] = 1;
      order.push_back(r);
    }
  };
  queue(widest_row);
  queue(0);
  queue(height - 1);
  int step = 1;
  while (2 * step < height) step *= 2;
  for (; step >= 1; step /= 2)
    for (int r = step; r < height; r += 2 * step) queue(r);
  return order;
}

// Grows a rectangle from the widest row's longest run one row at a time,
// towards whichever neighbour row keeps it wider, and keeps the largest area
// seen. Each row contributes its longest run, so the rectangle is all set.
void find_core_rectangle(const std::vector<Span>& longest_span, int widest_row,
                         PlacementShape& shape) {
  const int h = static_cast<int>(longest_span.size());
  int lo = widest_row, hi = widest_row;
  Span span = longest_span[widest_row];
  long long best_area = 0;
  auto overlap = [](Span a, Span b) { return Span{std::max(a.begin, b.begin), std::min(a.end, b.end)}; };
  while (span.end > span.begin) {
    const long long area = static_cast<long long>(span.end - span.begin) * (hi - lo + 1);
    if (area > best_area) {
      best_area = area;
      shape.core_columns = span;
      shape.core_bottom = lo;
      shape.core_height = hi - lo + 1;
    }
    const Span below = lo > 0 ? overlap(span, longest_span[lo - 1]) : Span{0, 0};
    const Span above = hi + 1 < h ? overlap(span, longest_span[hi + 1]) : Span{0, 0};
    if (below.end - below.begin >= above.end - above.begin) {
      span = below;
      --lo;
    } else {
      span = above;
      ++hi;
    }
  }
}

// For each column, the first row (in the order `rows` visits them) holding a
// set texel; every set bit is looked at once, as the first time it appears.
template <class RowRange, class Record>
void first_row_per_column(const TexelMask& mask, RowRange rows, Record record) {
  std::vector<std::uint64_t> seen(mask.words_per_row, 0);
  for (int r : rows) {
    const std::uint64_t* row = mask.row(r);
    for (int k = 0; k < mask.words_per_row; ++k) {
      for (std::uint64_t fresh = row[k] & ~seen[k]; fresh; fresh &= fresh - 1)
        record((k << 6) + count_trailing_zeros(fresh), r);
      seen[k] |= row[k];
    }
  }
}

}  // namespace

PlacementShape make_placement_shape(TexelMask mask) {
  PlacementShape shape;
  const int h = mask.height;
  shape.row_start.reserve(h + 1);
  std::vector<Span> longest_span;  // per row
  for (int r = 0; r < h; ++r) {
    shape.row_start.push_back(static_cast<int>(shape.runs.size()));
    const std::uint64_t* row = mask.row(r);
    Span longest = {0, 0};
    for (int x = find_bit(row, 0, mask.width, true); x < mask.width;) {
      const int end = find_bit(row, x, mask.width, false);
      shape.runs.push_back({x, end});
      shape.texels += end - x;
      if (end - x > longest.end - longest.begin) longest = {x, end};
      x = find_bit(row, end, mask.width, true);
    }
    longest_span.push_back(longest);
    shape.longest_run.push_back(longest.end - longest.begin);
    if (shape.longest_run[r] > shape.longest_run[shape.widest_row]) shape.widest_row = r;
  }
  shape.row_start.push_back(static_cast<int>(shape.runs.size()));
  shape.row_order = spread_row_order(h, shape.widest_row);
  find_core_rectangle(longest_span, shape.widest_row, shape);

  std::vector<int> bottom_up(h);
  std::iota(bottom_up.begin(), bottom_up.end(), 0);
  const std::vector<int> top_down(bottom_up.rbegin(), bottom_up.rend());
  shape.column_bottom.assign(mask.width, h);
  shape.column_top.assign(mask.width, 0);
  first_row_per_column(mask, bottom_up, [&](int x, int r) { shape.column_bottom[x] = r; });
  first_row_per_column(mask, top_down, [&](int x, int r) { shape.column_top[x] = r + 1; });
  for (int x = 0; x < mask.width; ++x)
    if (shape.column_bottom[x] < h) shape.column_order.push_back(x);
  std::stable_sort(shape.column_order.begin(), shape.column_order.end(),
                   [&](int a, int b) { return shape.column_bottom[a] < shape.column_bottom[b]; });
  // The lowest column plus ones spread evenly over the set columns.
  std::vector<int> set_columns = shape.column_order;
  std::sort(set_columns.begin(), set_columns.end());
  if (!set_columns.empty()) shape.key_columns.push_back(shape.column_order.front());
  for (size_t k = 0; k < kKeyColumns && !set_columns.empty(); ++k)
    shape.key_columns.push_back(set_columns[k * (set_columns.size() - 1) / (kKeyColumns - 1)]);
  shape.mask = std::move(mask);
  return shape;
}

}  // namespace atlas
