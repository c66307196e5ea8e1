#include "pack/pack.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <utility>

#include "core/parallel_for.hpp"
#include "core/uv_layout.hpp"
#include "pack/page_filling.hpp"
#include "pack/scaled_chart.hpp"

namespace atlas {
namespace {

constexpr double kScaleTolerance = 1.005;  // scale searches stop within 0.5% of the answer
constexpr int kScaleSteps = 12;            // ... or after this many packings
constexpr double kAimBelow = 0.998;        // scale guesses aim just under the limit
constexpr int kTallPage = 4;               // fixed size: trial pages are this much taller
// Fixed size: first guess of the share of the page the charts' own area fills.
constexpr double kExpectedFill = 0.6;

// Widths tried beside the chosen one (sweep_widths): steps fine enough to
// meet the widths where a few large charts fit side by side, and few enough
// that the sweep costs less than the recipes before it. 0 steps: no sweep.
constexpr double kWidthStep = 1.08;
constexpr int kWidthSteps = 4;

// Padded chart texels over page texels at which a page is taken as full,
// to estimate how far charts that did not fit overshoot it.
constexpr double kFullPage = 0.8;
// A packing that broke a limit overshoots it by at least this ratio, so the
// next try is a few percent smaller: when the estimate above says the charts
// should have fitted, predicting from it would creep down by the search
// tolerance and spend every step without finding a fit.
constexpr double kLeastOvershoot = 1.1;

// Scaled padding stops here: the bake extends a chart's colour this far, past
// the 1.5 texels a bilinear read at full resolution reaches beyond the edge,
// so such reads never meet the pull-push fill.
constexpr int kLeastScaledPadding = 2;

struct Packing {
  double scale = 1.0;
  std::vector<ScaledChart> charts;
  Layout layout;
  // > 0: the charts did not fit the one page allowed (layout empty); how
  // many times their padded texels exceed what that page held (estimated
  // with kFullPage when the page was not tried).
  double overflow = 0.0;
  int recipe = -1;  // index into kRecipes of the recipe that packed layout, if one did
};

void require_valid(const std::vector<RowMatrixX2d>& chart_uv, const PackOptions& o) {
  std::ostringstream msg;
  if (!(o.density_scale > 0.0 && std::isfinite(o.density_scale)))
    msg << "density_scale must be positive and finite, got " << o.density_scale;
  else if (o.padding < 0 || o.padding > kMaxPadding)
    msg << "padding must be 0.." << kMaxPadding << ", got " << o.padding;
  else if (o.max_page_size < kSideQuantum || o.max_page_size > kMaxPageSide)
    msg << "max_page_size must be " << kSideQuantum << ".." << kMaxPageSide << ", got " << o.max_page_size;
  else if (o.fixed_page_size < 0 || o.fixed_page_size > kMaxPageSide)
    msg << "fixed_page_size must be 0.." << kMaxPageSide << ", got " << o.fixed_page_size;
  else if (o.max_pages < 0)
    msg << "max_pages must be >= 0, got " << o.max_pages;
  else if (o.texel_budget < 0)
    msg << "texel_budget must be >= 0, got " << o.texel_budget;
  else if (o.fixed_page_size > 0 && !is_allowed_side(o.fixed_page_size, o.page_sides))
    msg << "fixed_page_size " << o.fixed_page_size << " is not a side page_sides "
        << (o.page_sides == PageSides::PowerOfTwo ? "power_of_two" : "multiple_of_4") << " allows";
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

// Largest scale at which every chart, grown by padding, fits a page of
// `side` in either orientation (the frame's margin beyond it included): a
// chart spanning E texels covers at most E + 2 texels. Infinite when every
// chart is a point.
double largest_fitting_scale(const std::vector<const RowMatrixX2d*>& chart_uv, int side, const Frame& frame) {
  const double room = side + 2.0 * frame.margin - 2.0 - 2.0 * frame.padding;
  if (room < 1.0) {
    std::ostringstream msg;
    msg << "padding " << frame.padding << " leaves no room on a page of " << side << " texels";
    throw InputError(msg.str());
  }
  double extent = 0.0;
  for (const RowMatrixX2d* uv : chart_uv)
    if (uv->rows() > 0)
      extent = std::max(extent, (uv->colwise().maxCoeff() - uv->colwise().minCoeff()).maxCoeff());
  return extent > 0.0 ? room / extent : std::numeric_limits<double>::infinity();
}

// Recipes (a chart order and how charts rest) the default sizing tries,
// keeping the smallest page: which one packs best depends on the charts'
// shapes. They are tried two at a time (one per core of a small machine),
// further pairs only once one found a page, and scale searches use the
// first recipe alone (see shrink_to_limits).
struct Recipe {
  ChartSize order;
  Rest rest;
};
constexpr std::array<Recipe, 8> kRecipes = {{{ChartSize::BoxArea, Rest::Top},
                                            {ChartSize::BoxArea, Rest::Centroid},
                                            {ChartSize::Texels, Rest::Top},
                                            {ChartSize::Texels, Rest::Centroid},
                                            {ChartSize::LongSide, Rest::Top},
                                            {ChartSize::LongSide, Rest::Centroid},
                                            {ChartSize::Perimeter, Rest::Top},
                                            {ChartSize::Perimeter, Rest::Centroid}}};
constexpr int kRecipesAtOnce = 2;
// Past this many charts only the first pair of recipes is tried, without a
// sweep of widths: each try packs every chart again, at a cost that grows
// faster than the charts, and among thousands of charts the order and the
// width move the page by little (bench/README.md).
constexpr size_t kManyCharts = 1000;

// Packs packing.charts on one page with recipes [first, last) of kRecipes and
// keeps the smallest page, the one of packing.layout included (if any);
// placed_share (if given) is that of order 0, see pack_smallest_page.
void keep_smallest_page(Packing& packing, int first, int last, const Frame& frame, int max_side,
                        const RunControl& control, double* placed_share = nullptr) {
  if (packing.layout.pages.size() > 1) return;
  std::array<std::optional<Layout>, kRecipes.size()> single;
  for (int pair = first; pair < last; pair += kRecipesAtOnce) {
    if (pair > 0 && packing.layout.pages.empty()) break;
    const int end = std::min(last, pair + kRecipesAtOnce);
    parallel_for(end - pair, 1, [&](int i) {
      const int k = pair + i;
      Frame resting = frame;
      resting.rest = kRecipes[k].rest;
      single[k] = pack_smallest_page(largest_first(packing.charts, kRecipes[k].order), packing.charts,
                                     resting, max_side, control, k == 0 ? placed_share : nullptr);
    });
    for (int k = pair; k < end; ++k)
      if (single[k] &&
          (packing.layout.pages.empty() || area(single[k]->pages[0]) < area(packing.layout.pages[0]))) {
        packing.layout = std::move(*single[k]);
        packing.recipe = k;
      }
  }
}

// Page widths kWidthStep^k times the chosen one (0 < |k| <= kWidthSteps),
// as the page sides allow, each once (power-of-two sides round most of them
// alike). The chosen width may be among them: the chosen page was packed
// wider and then trimmed, so packing at its own width can differ.
std::vector<int> swept_widths(int chosen, int to_virtual, int max_side, PageSides sides) {
  std::vector<int> widths;
  for (int k = -kWidthSteps; k <= kWidthSteps; ++k) {
    if (k == 0) continue;
    const double virtual_width = (chosen + to_virtual) * std::pow(kWidthStep, k);
    widths.push_back(std::min(max_side, allowed_side(virtual_width - to_virtual, sides)));
  }
  std::sort(widths.begin(), widths.end());
  widths.erase(std::unique(widths.begin(), widths.end()), widths.end());
  return widths;
}

// A few large charts fit side by side at some page widths only, and the
// near-square search steps past them: the swept widths are tried too, with
// the recipe that chose the page.
void sweep_widths(Packing& packing, const Frame& frame, int max_side, const RunControl& control) {
  if (packing.recipe < 0 || packing.layout.pages.size() != 1) return;
  const Recipe& recipe = kRecipes[packing.recipe];
  Frame resting = frame;
  resting.rest = recipe.rest;
  const std::vector<int> order = largest_first(packing.charts, recipe.order);
  const int to_virtual = 2 * frame.margin;
  const std::vector<int> widths =
      swept_widths(packing.layout.pages[0].width, to_virtual, max_side, frame.sides);
  const long long chosen_area = area(packing.layout.pages[0]);
  std::vector<std::optional<Layout>> swept(widths.size());
  parallel_for(static_cast<int>(widths.size()), 1, [&](int i) {
    // A page taller than this is larger than the chosen one: the packing
    // stops at the first chart above it (the charts below land as they would
    // on a taller page).
    const int height = static_cast<int>(std::min<long long>(max_side, chosen_area / widths[i]));
    auto page = pack_one_page(order, packing.charts, widths[i] + to_virtual, height + to_virtual,
                              resting, control);
    if (page) swept[i] = Layout{std::move(page->placement), {trimmed_page(page->used, frame)}};
  });
  for (std::optional<Layout>& layout : swept)
    if (layout && area(layout->pages[0]) < area(packing.layout.pages[0]))
      packing.layout = std::move(*layout);
}

// Default sizing at one scale: the smallest page over the first `orders` recipes of
// kRecipes, else the fewest max pages (unless max_pages is 1: then the
// overflow is all a scale search needs).
Packing pack_free(const std::vector<const RowMatrixX2d*>& chart_uv, double scale, const Frame& frame,
                  int max_side, int max_pages, int orders, const RunControl& control) {
  Packing packing{scale, scale_charts(chart_uv, scale, frame.padding, kHoleCell, frame.gap, control), {}};
  double placed_share = 0.0;
  keep_smallest_page(packing, 0, orders, frame, max_side, control, &placed_share);
  if (!packing.layout.pages.empty()) return packing;
  if (max_pages == 1) {
    double padded = 0.0;
    for (const ScaledChart& chart : packing.charts) padded += static_cast<double>(chart.footprint);
    const double side = max_side + 2.0 * frame.margin;
    packing.overflow = placed_share > 0.0 ? 1.0 / placed_share : padded / (kFullPage * side * side);
  } else {
    packing.layout = pack_many_pages(largest_first(packing.charts), packing.charts, frame, max_side,
                                     control);
  }
  return packing;
}

// The packing at the largest scale < failed (and <= cap) that fits, where
// try_scale(s) packs at s and returns it with its fill ratio r: it fits iff
// r <= 1. r grows about as s^e, e = 2 while the charts dominate and less
// when their padding does; e is re-estimated from the last two tries and
// s * r^(-1/e) predicts the answer. A prediction outside the bracket
// (largest fitting, smallest failing) is replaced by the bracket's middle.
template <class TryScale>
Packing largest_fitting_packing(TryScale try_scale, double start, double cap, double failed,
                                const char* too_small) {
  std::optional<Packing> fitting;
  double s = std::min(start, cap), last_s = 0.0, last_ratio = 0.0;
  for (int step = 0; step < kScaleSteps; ++step) {
    auto [packing, ratio] = try_scale(s);
    if (ratio <= 1.0 && (!fitting || s > fitting->scale))
      fitting = std::move(packing);
    else if (ratio > 1.0)
      failed = std::min(failed, s);
    const double lo = fitting ? fitting->scale : 0.0;
    if (lo >= cap || failed <= lo * kScaleTolerance) break;
    // The least overshoot is a floor, not a measure: it says nothing of the exponent.
    const bool measured = std::isfinite(ratio) && ratio != kLeastOvershoot;
    double exponent = 2.0;
    if (last_ratio > 0.0 && measured && s != last_s)
      exponent = std::clamp(std::log(ratio / last_ratio) / std::log(s / last_s), 0.25, 2.0);
    double next = std::isfinite(ratio) ? kAimBelow * s * std::pow(ratio, -1.0 / exponent) : 0.5 * s;
    next = std::min(cap, next);
    // A fit that predicts the limit within tolerance of itself is the answer.
    if (fitting && ratio <= 1.0 && next < lo * kScaleTolerance) break;
    if (next <= lo || next >= failed)
      next = !fitting ? 0.5 * failed
                      : std::isfinite(failed) ? std::sqrt(lo * failed) : std::min(cap, 1.1 * lo);
    if (fitting && next < lo * kScaleTolerance) break;  // already within tolerance
    if (measured) {
      last_s = s;
      last_ratio = ratio;
    }
    s = next;
  }
  if (!fitting) throw ChartsDoNotFit(too_small);
  return std::move(*fitting);
}

// Area of the corner triangles, in the units of the corners squared.
double corner_area(const std::vector<const RowMatrixX2d*>& chart_uv) {
  double area = 0.0;
  for (const RowMatrixX2d* uv : chart_uv)
    for (Eigen::Index f = 0; f + 2 < uv->rows(); f += 3) {
      const Eigen::RowVector2d a = uv->row(f + 1) - uv->row(f), b = uv->row(f + 2) - uv->row(f);
      area += 0.5 * std::abs(a.x() * b.y() - a.y() * b.x());
    }
  return area;
}

// Page limits of the free sizing: total texels (0: none) and page count (0: none).
struct PageLimits {
  long long texels = 0;
  int pages = 0;

  // How far a packing overshoots: > 1 when it breaks a limit. Both parts grow
  // about as scale^2, so the scale search can predict from them: page texels
  // over the budget, and over `pages` full pages (more pages is > 1 anyway).
  double ratio(const Packing& packing, int max_side) const {
    if (packing.overflow > 0.0) return std::max(kLeastOvershoot, packing.overflow);
    const std::vector<PageSize>& pages_used = packing.layout.pages;
    double r = 0.0;
    const double used = static_cast<double>(page_texels(pages_used));
    if (texels > 0) r = used / texels;
    if (pages > 0) {
      const double full = static_cast<double>(pages) * max_side * max_side;
      r = std::max(r, static_cast<int>(pages_used.size()) > pages ? std::max(kLeastOvershoot, used / full)
                                                                   : used / full);
    }
    return r;
  }
};

// The largest scale <= cap whose pages keep within the limits; `failed` is
// a scale known not to (infinite if none is known yet).
Packing shrink_to_limits(const std::vector<const RowMatrixX2d*>& chart_uv, double start, double cap,
                         double failed, const Frame& frame, int max_side, const PageLimits& limits,
                         const RunControl& control) {
  // One order: the search ends within its tolerance of the limit, where
  // the order gains little and many tries would each pay for all orders.
  double smallest = std::numeric_limits<double>::infinity();  // scale tried
  auto try_scale = [&](double s) {
    smallest = std::min(smallest, s);
    Packing packing = pack_free(chart_uv, s, frame, max_side, limits.pages, 1, control);
    const double ratio = limits.ratio(packing, max_side);
    return std::make_pair(std::move(packing), ratio);
  };
  try {
    return largest_fitting_packing(try_scale, start, cap, failed,
                                   "the charts with their padding do not fit the texel budget or the "
                                   "page count at any scale");
  } catch (const ChartsDoNotFit&) {
    // Charts shrunk to a texel or two are their padding alone and pack the
    // same at any smaller scale: only the order can still make them fit.
    Packing packing = pack_free(chart_uv, smallest, frame, max_side, limits.pages,
                                static_cast<int>(kRecipes.size()), control);
    if (limits.ratio(packing, max_side) <= 1.0) return packing;
    throw;
  }
}

// fixed_page_size: the largest scale at which the charts fit one side x side
// page. Each try packs on a page as wide but kTallPage times taller, so it
// also tells the height the charts need: at a fixed width it grows as scale^2.
Packing pack_fixed(const std::vector<const RowMatrixX2d*>& chart_uv, const Frame& frame, int side,
                   const RunControl& control) {
  const int virtual_side = side + 2 * frame.margin;
  auto try_scale = [&](double s) {
    Packing packing{s, scale_charts(chart_uv, s, frame.padding, kHoleCell, frame.gap, control), {}};
    const auto page = pack_one_page(largest_first(packing.charts), packing.charts, virtual_side,
                                    kTallPage * virtual_side, frame, control);
    if (!page) return std::make_pair(std::move(packing), std::numeric_limits<double>::infinity());
    packing.layout = {page->placement, {{side, side}}};
    return std::make_pair(std::move(packing), static_cast<double>(page->used.height) / virtual_side);
  };
  double cap = largest_fitting_scale(chart_uv, side, frame);
  if (std::isinf(cap)) cap = 1.0;  // every chart is a point: any scale packs the same
  const double area = corner_area(chart_uv);  // at scale 1
  const double start = area > 0.0 ? std::sqrt(kExpectedFill * side * side / area) : cap;
  return largest_fitting_packing(try_scale, start, cap, std::numeric_limits<double>::infinity(),
                                 "fixed_page_size is too small to hold the charts with their padding");
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
  result.chart_turns.resize(chart_uv.size());
  result.chart_translation.resize(static_cast<Eigen::Index>(chart_uv.size()), 2);
  long long chart_texels = 0;
  for (size_t c = 0; c < chart_uv.size(); ++c) {
    const Placement& at = layout.placement[c];
    const ScaledChart& chart = packing.charts[c];
    const TexelMask& mask = chart.turned[at.turn].mask;
    // Mask texel (0, 0) is texel mask.origin of scale * R * uv - shift and
    // lands on virtual texel (at.x, at.y), i.e. page texel (at.x, at.y) - margin.
    const Eigen::RowVector2d offset(at.x - frame.margin - mask.origin_x,
                                    at.y - frame.margin - mask.origin_y);
    const Eigen::RowVector2d translation = offset - chart.shift[at.turn];
    RowMatrixX2d corners = turned_corners(*chart_uv[c], packing.scale, at.turn);
    corners.rowwise() += translation;
    const PageSize& page = layout.pages[at.page];
    corners.col(0) /= page.width;
    corners.col(1) /= page.height;
    result.placed_uv[c] = std::move(corners);
    result.chart_page[c] = at.page;
    result.chart_turns[c] = at.turn;
    result.chart_translation.row(static_cast<Eigen::Index>(c)) = translation;
    chart_texels += chart.raster_texels[at.turn];
  }
  result.efficiency = static_cast<double>(chart_texels) / page_texels(layout.pages);
  result.padding = frame.padding;
  return result;
}

// The result for no charts: one empty page of the smallest (or the fixed) size.
PackResult empty_result(const PackOptions& options) {
  PackResult empty;
  empty.scale = options.density_scale;
  empty.padding = options.padding;
  const int side = options.fixed_page_size > 0 ? options.fixed_page_size : kSideQuantum;
  empty.pages.push_back({side, side});
  empty.chart_translation.resize(0, 2);
  return empty;
}

// Per chart, its corners: chart_uv's own, or where some are not finite, a
// repaired copy held in `repaired`.
std::vector<const RowMatrixX2d*> finite_charts(const std::vector<RowMatrixX2d>& chart_uv,
                                               std::vector<RowMatrixX2d>& repaired) {
  repaired.reserve(chart_uv.size());  // no reallocation: the result points into it
  std::vector<const RowMatrixX2d*> uv(chart_uv.size());
  for (size_t c = 0; c < chart_uv.size(); ++c) {
    if (chart_uv[c].allFinite()) {
      uv[c] = &chart_uv[c];
    } else {
      repaired.push_back(with_finite_corners(chart_uv[c]));
      uv[c] = &repaired.back();
    }
  }
  return uv;
}

// Default sizing: the packing at the largest scale <= `scale` that keeps
// within the limits, on the smallest page the recipes find when one page does.
Packing pack_within_limits(const std::vector<const RowMatrixX2d*>& uv, double scale,
                           const Frame& frame, int max_side, const PackOptions& options,
                           const RunControl& control) {
  const PageLimits limits{options.texel_budget, options.max_pages};
  // Charts whose own area already breaks the texel limit are not packed at
  // full scale first: rasterising thousands of them there costs more than
  // all the packings at the scale that fits.
  const double area = corner_area(uv) * scale * scale;
  const long long texel_limit = std::min<long long>(
      options.texel_budget > 0 ? options.texel_budget : std::numeric_limits<long long>::max(),
      options.max_pages > 0 ? static_cast<long long>(options.max_pages) * max_side * max_side
                            : std::numeric_limits<long long>::max());
  if (area > static_cast<double>(texel_limit))
    return shrink_to_limits(uv, scale * std::sqrt(kExpectedFill * texel_limit / area), scale,
                            scale, frame, max_side, limits, control);
  // The first pair of orders, then the others only if the charts fit:
  // a page that broke the limits is shrunk in one order.
  Packing packing = pack_free(uv, scale, frame, max_side, limits.pages, kRecipesAtOnce, control);
  const double ratio = limits.ratio(packing, max_side);
  if (ratio > 1.0)
    return shrink_to_limits(uv, kAimBelow * scale / std::sqrt(ratio), scale, scale, frame,
                            max_side, limits, control);
  if (uv.size() > kManyCharts) return packing;
  // A smaller page keeps within the limits too.
  keep_smallest_page(packing, kRecipesAtOnce, static_cast<int>(kRecipes.size()), frame, max_side,
                     control);
  sweep_widths(packing, frame, max_side, control);
  return packing;
}

// The charts packed with options.padding as given.
PackResult pack_at_padding(const std::vector<RowMatrixX2d>& chart_uv, const PackOptions& options,
                           const RunControl& control) {
  // Half the padding may lie beyond the border: pages wrap when sampled, so
  // the two borders together still give a chart its full padding.
  const Frame frame{options.padding, options.padding / 2, options.page_sides, options.square_pages,
                    options.padding_between_charts};
  if (chart_uv.empty()) return empty_result(options);
  std::vector<RowMatrixX2d> repaired;  // charts that had non-finite corners
  const std::vector<const RowMatrixX2d*> uv = finite_charts(chart_uv, repaired);

  if (options.fixed_page_size > 0) {
    // density_scale does not apply: below 1 the charts lost texel density.
    PackResult result = to_result(uv, pack_fixed(uv, frame, options.fixed_page_size, control), frame);
    result.shrunk = result.scale < 1.0 - 1e-9;
    return result;
  }

  const int max_side = largest_allowed_side(options.max_page_size, options.page_sides);
  const double scale = std::min(
      options.density_scale, largest_fitting_scale(uv, max_side, frame));
  Packing packing = pack_within_limits(uv, scale, frame, max_side, options, control);
  lower_single_page(packing.layout, packing.charts, frame, control);
  PackResult result = to_result(uv, packing, frame);
  result.shrunk = result.scale < options.density_scale * (1.0 - 1e-9);
  return result;
}

int longest_side(const std::vector<PageSize>& pages) {
  int side = 0;
  for (const PageSize& page : pages) side = std::max({side, page.width, page.height});
  return side;
}

}  // namespace

bool is_allowed_side(int side, PageSides sides) { return allowed_side(side, sides) == side; }

int padding_for_side(const PackOptions& options, int side) {
  if (options.full_padding_side <= 0 || side >= options.full_padding_side) return options.padding;
  const long scaled = std::lround(static_cast<double>(options.padding) * side / options.full_padding_side);
  return static_cast<int>(std::clamp<long>(scaled, std::min(options.padding, kLeastScaledPadding), options.padding));
}

int budget_page_side(const PackOptions& options) {
  if (options.texel_budget <= 0) return options.max_page_size;
  const double side = std::sqrt(static_cast<double>(options.texel_budget));
  return static_cast<int>(std::min<double>(options.max_page_size, side));
}

PackResult pack_charts(const std::vector<RowMatrixX2d>& chart_uv, const PackOptions& options,
                       const RunControl& control) {
  require_valid(chart_uv, options);
  control.throw_if_cancelled();
  PackOptions scaled = options;
  if (options.fixed_page_size > 0) scaled.padding = padding_for_side(options, options.fixed_page_size);
  PackResult result;
  try {
    result = pack_at_padding(chart_uv, scaled, control);
  } catch (const ChartsDoNotFit&) {
    // No scale fits the limits at this padding; pages within them are small
    // enough to call for less padding, perhaps.
    scaled.padding = padding_for_side(options, budget_page_side(options));
    if (options.fixed_page_size > 0 || scaled.padding == options.padding) throw;
    return pack_at_padding(chart_uv, scaled, control);
  }
  // The page size follows the charts: pack again while it calls for less
  // padding (the padding only falls, so this ends).
  for (;;) {
    scaled.padding = padding_for_side(options, longest_side(result.pages));
    if (scaled.padding >= result.padding) return result;
    result = pack_at_padding(chart_uv, scaled, control);
  }
}

}  // namespace atlas
