#include "pack.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <sstream>
#include <cstdio>

#include "chart_raster.hpp"
#include "coarse_mask.hpp"
#include "page_occupancy.hpp"

namespace atlas {
namespace {

constexpr int kSideQuantum = 4;  // page sides are rounded up to multiples of this
// First guess of packing density when sizing a page; the width search corrects it.
constexpr double kExpectedDensity = 0.8;
constexpr int kSquareProbes = 2;  // widths tried after the first to make the default page square
constexpr double kSquareTolerance = 0.03;
constexpr int kScaleBisections = 8;     // fixed page / budget scale search steps
constexpr int kMaxShrinkAttempts = 24;  // budget: give up after this many shrinks
constexpr double kScaleTolerance = 1.005;
// Holes are searched on a grid of kHoleCell x kHoleCell texel cells: 16x less
// work than texel by texel, at the price of spots on multiples of 4 texels.
constexpr int kHoleCell = 4;
// A chart that found no hole rules out holes for charts of >= this fraction
// of its texels on that page; charts come largest first, so holes are tried
// again each time charts have shrunk by another 10%.
constexpr double kHoleMissMargin = 0.9;

// Pages are packed in a virtual frame reaching `margin` = padding / 2 texels
// beyond every border: dilated masks must stay inside it, so a chart's own
// texels keep padding - margin >= padding / 2 texels from the border. Pages
// wrap when sampled, so the two borders together still give a full padding.
struct Frame {
  int padding = 0;
  int margin = 0;
};

// One chart rasterised at the current scale, in both orientations.
struct ScaledChart {
  std::array<PlacementShape, 2> turned;  // dilated masks at 0 and 90 degrees
  std::array<PlacementShape, 2> cells;   // the same on the hole grid
  std::array<Eigen::RowVector2d, 2> shift = {Eigen::RowVector2d::Zero(),
                                             Eigen::RowVector2d::Zero()};  // whole texels
  std::array<long long, 2> texels = {0, 0};                                // before dilation
};

// Where a chart went: its dilated mask's texel (0, 0) sits at (x, y) of the
// page's virtual frame.
struct Placement {
  int page = 0;
  int x = 0, y = 0;
  int turn = 0;  // 1: rotated 90 degrees counter-clockwise
};

struct Layout {
  std::vector<Placement> placement;  // per chart
  std::vector<PageSize> pages;
};

struct Packing {
  double scale = 1.0;
  std::vector<ScaledChart> charts;
  Layout layout;
};

int round_up_to_quantum(double side) {
  return std::max(kSideQuantum,
                  static_cast<int>(std::ceil(side / kSideQuantum - 1e-9)) * kSideQuantum);
}

long long page_texels(const std::vector<PageSize>& pages) {
  long long total = 0;
  for (const PageSize& p : pages) total += static_cast<long long>(p.width) * p.height;
  return total;
}

void require_valid(const std::vector<RowMatrixX2d>& chart_uv, const PackOptions& o) {
  std::ostringstream msg;
  if (!(o.density_scale > 0.0 && std::isfinite(o.density_scale)))
    msg << "density_scale must be positive and finite, got " << o.density_scale;
  else if (o.padding < 0)
    msg << "padding must be >= 0, got " << o.padding;
  else if (o.max_page_size < kSideQuantum)
    msg << "max_page_size must be >= " << kSideQuantum << ", got " << o.max_page_size;
  else if (o.fixed_page_size < 0)
    msg << "fixed_page_size must be >= 0, got " << o.fixed_page_size;
  else if (o.texel_budget < 0)
    msg << "texel_budget must be >= 0, got " << o.texel_budget;
  else if (o.fixed_page_size > 0 && o.texel_budget > 0 &&
           static_cast<long long>(o.fixed_page_size) * o.fixed_page_size > o.texel_budget)
    msg << "fixed_page_size " << o.fixed_page_size << " exceeds texel_budget " << o.texel_budget;
  else if (o.fixed_page_size == 0 && o.texel_budget > 0 &&
           o.texel_budget < kSideQuantum * kSideQuantum)
    msg << "texel_budget must hold at least one " << kSideQuantum << "x" << kSideQuantum
        << " page, got " << o.texel_budget;
  for (size_t c = 0; msg.tellp() == 0 && c < chart_uv.size(); ++c)
    if (chart_uv[c].rows() % 3 != 0)
      msg << "chart " << c << " must hold 3 corners per face, got " << chart_uv[c].rows()
          << " rows";
  if (msg.tellp() != 0) throw InputError(msg.str());
}

// Non-finite corners (from a failed upstream solve) are pulled onto the mean
// of the chart's finite corners, so they cannot poison page sizes or output.
RowMatrixX2d with_finite_corners(const RowMatrixX2d& uv) {
  const auto finite = uv.array().isFinite().rowwise().all().eval();
  Eigen::RowVector2d mean = Eigen::RowVector2d::Zero();
  for (Eigen::Index i = 0; i < uv.rows(); ++i)
    if (finite(i)) mean += uv.row(i);
  if (finite.count() > 0) mean /= static_cast<double>(finite.count());
  RowMatrixX2d out = uv;
  for (Eigen::Index i = 0; i < uv.rows(); ++i)
    if (!finite(i)) out.row(i) = mean;
  return out;
}

// scale * R * uv, R = identity (turn 0) or 90 degrees counter-clockwise: (x, y) -> (-y, x).
RowMatrixX2d turned_corners(const RowMatrixX2d& uv, double scale, int turn) {
  RowMatrixX2d out(uv.rows(), 2);
  if (turn == 0) {
    out = scale * uv;
  } else {
    out.col(0) = -scale * uv.col(1);
    out.col(1) = scale * uv.col(0);
  }
  return out;
}

// Both orientations of one chart. The corners are first moved by whole texels
// next to the origin so that mask coordinates stay small integers and the
// texel grid is preserved.
ScaledChart scale_chart(const RowMatrixX2d& uv, double scale, int padding) {
  ScaledChart chart;
  for (int turn = 0; turn < 2; ++turn) {
    RowMatrixX2d corners = turned_corners(uv, scale, turn);
    if (corners.rows() > 0) chart.shift[turn] = corners.colwise().minCoeff().array().floor();
    corners.rowwise() -= chart.shift[turn];
    TexelMask mask = rasterize_chart(corners);
    chart.texels[turn] = count_set_texels(mask);
    chart.turned[turn] = make_placement_shape(dilate_mask(mask, padding));
    const TexelMask& dilated = chart.turned[turn].mask;
    chart.cells[turn] = make_placement_shape(
        coarsen_mask(dilated, 0, 0, kHoleCell, dilated.width, dilated.height));
  }
  return chart;
}

std::vector<ScaledChart> scale_charts(const std::vector<const RowMatrixX2d*>& chart_uv, double scale,
                                      int padding, const RunControl& control) {
  control.throw_if_cancelled();
  std::vector<ScaledChart> charts(chart_uv.size());
  const int n = static_cast<int>(chart_uv.size());
#pragma omp parallel for schedule(dynamic, 16)
  for (int c = 0; c < n; ++c)
    if (!control.cancelled()) charts[c] = scale_chart(*chart_uv[c], scale, padding);
  control.throw_if_cancelled();
  return charts;
}

// Largest scale at which every chart, grown by padding, fits a square of
// `virtual_side`. A chart spanning E texels covers at most E + 2 of them.
double largest_fitting_scale(const std::vector<const RowMatrixX2d*>& chart_uv, int virtual_side,
                             int padding) {
  const double room = virtual_side - 2.0 - 2.0 * padding;
  if (room < 1.0) {
    std::ostringstream msg;
    msg << "padding " << padding << " leaves no room on a page of " << virtual_side << " texels";
    throw InputError(msg.str());
  }
  double extent = 0.0;
  for (const RowMatrixX2d* uv : chart_uv)
    if (uv->rows() > 0) extent = std::max(extent, (uv->colwise().maxCoeff() - uv->colwise().minCoeff()).maxCoeff());
  return extent > 0.0 ? room / extent : std::numeric_limits<double>::infinity();
}

// Largest bounding box first: big charts shape the page, small ones fill gaps.
std::vector<int> largest_first(const std::vector<ScaledChart>& charts) {
  std::vector<int> order(charts.size());
  std::iota(order.begin(), order.end(), 0);
  auto box = [&](int c) {
    const TexelMask& m = charts[c].turned[0].mask;
    return static_cast<long long>(m.width) * m.height;
  };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return box(a) > box(b); });
  return order;
}

