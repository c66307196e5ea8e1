// Placing scaled charts on pages: on one page of a given size, on the
// smallest near-square page, or on as many pages of the largest size as needed.
#pragma once
#include <optional>
#include <vector>

#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "pack/pack.hpp"
#include "pack/scaled_chart.hpp"

namespace atlas {

// Holes are searched on a grid of kHoleCell x kHoleCell texel cells: 4x less
// work than texel by texel, at the price of hole spots on even texels and
// cells lost where a hole's edge crosses them (larger cells lose holes that
// small charts would fill, and save little: drops dominate the time).
constexpr int kHoleCell = 2;

// What makes a spot low for a chart: where its centroid row ends (a tall
// chart may stand where it leaves room beside it) or where its top ends (a
// long chart lies down). Which packs tighter depends on the charts.
enum class Rest { Centroid, Top };

// Pages are packed in a virtual frame reaching `margin` texels beyond every
// border: dilated masks must stay inside it, so a chart's own texels keep
// padding - margin texels from the border.
struct Frame {
  int padding = 0;
  int margin = 0;
  PageSides sides = PageSides::MultipleOf4;
  bool square = false;  // both sides equal (the larger of the two)
  // Padding as the gap between two charts: a chart's padded raster may not
  // meet another's raster before padding, so charts are `padding` apart
  // (not 2 * padding, as when every chart owns a ring of padding).
  bool gap = false;
  Rest rest = Rest::Centroid;  // how place_chart ranks the spots of a chart
};

// Texels of a page.
long long area(const PageSize& page);

// Smallest side >= `side` (and >= 1) of the kind `sides` allows.
int allowed_side(double side, PageSides sides);

// Where a chart went: its dilated mask's texel (0, 0) sits at (x, y) of the
// virtual frame of page `page`.
struct Placement {
  int page = 0;
  int x = 0, y = 0;
  int turn = 0;  // index into ScaledChart::turned
};

struct Layout {
  std::vector<Placement> placement;  // per chart
  std::vector<PageSize> pages;
};

struct OnePage {
  std::vector<Placement> placement;  // per chart; only charts in the order are set
  PageSize used;                     // extent used in the virtual frame
};

// What "largest" means when ordering charts (of the box at turn 0: its
// area, its longer side, its width + height; or the padded texels).
enum class ChartSize { BoxArea, Texels, LongSide, Perimeter };

// Charts, largest first (bounding box area by default): big charts shape the
// page, small ones fill gaps.
std::vector<int> largest_first(const std::vector<ScaledChart>& charts,
                               ChartSize size = ChartSize::BoxArea);

// Page holding `used` virtual texels, its sides of the frame's kind.
PageSize trimmed_page(PageSize used, const Frame& frame);

// The charts of `order` on one page whose virtual frame is width x height,
// or nullopt as soon as one does not fit; then *placed_texels (if given) is
// the footprints (ScaledChart::footprint) of the charts placed before.
std::optional<OnePage> pack_one_page(const std::vector<int>& order,
                                     const std::vector<ScaledChart>& charts, int width,
                                     int height, const Frame& frame, const RunControl& control,
                                     long long* placed_texels = nullptr);

// The smallest near-square page with sides <= max_side holding the charts,
// or nullopt if they need more than one page; then *placed_share (if given)
// is the share of their footprints a max_side page held before one did
// not fit (0 when they hold more texels than that page: it was not tried).
std::optional<Layout> pack_smallest_page(const std::vector<int>& order,
                                         const std::vector<ScaledChart>& charts,
                                         const Frame& frame, int max_side,
                                         const RunControl& control,
                                         double* placed_share = nullptr);

// A one-page layout (else unchanged) with the page lowered where it can be:
// the chart setting its height alone moved, if that lowers the page, to
// where its top ends lowest, whatever the frame's Rest.
void lower_single_page(Layout& layout, const std::vector<ScaledChart>& charts, const Frame& frame,
                       const RunControl& control);

// First fit over pages of max_side; the last page is then made as small as it
// can be. Every chart must fit an empty page.
Layout pack_many_pages(const std::vector<int>& order, const std::vector<ScaledChart>& charts,
                       const Frame& frame, int max_side, const RunControl& control);

}  // namespace atlas
