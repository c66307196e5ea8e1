#include "pack/page_filling.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "pack/coarse_mask.hpp"
#include "pack/page_occupancy.hpp"

namespace atlas {
namespace {

// First guess of the packing density (set texels of the dilated masks / page
// texels) when sizing a page; the width search corrects it.
constexpr double kExpectedDensity = 0.8;
constexpr int kSquareProbes = 2;  // widths tried after the first one
constexpr double kSquareTolerance = 0.03;

// A page being filled: its texels, for drops, and the same on the hole grid
// (a cell is occupied when any of its texels is), for hole searches.
// With a gap padding the occupied texels are the charts before padding, so
// the extent of the padded charts (what the page must hold) is kept apart.
struct Page {
  PageOccupancy texels;
  PageOccupancy cells;
  int gap_padding;  // > 0: the padding is a gap, charts occupy their bare rasters
  Rest rest;
  PageSize extent = {0, 0};

  Page(int width, int height, const Frame& frame)
      : texels(width, height),
        cells(width / kHoleCell, height / kHoleCell),
        gap_padding(frame.gap ? frame.padding : 0),
        rest(frame.rest) {}
};

// Lowest spot in a hole for one orientation, with its top below top_limit.
// Cell spot (X, Y) is texel spot (kHoleCell X, kHoleCell Y): the chart's
// cells are aligned with the page's there, and free cells mean free texels.
std::optional<Eigen::Vector2i> spot_in_hole(const Page& page, const ScaledChart& chart, int turn,
                                            int top_limit) {
  const int room = top_limit - chart.turned[turn].mask.height;  // highest texel y allowed
  if (room < 0) return std::nullopt;
  const PlacementShape& cells = chart.cells[turn];
  const auto at = page.cells.first_fit(cells, room / kHoleCell + cells.mask.height);
  if (!at) return std::nullopt;
  return Eigen::Vector2i(*at * kHoleCell);
}

void occupy(Page& page, const ScaledChart& chart, int turn, Eigen::Vector2i at) {
  const TexelMask& padded = chart.turned[turn].mask;
  page.extent = {std::max(page.extent.width, at.x() + padded.width),
                 std::max(page.extent.height, at.y() + padded.height)};
  const TexelMask& mask = page.gap_padding > 0 ? chart.bare[turn] : padded;
  at += Eigen::Vector2i::Constant(page.gap_padding);
  page.texels.occupy(mask, at.x(), at.y());
  const TexelMask cells = coarsen_mask(mask, at.x(), at.y(), kHoleCell, page.cells.width(),
                                       page.cells.height());
  if (cells.width > 0) page.cells.occupy(cells, cells.origin_x, cells.origin_y);
}

int rest_row(const PlacementShape& shape, Rest rest) {
  return rest == Rest::Top ? shape.mask.height : shape.centroid_row;
}

// Every quarter turn is tried; the lowest spot by `rest` wins, if lower
// than `below` (the rest row). Each turn is dropped onto the horizon, then
// holes below are searched for a lower spot (always: skipping them for
// charts as large as one that lately found no hole saves little time and
// loses the holes that chart's shape missed).
std::optional<Placement> lowest_spot(const Page& page, const ScaledChart& chart, Rest rest,
                                     int below) {
  std::array<int, kTurns> turns;
  std::iota(turns.begin(), turns.end(), 0);
  std::stable_sort(turns.begin(), turns.end(), [&](int a, int b) {
    return chart.turned[a].mask.height < chart.turned[b].mask.height;
  });
  std::optional<Placement> best;
  // Spots resting below `below` end at most this high.
  auto top_limit = [&](int turn) {
    const PlacementShape& shape = chart.turned[turn];
    return below - 1 - rest_row(shape, rest) + shape.mask.height;
  };
  auto keep_if_lower = [&](int turn, const std::optional<Eigen::Vector2i>& at) {
    if (!at) return;
    best = Placement{0, at->x(), at->y(), turn};
    below = at->y() + rest_row(chart.turned[turn], rest);
  };
  for (int turn : turns)
    keep_if_lower(turn, page.texels.lowest_drop(chart.turned[turn], top_limit(turn)));
  for (int turn : turns) keep_if_lower(turn, spot_in_hole(page, chart, turn, top_limit(turn)));
  return best;
}

// Charts go where they rest lowest, by the page's Rest: the packed region
// stays low and compact.
bool place_chart(Page& page, const ScaledChart& chart, Placement& placement) {
  const auto spot = lowest_spot(page, chart, page.rest, page.texels.height() + 1);
  if (!spot) return false;
  occupy(page, chart, spot->turn, {spot->x, spot->y});
  placement.x = spot->x;
  placement.y = spot->y;
  placement.turn = spot->turn;
  return true;
}

int top_of(const ScaledChart& chart, const Placement& at) {
  return at.y + chart.turned[at.turn].mask.height;
}

// Extent of the charts of `order` at their placements, in virtual texels.
PageSize extent_of(const std::vector<int>& order, const std::vector<ScaledChart>& charts,
                   const std::vector<Placement>& placement) {
  PageSize used{0, 0};
  for (int c : order) {
    const TexelMask& mask = charts[c].turned[placement[c].turn].mask;
    used = {std::max(used.width, placement[c].x + mask.width),
            std::max(used.height, placement[c].y + mask.height)};
  }
  return used;
}

// A chart standing for its low centroid may set the page's height where
// lying down, elsewhere, it would not: the highest chart, if no other is as
// high, is moved to where its top ends lowest among the others, if that
// lowers the extent and widens it not. (The page is rebuilt without it:
// once more per move, so one move only, which is where the gain lies.)
void lower_highest_chart(const std::vector<int>& order, const std::vector<ScaledChart>& charts,
                         const Frame& frame, int width, int height,
                         std::vector<Placement>& placement, const RunControl& control) {
  if (order.empty()) return;
  control.throw_if_cancelled();
  int highest = order.front();
  for (int c : order)
    if (top_of(charts[c], placement[c]) > top_of(charts[highest], placement[highest])) highest = c;
  const int top = top_of(charts[highest], placement[highest]);
  for (int c : order)
    if (c != highest && top_of(charts[c], placement[c]) == top) return;
  Page page(width, height, frame);
  for (int c : order)
    if (c != highest) occupy(page, charts[c], placement[c].turn, {placement[c].x, placement[c].y});
  const auto spot = lowest_spot(page, charts[highest], Rest::Top, top);
  if (!spot) return;
  const PageSize used = extent_of(order, charts, placement);
  occupy(page, charts[highest], spot->turn, {spot->x, spot->y});
  if (page.extent.width > used.width || page.extent.height >= used.height) return;
  placement[highest].x = spot->x;
  placement[highest].y = spot->y;
  placement[highest].turn = spot->turn;
}

}  // namespace

long long area(const PageSize& page) { return static_cast<long long>(page.width) * page.height; }

std::vector<int> largest_first(const std::vector<ScaledChart>& charts, ChartSize size) {
  std::vector<int> order(charts.size());
  std::iota(order.begin(), order.end(), 0);
  auto key = [&](int c) -> long long {
    const TexelMask& m = charts[c].turned[0].mask;
    switch (size) {
      case ChartSize::BoxArea:
        break;
      case ChartSize::Texels:
        return charts[c].footprint;
      case ChartSize::LongSide:
        return std::max(m.width, m.height);
      case ChartSize::Perimeter:
        return m.width + m.height;
    }
    return static_cast<long long>(m.width) * m.height;
  };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return key(a) > key(b); });
  return order;
}