// A page being filled: its texels, for drops, and the same on the hole grid
// (a cell is occupied when any of its texels is), for hole searches.
struct Page {
  PageOccupancy texels;
  PageOccupancy cells;
  long long hole_miss_texels = std::numeric_limits<long long>::max();

  Page(int width, int height)
      : texels(width, height), cells(width / kHoleCell, height / kHoleCell) {}
};

// Lowest spot in a hole of the page for one orientation, with its top below
// top_limit. A spot on the hole grid is the texel spot kHoleCell times it.
std::optional<Eigen::Vector2i> spot_in_hole(const Page& page, const ScaledChart& chart, int turn,
                                            int top_limit) {
  const int room = top_limit - chart.turned[turn].mask.height;  // for the texel y
  if (room < 0) return std::nullopt;
  const PlacementShape& cells = chart.cells[turn];
  const auto at = page.cells.first_fit(cells, room / kHoleCell + cells.mask.height);
  if (!at) return std::nullopt;
  return Eigen::Vector2i(*at * kHoleCell);
}

// Both orientations are tried; the one whose top ends lowest wins (a long
// chart lies down), which keeps the packed region low and compact. Each is
// dropped onto the horizon, then holes below are searched for a lower spot
// unless the page recently had no hole for a chart that large.
bool place_chart(Page& page, const ScaledChart& chart, Placement& placement) {
  const int flat_first = chart.turned[1].mask.height < chart.turned[0].mask.height ? 1 : 0;
  const std::array<int, 2> turns = {flat_first, 1 - flat_first};
  std::optional<Eigen::Vector2i> best;
  int best_turn = 0, best_top = page.texels.height() + 1;
  auto keep_if_lower = [&](int turn, const std::optional<Eigen::Vector2i>& at) {
    if (!at) return false;
    best = at;
    best_turn = turn;
    best_top = at->y() + chart.turned[turn].mask.height;
    return true;
  };
  for (int turn : turns)
    keep_if_lower(turn, page.texels.lowest_drop(chart.turned[turn], best_top - 1));
  // Without a drop spot the holes are the only chance, whatever was missed before.
  const long long texels = chart.turned[0].texels;
  if (!best || texels < page.hole_miss_texels) {
    bool in_hole = false;
    for (int turn : turns) in_hole |= keep_if_lower(turn, spot_in_hole(page, chart, turn, best_top - 1));
    if (!in_hole)
      page.hole_miss_texels =
          std::min(page.hole_miss_texels, static_cast<long long>(kHoleMissMargin * texels));
  }
  if (!best) return false;
  const PlacementShape& shape = chart.turned[best_turn];
  page.texels.occupy(shape, best->x(), best->y());
  const TexelMask cells = coarsen_mask(shape.mask, best->x(), best->y(), kHoleCell,
                                       page.cells.width(), page.cells.height());
  if (cells.width > 0)
    page.cells.occupy(make_placement_shape(cells), cells.origin_x, cells.origin_y);
  placement.x = best->x();
  placement.y = best->y();
  placement.turn = best_turn;
  return true;
}

