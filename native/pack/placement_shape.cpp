#include "pack/placement_shape.hpp"

#include <algorithm>

namespace atlas {
namespace {

constexpr int kKeyColumns = 8;

// Runs of every row, their count and, per row, the longest one.
void collect_runs(const TexelMask& mask, PlacementShape& shape, std::vector<Span>& longest) {
  shape.row_start.reserve(mask.height + 1);
  long long row_sum = 0;  // over set texels, of their row
  for (int r = 0; r < mask.height; ++r) {
    shape.row_start.push_back(static_cast<int>(shape.runs.size()));
    const std::uint64_t* row = mask.row(r);
    longest.push_back({0, 0});
    for (int x = find_bit(row, 0, mask.width, true); x < mask.width;) {
      const int end = find_bit(row, x, mask.width, false);
      shape.runs.push_back({x, end});
      shape.texels += end - x;
      row_sum += static_cast<long long>(end - x) * r;
      if (end - x > longest[r].end - longest[r].begin) longest[r] = {x, end};
      x = find_bit(row, end, mask.width, true);
    }
    shape.longest_run.push_back(longest[r].end - longest[r].begin);
    if (shape.longest_run[r] > shape.longest_run[shape.widest_row]) shape.widest_row = r;
  }
  shape.row_start.push_back(static_cast<int>(shape.runs.size()));
  if (shape.texels > 0) shape.centroid_row = static_cast<int>(row_sum / shape.texels);
}

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
void find_core_rectangle(const std::vector<Span>& longest, PlacementShape& shape) {
  const int h = static_cast<int>(longest.size());
  int lo = shape.widest_row, hi = shape.widest_row;
  Span span = longest[lo];
  long long best_area = 0;
  auto overlap = [](Span a, Span b) {
    return Span{std::max(a.begin, b.begin), std::min(a.end, b.end)};
  };
  while (span.end > span.begin) {
    const long long area = static_cast<long long>(span.end - span.begin) * (hi - lo + 1);
    if (area > best_area) {
      best_area = area;
      shape.core_columns = span;
      shape.core_bottom = lo;
      shape.core_height = hi - lo + 1;
    }
    const Span below = lo > 0 ? overlap(span, longest[lo - 1]) : Span{0, 0};
    const Span above = hi + 1 < h ? overlap(span, longest[hi + 1]) : Span{0, 0};
    if (below.end - below.begin >= above.end - above.begin) {
      span = below;
      --lo;
    } else {
      span = above;
      ++hi;
    }
  }
}

// Lower outline, its columns lowest first, and a few columns for bounds: the
// lowest one plus ones spread evenly over the set columns.
void find_lower_outline(const TexelMask& mask, PlacementShape& shape) {
  shape.column_bottom = first_set_row_per_column(mask, false);
  std::vector<int> set_columns;
  for (int x = 0; x < mask.width; ++x) {
    if (shape.column_bottom[x] < 0)
      shape.column_bottom[x] = mask.height;
    else
      set_columns.push_back(x);
  }
  shape.column_order = set_columns;
  std::stable_sort(shape.column_order.begin(), shape.column_order.end(),
                   [&](int a, int b) { return shape.column_bottom[a] < shape.column_bottom[b]; });
  shape.key_columns.push_back(shape.column_order.front());
  const size_t last = set_columns.size() - 1;
  for (int k = 0; k < kKeyColumns; ++k)
    shape.key_columns.push_back(set_columns[k * last / (kKeyColumns - 1)]);
}

}  // namespace

PlacementShape make_placement_shape(TexelMask mask) {
  PlacementShape shape;
  std::vector<Span> longest;  // per row
  collect_runs(mask, shape, longest);
  shape.row_order = spread_row_order(mask.height, shape.widest_row);
  find_core_rectangle(longest, shape);
  find_lower_outline(mask, shape);
  shape.mask = std::move(mask);
  return shape;
}

}  // namespace atlas