int allowed_side(double side, PageSides sides) {
  side = std::max(1.0, side) - 1e-9;
  switch (sides) {
    case PageSides::Tight:
      return static_cast<int>(std::ceil(side));
    case PageSides::MultipleOf4:
      return std::max(kSideQuantum, static_cast<int>(std::ceil(side / kSideQuantum)) * kSideQuantum);
    case PageSides::PowerOfTwo:
      break;
  }
  int p = 1;
  while (p < side) p *= 2;
  return p;
}

int largest_allowed_side(int max_side, PageSides sides) {
  if (sides == PageSides::Tight) return max_side;
  if (sides == PageSides::MultipleOf4) return max_side / kSideQuantum * kSideQuantum;
  int p = 1;
  while (2 * p <= max_side) p *= 2;
  return p;
}

PageSize trimmed_page(PageSize used, const Frame& frame) {
  PageSize page{allowed_side(used.width - 2 * frame.margin, frame.sides),
                allowed_side(used.height - 2 * frame.margin, frame.sides)};
  if (frame.square) page.width = page.height = std::max(page.width, page.height);
  return page;
}

std::optional<OnePage> pack_one_page(const std::vector<int>& order,
                                     const std::vector<ScaledChart>& charts, int width,
                                     int height, const Frame& frame, const RunControl& control,
                                     long long* placed_texels) {
  OnePage result;
  result.placement.resize(charts.size());
  Page page(width, height, frame);
  long long placed = 0;
  for (int c : order) {
    control.throw_if_cancelled();
    if (!place_chart(page, charts[c], result.placement[c])) {
      if (placed_texels) *placed_texels = placed;
      return std::nullopt;
    }
    placed += charts[c].footprint;
  }
  result.used = page.extent;
  return result;
}