// Page side holding `used` virtual texels: the margins lie outside the page.
int trimmed_side(int used, const Frame& frame) {
  return round_up_to_quantum(std::max(1, used - 2 * frame.margin));
}

// Packs the charts in `order` onto one page whose virtual frame is width x
// height, trimmed to what they use; gives up at the first chart that does not fit.
std::optional<Layout> pack_one_page(const std::vector<int>& order,
                                    const std::vector<ScaledChart>& charts, const Frame& frame,
                                    int width, int height, const RunControl& control) {
  Layout layout;
  layout.placement.resize(charts.size());
  Page page(width, height);
  for (int c : order) {
    control.throw_if_cancelled();
    if (!place_chart(page, charts[c], layout.placement[c])) return std::nullopt;
  }
  layout.pages.push_back({trimmed_side(page.texels.used_width(), frame),
                          trimmed_side(page.texels.used_height(), frame)});
  return layout;
}

// The smallest near-square page (sides <= max_side) holding the charts, or
// nullopt if they need more than one page. Page width w gives height h(w);
// the next width tried is sqrt(w * h), the side of a square of equal area.
std::optional<Layout> pack_smallest_page(const std::vector<int>& order,
                                         const std::vector<ScaledChart>& charts,
                                         const Frame& frame, int max_side,
                                         const RunControl& control) {
  const int to_virtual = 2 * frame.margin, max_virtual = max_side + to_virtual;
  double dilated_area = 0.0;
  int narrowest = 1;
  for (int c : order) {
    const TexelMask& m = charts[c].turned[0].mask;
    dilated_area += static_cast<double>(count_set_texels(m));
    narrowest = std::max(narrowest, std::min(m.width, m.height));
  }
  if (dilated_area > static_cast<double>(max_virtual) * max_virtual) return std::nullopt;
  auto width_for = [&](double virtual_width) {
    return std::min(max_side, round_up_to_quantum(virtual_width - to_virtual));
  };
  auto pack = [&](int width) {
    auto layout = pack_one_page(order, charts, frame, width + to_virtual, max_virtual, control);
    fprintf(stderr, "probe %d -> %d x %d\n", width, layout ? layout->pages[0].width : 0, layout ? layout->pages[0].height : 0);
    return layout;
  };
  int width = width_for(std::max<double>(narrowest, std::sqrt(dilated_area / kExpectedDensity)));
  std::optional<Layout> best = pack(width);
  while (!best && width < max_side) {
    width = width_for((width + to_virtual) * 1.25);
    best = pack(width);
  }
  if (!best) return std::nullopt;
  auto area = [](const Layout& l) { return page_texels(l.pages); };
  int height = best->pages[0].height;
  for (int probe = 0; probe < kSquareProbes; ++probe) {
    const int next = width_for(std::sqrt(static_cast<double>(width) * height) + to_virtual);
    // Near enough to square: another probe would change the area by little.
    if (std::abs(next - width) <= std::max<double>(kSideQuantum, kSquareTolerance * width)) break;
    width = next;
    auto candidate = pack(width);
    if (!candidate) break;
    height = candidate->pages[0].height;
    if (area(*candidate) < area(*best)) best = std::move(candidate);
  }
  return best;
}

