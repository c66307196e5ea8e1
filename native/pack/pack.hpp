// The pack stage. Takes flattened charts in texels. Gives their placement on
// as few pages as possible (pack_charts), rasterised at texel resolution so
// that no two charts (padding included) share a texel, and the page-side
// rules it follows. Charts come out of the flattening at arbitrary angles:
// turned_to_smallest_box (smallest_box_turn.hpp) turns them to their
// smallest box first. page_filling, page_occupancy, placement_shape,
// scaled_chart, chart_raster, coarse_mask and texel_mask are its internals.
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "pack/smallest_box_turn.hpp"

namespace atlas {

// The charts, grown by their padding, fit the texel budget or the page count
// at no scale: the caller can say what in its input causes it.
struct ChartsDoNotFit : InputError {
  using InputError::InputError;
};

// How page sides are rounded once the charts are placed.
enum class PageSides {
  Tight,        // the texels used, nothing more
  MultipleOf4,  // multiples of 4 texels (BCn and ASTC 4x4 blocks)
  PowerOfTwo,
};

// Bounds of the options, far past any use: page sides and rasters stay in int.
constexpr int kMaxPadding = 1024;
constexpr int kMaxPageSide = 1 << 16;

struct PackOptions {
  double density_scale = 1.0;  // texels per original texel
  int padding = 4;             // empty texels kept around every chart; 0: none (at most kMaxPadding)
  // Pages whose longer side is under this many texels get the padding scaled
  // by side / full_padding_side, rounded, but at least min(padding, 2): from
  // the same viewing distance a page half as large is read one mip level
  // finer, so half the padding keeps the same distances free of bleeding.
  // 0: every page gets the full padding.
  int full_padding_side = 1024;
  int max_page_size = 8192;    // largest page side (at most kMaxPageSide; 0 is refused)
  int fixed_page_size = 0;     // > 0: square pages of this side, charts scaled to fit one page;
                               // 0: the page size follows the charts
  long long texel_budget = 0;  // > 0: total output texels may not exceed this; charts are
                               // scaled down uniformly if they would
  int max_pages = 0;           // > 0: at most this many pages; charts are scaled down
                               // uniformly if they need more pages of max_page_size
  PageSides page_sides = PageSides::MultipleOf4;
  bool square_pages = false;   // pages with equal sides (the larger one)
  // false: every chart owns a ring of `padding` texels, so two charts are
  // 2 * padding apart; true: `padding` is the gap between two charts (as in
  // xatlas), each chart's padded raster tested against the others' bare ones.
  bool padding_between_charts = false;
};

struct PackResult {
  std::vector<RowMatrixX2d> placed_uv;  // per chart: 3F_c x 2 corner UVs in page units [0,1]
  std::vector<int> chart_page;          // per chart: output page
  std::vector<PageSize> pages;
  double scale = 1.0;                   // uniform scale finally applied (< density_scale if shrunk)
  bool shrunk = false;                  // scale < density_scale: the charts lost texel density
  double efficiency = 0.0;              // chart texels / page texels
  int padding = 0;                      // texels of padding used (see full_padding_side)
  // The exact transform, per chart: page texel = scale * R * input texel + translation,
  // R turning chart_turns quarter turns counter-clockwise (one: (x, y) -> (-y, x)).
  // The translation is whole texels, so at scale 1 texels copy 1:1.
  std::vector<int> chart_turns;  // 0..3
  RowMatrixX2d chart_translation;  // C x 2, texels
};

// chart_uv[c] holds chart c's corner UVs in texels (3 rows per face, any placement).
// Charts are rasterised conservatively, grown by options.padding, and placed
// largest first, at any quarter turn, where its top or its centroid ends
// lowest (see the page sizes below): dropped onto the horizon of what is
// already placed, or lower, into a hole under it (searched on a 2-texel grid).
// A grown raster may not meet another grown raster or, with
// padding_between_charts, another chart's raster before growing.
// Page size: by default the smallest near-square page (sides multiples of 4),
// over four orders of "largest" (box area, padded texels, long side,
// perimeter), each with charts resting by their top and by their centroid,
// then a few widths from a quarter narrower to a third wider with the recipe
// that won; or, beyond max_page_size, the fewest pages of that size (the
// last one shrunk; box area order, resting by the centroid);
// fixed_page_size: one page of exactly that side (resting by the centroid),
// charts scaled as large as fit (density_scale is then ignored). Charts keep
// at least padding / 2 texels from page borders (pages wrap, so both borders
// together give the full padding). When the pages come out under
// full_padding_side, or fit no budget at full padding, the charts are packed
// again with the padding scaled, as long as the smaller pages call for less.
// Throws InputError on bad options, rows not a multiple of 3, or a budget or
// fixed page too small for the charts' padding alone; non-finite corners are
// pulled onto their chart's mean corner.
PackResult pack_charts(const std::vector<RowMatrixX2d>& chart_uv, const PackOptions& options,
                       const RunControl& control);

constexpr int kSideQuantum = 4;  // page sides are multiples of this in PageSides::MultipleOf4

// True when a page side of `side` texels is of the kind `sides` allows (a
// fixed_page_size must be).
bool is_allowed_side(int side, PageSides sides);

// Largest side <= max_side (>= kSideQuantum) of the kind `sides` allows.
int largest_allowed_side(int max_side, PageSides sides);

// The padding pack_charts keeps on pages whose longer side is `side` texels.
int padding_for_side(const PackOptions& options, int side);

// The longest page side the texel budget leaves for one square page (or
// max_page_size without a budget): charts that fit no page at full padding
// are packed again with the padding of this side.
int budget_page_side(const PackOptions& options);

}  // namespace atlas