namespace {

// What the charts of an order ask of a page: their dilated texels, the
// narrowest width that holds each of them and their longest side.
struct OrderNeeds {
  double dilated_texels = 0.0;
  int narrowest = 1;  // the page must be at least this wide in virtual texels
  int longest = 1;    // longest side of a chart, in virtual texels
};

OrderNeeds needs_of(const std::vector<int>& order, const std::vector<ScaledChart>& charts) {
  OrderNeeds needs;
  for (int c : order) {
    needs.dilated_texels += static_cast<double>(charts[c].footprint);
    const TexelMask& m = charts[c].turned[0].mask;
    needs.narrowest = std::max(needs.narrowest, std::min(m.width, m.height));
    needs.longest = std::max(needs.longest, std::max(m.width, m.height));
  }
  return needs;
}

// The charts of an order on one page of a chosen width, as tall as max_side
// allows: the tries of pack_smallest_page's width search.
struct WidthTrials {
  const std::vector<int>& order;
  const std::vector<ScaledChart>& charts;
  const Frame& frame;
  int max_side;
  const RunControl& control;
  double dilated_texels;  // of the order
  double* placed_share;   // if given: set by a failed try at max_side, see pack_smallest_page

  int to_virtual() const { return 2 * frame.margin; }

  // The allowed page width for `virtual_width` virtual texels, at most max_side.
  int width_for(double virtual_width) const {
    return std::min(max_side, allowed_side(virtual_width - to_virtual(), frame.sides));
  }

  // The charts on a page `width` wide, trimmed; nullopt when they do not fit.
  std::optional<Layout> pack(int width) const {
    long long placed = 0;
    auto page = pack_one_page(order, charts, width + to_virtual(), max_side + to_virtual(), frame,
                              control, &placed);
    if (!page) {
      if (placed_share && width == max_side)
        *placed_share = static_cast<double>(placed) / dilated_texels;
      return std::nullopt;
    }
    return Layout{std::move(page->placement), {trimmed_page(page->used, frame)}};
  }
};

// Replaces best (a layout) by candidate when that fits on a smaller page.
void keep_smaller(std::optional<Layout>& best, std::optional<Layout> candidate) {
  if (candidate && area(candidate->pages[0]) < area(best->pages[0])) best = std::move(candidate);
}

// The first page the charts fit: at the width kExpectedDensity predicts, or
// wider ones while that is too narrow for the height cap. `width` receives its width.
std::optional<Layout> first_fit(const WidthTrials& trials, int narrowest, int& width) {
  width = trials.width_for(
      std::max(narrowest, static_cast<int>(std::sqrt(trials.dilated_texels / kExpectedDensity))));
  std::optional<Layout> best = trials.pack(width);
  while (!best && width < trials.max_side) {  // too narrow for the height cap
    width = trials.width_for((width + trials.to_virtual()) * 1.25);
    best = trials.pack(width);
  }
  return best;
}

// Page width w gives height h(w); the next width tried is sqrt(w * h), the
// side of the square of equal area. Starts from best, packed `width` wide.
void probe_squarer(const WidthTrials& trials, int width, std::optional<Layout>& best) {
  int height = best->pages[0].height;
  for (int probe = 0; probe < kSquareProbes; ++probe) {
    const int next =
        trials.width_for(std::sqrt(static_cast<double>(width) * height) + trials.to_virtual());
    // Near enough to square: another probe would change the area by little.
    if (std::abs(next - width) <= std::max<double>(kSideQuantum, kSquareTolerance * width)) break;
    width = next;
    auto candidate = trials.pack(width);
    if (!candidate) break;
    height = candidate->pages[0].height;
    keep_smaller(best, std::move(candidate));
  }
}

// Widths the square probes do not look at, tried after them.
void try_other_widths(const WidthTrials& trials, const OrderNeeds& needs,
                      std::optional<Layout>& best) {
  // A chart longer than the page is wide stands in it, and the page is at
  // least as tall as that chart: a page as wide as it may hold it lying
  // down, on a smaller page (a large chart with a few smaller ones).
  if (trials.width_for(needs.longest) > best->pages[0].width)
    keep_smaller(best, trials.pack(trials.width_for(needs.longest)));
  // Power-of-two widths step by 2x, past what the square probes look at: the
  // neighbouring widths may hold the charts on half the page.
  if (trials.frame.sides == PageSides::PowerOfTwo) {
    const int chosen = best->pages[0].width;
    for (int other : {chosen / 2, chosen * 2}) {
      if (other + trials.to_virtual() < needs.narrowest || other > trials.max_side) continue;
      keep_smaller(best, trials.pack(other));
    }
  }
}

}  // namespace