// First fit over pages of max_side: each chart goes to the first page with
// room. The last page is then repacked as small as it can be.
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
      pages.emplace_back(side, side);
      // Scales are capped so that every chart fits an empty page.
      if (!place_chart(pages.back(), charts[c], placement))
        throw std::logic_error("pack_many_pages: chart larger than an empty page");
    }
  }
  for (const Page& page : pages)
    layout.pages.push_back({trimmed_side(page.texels.used_width(), frame),
                            trimmed_side(page.texels.used_height(), frame)});

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

// Default sizing at one scale: the smallest page, else the fewest max pages.
Packing pack_free(const std::vector<const RowMatrixX2d*>& chart_uv, double scale, const Frame& frame,
                  int max_side, const RunControl& control) {
  Packing packing{scale, scale_charts(chart_uv, scale, frame.padding, control), {}};
  const std::vector<int> order = largest_first(packing.charts);
  if (auto single = pack_smallest_page(order, packing.charts, frame, max_side, control))
    packing.layout = std::move(*single);
  else
    packing.layout = pack_many_pages(order, packing.charts, frame, max_side, control);
  return packing;
}

// Largest scale <= first.scale whose packing fits the budget. Page area grows
// with scale^2, so the next scale tried is scale * sqrt(budget / texels);
// bisection then closes the gap to the last scale that did not fit.
Packing shrink_to_budget(const std::vector<const RowMatrixX2d*>& chart_uv, Packing first,
                         const Frame& frame, int max_side, long long budget,
                         const RunControl& control) {
  auto pack = [&](double s) { return pack_free(chart_uv, s, frame, max_side, control); };
  auto fits = [&](const Packing& p) { return page_texels(p.layout.pages) <= budget; };
  double failed_scale = first.scale;
  double ratio = static_cast<double>(budget) / page_texels(first.layout.pages);
  std::optional<Packing> fitting;
  for (int attempt = 0; !fitting; ++attempt) {
    if (attempt == kMaxShrinkAttempts)
      throw InputError("texel_budget is too small to hold the charts with their padding");
    const double s = failed_scale * std::clamp(0.99 * std::sqrt(ratio), 0.25, 0.97);
    Packing p = pack(s);
    if (fits(p)) {
      fitting = std::move(p);
    } else {
      failed_scale = s;
      ratio = static_cast<double>(budget) / page_texels(p.layout.pages);
    }
  }
  for (int i = 0; i < kScaleBisections && failed_scale > fitting->scale * kScaleTolerance; ++i) {
    Packing p = pack(std::sqrt(fitting->scale * failed_scale));
    if (fits(p))
      fitting = std::move(p);
    else
      failed_scale = p.scale;
  }
  return std::move(*fitting);
}