// A first width assuming kExpectedDensity, then near-square probes and a few
// other widths; the smallest page wins.
std::optional<Layout> pack_smallest_page(const std::vector<int>& order,
                                         const std::vector<ScaledChart>& charts,
                                         const Frame& frame, int max_side,
                                         const RunControl& control, double* placed_share) {
  const int max_virtual = max_side + 2 * frame.margin;
  const OrderNeeds needs = needs_of(order, charts);
  if (placed_share) *placed_share = 0.0;
  if (needs.dilated_texels > static_cast<double>(max_virtual) * max_virtual) return std::nullopt;
  const WidthTrials trials{order, charts, frame, max_side, control, needs.dilated_texels,
                           placed_share};
  int width = 0;
  std::optional<Layout> best = first_fit(trials, needs.narrowest, width);
  if (!best) return std::nullopt;
  probe_squarer(trials, width, best);
  try_other_widths(trials, needs, best);
  return best;
}

void lower_single_page(Layout& layout, const std::vector<ScaledChart>& charts, const Frame& frame,
                       const RunControl& control) {
  if (layout.pages.size() != 1) return;
  std::vector<int> all(charts.size());
  std::iota(all.begin(), all.end(), 0);
  const PageSize page = layout.pages[0];
  lower_highest_chart(all, charts, frame, page.width + 2 * frame.margin,
                      page.height + 2 * frame.margin, layout.placement, control);
  layout.pages[0] = trimmed_page(extent_of(all, charts, layout.placement), frame);
}

Layout pack_many_pages(const std::vector<int>& order, const std::vector<ScaledChart>& charts,
                       const Frame& frame, int max_side, const RunControl& control) {
  const int side = max_side + 2 * frame.margin;
  Layout layout;
  layout.placement.resize(charts.size());
  std::vector<Page> pages;
  for (int c : order) {
    control.throw_if_cancelled();
    Placement& placement = layout.placement[c];
    for (placement.page = 0; placement.page < static_cast<int>(pages.size()); ++placement.page)
      if (place_chart(pages[placement.page], charts[c], placement)) break;
    if (placement.page == static_cast<int>(pages.size())) {
      pages.emplace_back(side, side, frame);
      if (!place_chart(pages.back(), charts[c], placement))
        throw std::logic_error("pack_many_pages: a chart is larger than an empty page");
    }
  }
  for (const Page& page : pages)
    layout.pages.push_back(
        trimmed_page(page.extent, frame));

  const int last = static_cast<int>(pages.size()) - 1;
  std::vector<int> last_order;
  for (int c : order)
    if (layout.placement[c].page == last) last_order.push_back(c);
  if (auto small = pack_smallest_page(last_order, charts, frame, max_side, control)) {
    for (int c : last_order) {
      layout.placement[c] = small->placement[c];
      layout.placement[c].page = last;
    }
    layout.pages[last] = small->pages[0];
  }
  return layout;
}

}  // namespace atlas