// fixed_page_size: the largest scale at which all charts fit one side x side
// page. Starts from the scale filling the page at the expected density, walks
// by x1.4 / x0.7 until it brackets the answer, then bisects.
Packing pack_fixed(const std::vector<const RowMatrixX2d*>& chart_uv, const Frame& frame, int side,
                   const RunControl& control) {
  const int virtual_side = side + 2 * frame.margin;
  auto try_scale = [&](double s) -> std::optional<Packing> {
    Packing packing{s, scale_charts(chart_uv, s, frame.padding, control), {}};
    auto layout = pack_one_page(largest_first(packing.charts), packing.charts, frame,
                                virtual_side, virtual_side, control);
    if (!layout) return std::nullopt;
    layout->pages[0] = {side, side};
    packing.layout = std::move(*layout);
    return packing;
  };
  double cap = largest_fitting_scale(chart_uv, virtual_side, frame.padding);
  if (std::isinf(cap)) cap = 1.0;  // every chart is a point: any scale packs the same
  double area = 0.0;  // at scale 1, from the corner polygons: only a first guess
  for (const RowMatrixX2d* uv : chart_uv)
    for (Eigen::Index f = 0; f + 2 < uv->rows(); f += 3) {
      const Eigen::RowVector2d a = uv->row(f + 1) - uv->row(f), b = uv->row(f + 2) - uv->row(f);
      area += 0.5 * std::abs(a.x() * b.y() - a.y() * b.x());
    }
  double start = area > 0.0 ? std::sqrt(kExpectedDensity * side * side / area) : cap;
  start = std::min(start, cap);

  std::optional<Packing> fitting = try_scale(start);
  double failed_scale = std::numeric_limits<double>::infinity();
  if (fitting) {
    while (fitting->scale < cap && std::isinf(failed_scale)) {
      const double s = std::min(cap, fitting->scale * 1.4);
      if (auto p = try_scale(s)) fitting = std::move(p);
      else failed_scale = s;
    }
  } else {
    failed_scale = start;
    for (int attempt = 0; !fitting; ++attempt) {
      if (attempt == kMaxShrinkAttempts)
        throw InputError("fixed_page_size is too small to hold the charts with their padding");
      const double s = failed_scale * 0.7;
      if (auto p = try_scale(s)) fitting = std::move(p);
      else failed_scale = s;
    }
  }
  for (int i = 0; i < kScaleBisections && std::isfinite(failed_scale) &&
                  failed_scale > fitting->scale * kScaleTolerance;
       ++i) {
    const double s = std::sqrt(fitting->scale * failed_scale);
    if (auto p = try_scale(s)) fitting = std::move(p);
    else failed_scale = s;
  }
  return std::move(*fitting);
}

// Page units of every chart and the exact transform that produced them.
PackResult to_result(const std::vector<const RowMatrixX2d*>& chart_uv, const Packing& packing,
                     const Frame& frame) {
  const Layout& layout = packing.layout;
  PackResult result;
  result.scale = packing.scale;
  result.pages = layout.pages;
  result.placed_uv.resize(chart_uv.size());
  result.chart_page.resize(chart_uv.size());
  result.chart_rotated.resize(chart_uv.size());
  result.chart_translation.resize(static_cast<Eigen::Index>(chart_uv.size()), 2);
  long long chart_texels = 0;
  for (size_t c = 0; c < chart_uv.size(); ++c) {
    const Placement& at = layout.placement[c];
    const ScaledChart& chart = packing.charts[c];
    const TexelMask& mask = chart.turned[at.turn].mask;
    // Mask texel (0, 0) is corner-frame texel mask.origin, and lands on virtual
    // texel (at.x, at.y), i.e. page texel (at.x, at.y) - margin.
    const Eigen::RowVector2d offset(at.x - frame.margin - mask.origin_x,
                                    at.y - frame.margin - mask.origin_y);
    RowMatrixX2d corners = turned_corners(*chart_uv[c], packing.scale, at.turn);
    corners.rowwise() += offset - chart.shift[at.turn];
    const PageSize& page = layout.pages[at.page];
    corners.col(0) /= page.width;
    corners.col(1) /= page.height;
    result.placed_uv[c] = std::move(corners);
    result.chart_page[c] = at.page;
    result.chart_rotated[c] = at.turn == 1;
    result.chart_translation.row(static_cast<Eigen::Index>(c)) = offset - chart.shift[at.turn];
    chart_texels += chart.texels[at.turn];
  }
  result.efficiency = static_cast<double>(chart_texels) / page_texels(layout.pages);
  return result;
}

}  // namespace

PackResult pack_charts(const std::vector<RowMatrixX2d>& chart_uv, const PackOptions& options,
                       const RunControl& control) {
  require_valid(chart_uv, options);
  control.throw_if_cancelled();
  const Frame frame{options.padding, options.padding / 2};
  if (chart_uv.empty()) {
    PackResult empty;
    empty.scale = options.density_scale;
    const int side = options.fixed_page_size > 0 ? options.fixed_page_size : kSideQuantum;
    empty.pages.push_back({side, side});
    empty.chart_translation.resize(0, 2);
    return empty;
  }

  std::vector<RowMatrixX2d> repaired;  // only charts that had non-finite corners
  repaired.reserve(chart_uv.size());
  std::vector<const RowMatrixX2d*> uv(chart_uv.size());
  for (size_t c = 0; c < chart_uv.size(); ++c) {
    if (chart_uv[c].allFinite()) {
      uv[c] = &chart_uv[c];
    } else {
      repaired.push_back(with_finite_corners(chart_uv[c]));
      uv[c] = &repaired.back();
    }
  }

  if (options.fixed_page_size > 0)
    return to_result(uv, pack_fixed(uv, frame, options.fixed_page_size, control), frame);

  const int max_side = options.max_page_size / kSideQuantum * kSideQuantum;
  const double scale = std::min(
      options.density_scale, largest_fitting_scale(uv, max_side + 2 * frame.margin, frame.padding));
  Packing packing = pack_free(uv, scale, frame, max_side, control);
  if (options.texel_budget > 0 && page_texels(packing.layout.pages) > options.texel_budget)
    packing = shrink_to_budget(uv, std::move(packing), frame, max_side, options.texel_budget, control);
  return to_result(uv, packing, frame);
}

}  // namespace atlas
