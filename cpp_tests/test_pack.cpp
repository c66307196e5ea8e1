#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/geometry.hpp"
#include "pack/chart_raster.hpp"
#include "pack/coarse_mask.hpp"
#include "pack/pack.hpp"
#include "pack/page_filling.hpp"
#include "pack/page_occupancy.hpp"
#include "pack/scaled_chart.hpp"
#include "pack/smallest_box_turn.hpp"

namespace atlas {
namespace {

// Axis-aligned w x h rectangle at (x, y), as two triangles.
RowMatrixX2d rectangle(double w, double h, double x = 0.0, double y = 0.0) {
  RowMatrixX2d uv(6, 2);
  uv << x, y, x + w, y, x + w, y + h,  //
      x, y, x + w, y + h, x, y + h;
  return uv;
}

// Star-shaped blob: a fan of `segments` triangles around (cx, cy) with radii in [r/2, r].
RowMatrixX2d blob(std::mt19937& rng, double r, int segments, double cx, double cy) {
  std::uniform_real_distribution<double> radius(0.5 * r, r);
  std::vector<Eigen::RowVector2d> rim(segments);
  for (int k = 0; k < segments; ++k) {
    const double a = 2.0 * kPi * k / segments;
    rim[k] = Eigen::RowVector2d(cx, cy) + radius(rng) * Eigen::RowVector2d(std::cos(a), std::sin(a));
  }
  RowMatrixX2d uv(3 * segments, 2);
  for (int k = 0; k < segments; ++k) {
    uv.row(3 * k) << cx, cy;
    uv.row(3 * k + 1) = rim[k];
    uv.row(3 * k + 2) = rim[(k + 1) % segments];
  }
  return uv;
}

std::vector<RowMatrixX2d> random_rectangles(int count, int max_side, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> side(1, max_side);
  std::uniform_real_distribution<double> where(-5000.0, 5000.0);
  std::vector<RowMatrixX2d> charts;
  for (int i = 0; i < count; ++i) charts.push_back(rectangle(side(rng), side(rng), where(rng), where(rng)));
  return charts;
}

std::vector<RowMatrixX2d> random_blobs(int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> radius(2.0, 40.0), where(-3000.0, 3000.0);
  std::uniform_int_distribution<int> segments(3, 24);
  std::vector<RowMatrixX2d> charts;
  for (int i = 0; i < count; ++i)
    charts.push_back(blob(rng, radius(rng), segments(rng), where(rng), where(rng)));
  return charts;
}

// Re-rasterises every placed chart from the result alone and checks that its
// texels lie on its page at least padding / 2 from the border, and that no
// texel of any page is claimed by two dilated charts (gap: that no dilated
// chart meets another chart's bare texels, i.e. charts are padding apart),
// for the padding the result says it kept.
void expect_valid_packing(const std::vector<RowMatrixX2d>& charts, const PackResult& result, bool gap = false) {
  const int padding = result.padding;
  ASSERT_EQ(result.placed_uv.size(), charts.size());
  ASSERT_EQ(result.chart_page.size(), charts.size());
  // Per page texel: 0, or 1 + the chart claiming it.
  std::vector<std::vector<int>> claimed;
  for (const PageSize& page : result.pages) {
    ASSERT_GT(page.width, 0);
    ASSERT_GT(page.height, 0);
    claimed.emplace_back(static_cast<size_t>(page.width) * page.height, 0);
  }
  // Calls visit(page, texel index) for each texel of `mask` on page p.
  auto for_each_texel = [&](const TexelMask& mask, int p, auto visit) {
    const PageSize page = result.pages[p];
    for (int y = 0; y < mask.height; ++y)
      for (int x = 0; x < mask.width; ++x) {
        const int px = mask.origin_x + x, py = mask.origin_y + y;
        if (mask.test(x, y) && px >= 0 && py >= 0 && px < page.width && py < page.height)
          visit(static_cast<size_t>(py) * page.width + px);
      }
  };
  std::vector<TexelMask> bare(charts.size());
  const int border = padding - padding / 2;
  for (size_t c = 0; c < charts.size(); ++c) {
    if (result.placed_uv[c].rows() == 0) continue;  // no faces: nothing to re-rasterise
    const int p = result.chart_page[c];
    ASSERT_GE(p, 0);
    ASSERT_LT(p, static_cast<int>(result.pages.size()));
    const PageSize page = result.pages[p];
    RowMatrixX2d texels = result.placed_uv[c];
    ASSERT_TRUE(texels.allFinite()) << "chart " << c;
    texels.col(0) *= page.width;
    texels.col(1) *= page.height;
    const TexelMask own = rasterize_chart(texels);
    EXPECT_GE(own.origin_x, border) << "chart " << c;
    EXPECT_GE(own.origin_y, border) << "chart " << c;
    EXPECT_LE(own.origin_x + own.width, page.width - border) << "chart " << c;
    EXPECT_LE(own.origin_y + own.height, page.height - border) << "chart " << c;
    int collisions = 0;
    for_each_texel(gap ? own : dilate_mask(own, padding), p, [&](size_t i) {
      collisions += claimed[p][i] != 0;
      claimed[p][i] = static_cast<int>(c) + 1;
    });
    EXPECT_EQ(collisions, 0) << "chart " << c << " overlaps an earlier chart on page " << p;
    if (gap) bare[c] = own;
  }
  for (size_t c = 0; gap && c < charts.size(); ++c) {
    if (result.placed_uv[c].rows() == 0) continue;
    const int p = result.chart_page[c];
    int near = 0;
    for_each_texel(dilate_mask(bare[c], padding), p, [&](size_t i) {
      near += claimed[p][i] != 0 && claimed[p][i] != static_cast<int>(c) + 1;
    });
    EXPECT_EQ(near, 0) << "chart " << c << " is less than the padding from another chart";
  }
}

// placed_uv must be exactly scale * R * uv + translation, in page units.
void expect_reported_transform(const std::vector<RowMatrixX2d>& charts, const PackResult& result) {
  ASSERT_EQ(result.chart_translation.rows(), static_cast<Eigen::Index>(charts.size()));
  for (size_t c = 0; c < charts.size(); ++c) {
    const PageSize page = result.pages[result.chart_page[c]];
    const Eigen::RowVector2d t = result.chart_translation.row(c);
    for (Eigen::Index i = 0; i < charts[c].rows(); ++i) {
      const double u = charts[c](i, 0), v = charts[c](i, 1);
      Eigen::RowVector2d turned(u, v);
      for (int k = 0; k < result.chart_turns[c]; ++k) turned = Eigen::RowVector2d(-turned.y(), turned.x());
      const Eigen::RowVector2d expected = result.scale * turned + t;
      EXPECT_NEAR(result.placed_uv[c](i, 0) * page.width, expected.x(), 1e-6);
      EXPECT_NEAR(result.placed_uv[c](i, 1) * page.height, expected.y(), 1e-6);
    }
  }
}

long long total_page_texels(const PackResult& result) {
  long long total = 0;
  for (const PageSize& p : result.pages) total += static_cast<long long>(p.width) * p.height;
  return total;
}

TEST(RasterizeChart, CoversOverlappedTexelsOnly) {
  // Edges on grid lines claim nothing beyond them.
  const TexelMask square = rasterize_chart(rectangle(10, 10, 0, 0));
  EXPECT_EQ(square.width, 10);
  EXPECT_EQ(square.height, 10);
  EXPECT_EQ(count_set_texels(square), 100);
  // The hypotenuse x + y = 2 only touches texel (1, 1) at its corner.
  RowMatrixX2d tri(3, 2);
  tri << 0.5, 0.5, 1.5, 0.5, 0.5, 1.5;
  const TexelMask t = rasterize_chart(tri);
  EXPECT_EQ(count_set_texels(t), 3);
  EXPECT_TRUE(t.test(0, 0) && t.test(1, 0) && t.test(0, 1));
  // A sliver that crosses a texel without covering any texel centre still claims it.
  tri << 0.0, 0.1, 3.0, 0.1, 3.0, 0.15;
  EXPECT_EQ(count_set_texels(rasterize_chart(tri)), 3);
  // Square dilation: one texel grown by 2 is a 5 x 5 block.
  const TexelMask dot = dilate_mask(rasterize_chart(rectangle(0.5, 0.5, 7.2, 3.2)), 2);
  EXPECT_EQ(dot.width, 5);
  EXPECT_EQ(dot.origin_x, 5);
  EXPECT_EQ(count_set_texels(dot), 25);
}

TEST(CoarsenMask, CellIsSetWhenAnyTexelIs) {
  // Texels 3..5 of row 2, placed at (6, 1): page texels 9..11 of row 3, i.e.
  // cells 2 (texels 8..11) of cell row 0 for 4 x 4 cells.
  TexelMask mask(8, 4, 0, 0);
  set_bits(mask.row(2), 3, 6);
  const TexelMask cells = coarsen_mask(mask, 6, 1, 4, 100, 100);
  EXPECT_EQ(cells.origin_x, 1);
  EXPECT_EQ(cells.origin_y, 0);
  EXPECT_EQ(count_set_texels(cells), 1);
  EXPECT_TRUE(cells.test(2 - cells.origin_x, 0));
  // Cells beyond the grid are dropped.
  EXPECT_EQ(coarsen_mask(mask, 6, 1, 4, 2, 100).width, 1);
  EXPECT_EQ(coarsen_mask(mask, 6, 1, 4, 1, 100).width, 0);
}

// A bridge (an upside-down U) over an empty pocket, with 5-texel gaps at the
// page sides: an 8 x 8 square dropped straight down rests on the deck, the
// hole search finds the pocket under it.
TEST(PageOccupancy, DropRestsOnTheDeckAndFirstFitFindsThePocket) {
  PageOccupancy page(40, 64);
  TexelMask bridge(30, 20, 0, 0);  // legs of 4 texels, deck of rows 16..19
  for (int y = 0; y < 20; ++y) {
    set_bits(bridge.row(y), 0, y < 16 ? 4 : 30);
    set_bits(bridge.row(y), 26, 30);
  }
  page.occupy(bridge, 5, 0);
  EXPECT_EQ(page.used_width(), 35);
  EXPECT_EQ(page.used_height(), 20);
  TexelMask square(8, 8, 0, 0);
  for (int y = 0; y < 8; ++y) set_bits(square.row(y), 0, 8);
  const PlacementShape shape = make_placement_shape(square);
  const auto drop = page.lowest_drop(shape, page.height());
  ASSERT_TRUE(drop);
  EXPECT_EQ(*drop, Eigen::Vector2i(0, 20));
  const auto hole = page.first_fit(shape, page.height());
  ASSERT_TRUE(hole);
  EXPECT_EQ(*hole, Eigen::Vector2i(9, 0));
  // Nothing fits under a top limit of 7 rows; once the pocket holds one
  // square, the next one goes beside it.
  EXPECT_FALSE(page.lowest_drop(shape, 7));
  page.occupy(square, 9, 0);
  EXPECT_EQ(*page.first_fit(shape, page.height()), Eigen::Vector2i(17, 0));
}

// A long chart lying on top of a tall one sets the page's height; standing
// beside it, it does not: lowering the page moves it there.
TEST(LowerSinglePage, TheChartSettingTheHeightStandsBesideTheOthers) {
  const RowMatrixX2d tall = rectangle(60, 100), long_chart = rectangle(100, 20);
  const Frame frame{4, 2};
  const std::vector<ScaledChart> charts =
      scale_charts({&tall, &long_chart}, 1.0, frame.padding, kHoleCell, false, RunControl());
  const int tall_height = charts[0].turned[0].mask.height;
  Layout layout;
  layout.placement = {{0, 0, 0, 0}, {0, 0, tall_height, 0}};  // the long chart on top
  const PageSize stacked = trimmed_page(
      {charts[1].turned[0].mask.width, tall_height + charts[1].turned[0].mask.height}, frame);
  layout.pages = {stacked};
  lower_single_page(layout, charts, frame, RunControl());
  ASSERT_EQ(layout.pages.size(), 1u);
  EXPECT_LE(layout.pages[0].width, stacked.width);
  EXPECT_EQ(layout.pages[0].height, trimmed_page({1, tall_height}, frame).height);
  const Placement& moved = layout.placement[1];
  EXPECT_EQ(moved.turn % 2, 1);
  EXPECT_GE(moved.x, charts[0].turned[0].mask.width);  // beside, not over, the tall chart
  EXPECT_EQ(layout.placement[0].y, 0);
}

TEST(PackCharts, RandomRectanglesNeverShareATexel) {
  const auto charts = random_rectangles(400, 60, 7);
  PackOptions options;
  options.padding = 4;
  const PackResult result = pack_charts(charts, options, RunControl());
  ASSERT_EQ(result.pages.size(), 1u);
  expect_valid_packing(charts, result);
  expect_reported_transform(charts, result);
  EXPECT_DOUBLE_EQ(result.scale, 1.0);
  EXPECT_GT(result.efficiency, 0.5);
  for (Eigen::Index c = 0; c < result.chart_translation.rows(); ++c)
    for (int k = 0; k < 2; ++k)  // whole texels: charts can be copied 1:1
      EXPECT_EQ(result.chart_translation(c, k), std::round(result.chart_translation(c, k)));
}

TEST(PackCharts, BlobsNeverShareATexel) {
  const auto charts = random_blobs(500, 11);
  PackOptions options;
  options.padding = 2;
  options.density_scale = 1.5;
  const PackResult result = pack_charts(charts, options, RunControl());
  expect_valid_packing(charts, result);
  expect_reported_transform(charts, result);
  EXPECT_DOUBLE_EQ(result.scale, 1.5);
  EXPECT_GT(result.efficiency, 0.45);
}

// Turns 2 and 3 are half-turned copies of the masks of turns 0 and 1; they
// must be exactly what rasterising the turned corners gives.
TEST(ScaleCharts, HalfTurnedMasksAreTheRastersOfTheTurnedCorners) {
  std::mt19937 rng(4);
  std::vector<RowMatrixX2d> charts;
  for (int i = 0; i < 20; ++i) charts.push_back(blob(rng, 30.0, 12, 0.37 * i - 3.1, 1.9 * i + 0.23));
  std::vector<const RowMatrixX2d*> uv;
  for (const RowMatrixX2d& c : charts) uv.push_back(&c);
  const int padding = 3;
  const std::vector<ScaledChart> scaled = scale_charts(uv, 1.3, padding, 2, true, RunControl());
  auto same = [](const TexelMask& a, const TexelMask& b) {
    return a.width == b.width && a.height == b.height && a.origin_x == b.origin_x &&
           a.origin_y == b.origin_y && a.words == b.words;
  };
  for (size_t c = 0; c < charts.size(); ++c)
    for (int turn = 0; turn < kTurns; ++turn) {
      const ScaledChart& chart = scaled[c];
      RowMatrixX2d corners = turned_corners(charts[c], 1.3, turn);
      corners.rowwise() -= chart.shift[turn];
      const TexelMask raster = rasterize_chart(corners);
      EXPECT_TRUE(same(chart.bare[turn], raster)) << "chart " << c << " turn " << turn;
      EXPECT_TRUE(same(chart.turned[turn].mask, dilate_mask(raster, padding)))
          << "chart " << c << " turn " << turn;
      EXPECT_EQ(chart.raster_texels[turn], count_set_texels(raster));
    }
}

// The share of page texels the charts cover on fixed sets of blobs at the
// default padding (4 texels, not scaled to these small pages), as reached by
// the packer: a change that packs worse fails.
TEST(PackCharts, EfficiencyOnBlobsAtTheDefaultPadding) {
  double sum = 0.0;
  PackOptions options;
  options.full_padding_side = 0;
  for (unsigned seed : {3u, 5u, 11u}) {
    const auto charts = random_blobs(300, seed);
    const PackResult result = pack_charts(charts, options, RunControl());
    ASSERT_EQ(result.pages.size(), 1u);
    sum += result.efficiency;
  }
  EXPECT_GE(sum / 3.0, 0.497);
}

// Padding as the gap between charts: charts padding apart, not 2 * padding,
// so the same charts take fewer texels.
TEST(PackCharts, PaddingBetweenChartsKeepsTheGapOnly) {
  const auto charts = random_blobs(300, 5);
  PackOptions options;
  options.padding = 4;
  const PackResult ring = pack_charts(charts, options, RunControl());
  options.padding_between_charts = true;
  const PackResult gap = pack_charts(charts, options, RunControl());
  expect_valid_packing(charts, gap, true);
  expect_reported_transform(charts, gap);
  EXPECT_LT(total_page_texels(gap), total_page_texels(ring));
  EXPECT_GT(gap.efficiency, 0.55);
}

// Pages under full_padding_side texels get padding in proportion to their
// longer side, at least 2 texels and never more than asked for.
TEST(PackCharts, SmallPagesGetPaddingInProportionToTheirSide) {
  const auto charts = random_blobs(300, 5);
  PackOptions options;
  options.full_padding_side = 0;
  const PackResult full = pack_charts(charts, options, RunControl());
  EXPECT_EQ(full.padding, 4);
  options.full_padding_side = PackOptions().full_padding_side;
  const PackResult scaled = pack_charts(charts, options, RunControl());
  const int side = std::max(full.pages[0].width, full.pages[0].height);
  ASSERT_LT(side, 896);  // 4 * side / 1024 rounds below 4
  EXPECT_LE(scaled.padding, std::max(2L, std::lround(4.0 * side / 1024)));
  // Packed again until its own page calls for no less padding than it got.
  const int scaled_side = std::max(scaled.pages[0].width, scaled.pages[0].height);
  EXPECT_GE(padding_for_side(options, scaled_side), scaled.padding);
  expect_valid_packing(charts, scaled);
  EXPECT_LT(total_page_texels(scaled), total_page_texels(full));

  for (const auto& [side, padding] : {std::pair{512, 2}, {768, 3}, {1024, 4}, {2048, 4}, {256, 2}}) {
    options.fixed_page_size = side;
    const PackResult fixed = pack_charts(charts, options, RunControl());
    EXPECT_EQ(fixed.padding, padding) << "page side " << side;
    expect_valid_packing(charts, fixed);
  }
  options.fixed_page_size = 0;
  options.padding = 1;
  EXPECT_EQ(pack_charts(charts, options, RunControl()).padding, 1);
}

TEST(PackCharts, DefaultPageIsSmallAndNearSquare) {
  std::vector<RowMatrixX2d> charts;
  for (int i = 0; i < 100; ++i) charts.push_back(rectangle(10, 10, 13.0 * i, 0.0));
  PackOptions options;
  options.padding = 4;
  const PackResult result = pack_charts(charts, options, RunControl());
  ASSERT_EQ(result.pages.size(), 1u);
  const PageSize page = result.pages[0];
  const double dilated = 100.0 * (10 + 2 * options.padding) * (10 + 2 * options.padding);
  EXPECT_LT(static_cast<double>(page.width) * page.height, 3.0 * dilated);
  EXPECT_EQ(page.width % 4, 0);
  EXPECT_EQ(page.height % 4, 0);
  EXPECT_LE(std::max(page.width, page.height), 2 * std::min(page.width, page.height));
  expect_valid_packing(charts, result);
}

TEST(PackCharts, TexelBudgetShrinksCharts) {
  const auto charts = random_rectangles(200, 40, 3);
  PackOptions options;
  options.padding = 2;
  const PackResult full = pack_charts(charts, options, RunControl());
  options.texel_budget = total_page_texels(full) / 3;
  const PackResult shrunk = pack_charts(charts, options, RunControl());
  EXPECT_LT(shrunk.scale, 1.0);
  EXPECT_GT(shrunk.scale, 0.3);  // not needlessly small
  EXPECT_LE(total_page_texels(shrunk), options.texel_budget);
  expect_valid_packing(charts, shrunk);
  expect_reported_transform(charts, shrunk);
}

TEST(PackCharts, MaxPageSizeSpillsOntoMorePages) {
  const auto charts = random_rectangles(300, 40, 5);
  PackOptions options;
  options.padding = 3;
  options.max_page_size = 256;
  const PackResult result = pack_charts(charts, options, RunControl());
  EXPECT_GT(result.pages.size(), 1u);
  for (const PageSize& page : result.pages) {
    EXPECT_LE(page.width, 256);
    EXPECT_LE(page.height, 256);
  }
  EXPECT_DOUBLE_EQ(result.scale, 1.0);
  expect_valid_packing(charts, result);
  // Fewest pages: all but the last are well filled.
  EXPECT_GT(result.efficiency, 0.5);
}

TEST(PackCharts, MaxPagesShrinksChartsOnlyWhenTheyDoNotFit) {
  const auto charts = random_rectangles(300, 40, 5);
  PackOptions options;
  options.padding = 3;
  options.max_page_size = 256;
  options.max_pages = 1;
  const PackResult shrunk = pack_charts(charts, options, RunControl());
  ASSERT_EQ(shrunk.pages.size(), 1u);
  EXPECT_LT(shrunk.scale, 1.0);
  // Not needlessly small: 2% more and the charts take a second page.
  PackOptions larger = options;
  larger.max_pages = 0;
  larger.density_scale = 1.02 * shrunk.scale;
  EXPECT_GT(pack_charts(charts, larger, RunControl()).pages.size(), 1u);
  EXPECT_TRUE(shrunk.shrunk);
  expect_valid_packing(charts, shrunk);
  expect_reported_transform(charts, shrunk);

  options.max_page_size = 2048;  // room enough: full density, no warning
  const PackResult full = pack_charts(charts, options, RunControl());
  EXPECT_DOUBLE_EQ(full.scale, 1.0);
  EXPECT_FALSE(full.shrunk);
}

TEST(PackCharts, EveryPageSideModeGivesPagesOfItsKind) {
  const auto charts = random_blobs(200, 4);
  PackOptions tight_options;
  tight_options.padding = 2;
  tight_options.page_sides = PageSides::Tight;
  const PageSize tight = pack_charts(charts, tight_options, RunControl()).pages[0];
  for (PageSides sides : {PageSides::Tight, PageSides::MultipleOf4, PageSides::PowerOfTwo})
    for (bool square : {false, true}) {
      PackOptions options;
      options.padding = 2;
      options.page_sides = sides;
      options.square_pages = square;
      const PackResult result = pack_charts(charts, options, RunControl());
      ASSERT_EQ(result.pages.size(), 1u);
      const PageSize page = result.pages[0];
      if (sides == PageSides::MultipleOf4) {
        EXPECT_EQ(page.width % 4, 0);
        EXPECT_EQ(page.height % 4, 0);
      }
      if (sides == PageSides::PowerOfTwo) {
        EXPECT_EQ(page.width & (page.width - 1), 0) << page.width;
        EXPECT_EQ(page.height & (page.height - 1), 0) << page.height;
      }
      if (square) {
        EXPECT_EQ(page.width, page.height);
      }
      EXPECT_DOUBLE_EQ(result.scale, 1.0);
      // Rounding costs at most 2x per side for powers of two, and the square
      // takes the longer side of a near-square page.
      const double side_growth = (sides == PageSides::PowerOfTwo ? 2.0 : 1.1) * (square ? 1.3 : 1.0);
      EXPECT_LE(page.width, side_growth * std::max(tight.width, tight.height)) << page.width;
      EXPECT_LE(page.height, side_growth * std::max(tight.width, tight.height)) << page.height;
      EXPECT_LE(static_cast<double>(page.width) * page.height,
                side_growth * side_growth * tight.width * tight.height);
      expect_valid_packing(charts, result);
    }
}

TEST(PackCharts, PowerOfTwoPagesOnManyPagesToo) {
  const auto charts = random_rectangles(300, 40, 5);
  PackOptions options;
  options.padding = 3;
  options.max_page_size = 300;  // pages of at most 256
  options.page_sides = PageSides::PowerOfTwo;
  const PackResult result = pack_charts(charts, options, RunControl());
  EXPECT_GT(result.pages.size(), 1u);
  for (const PageSize& page : result.pages) {
    EXPECT_LE(page.width, 256);
    EXPECT_EQ(page.width & (page.width - 1), 0) << page.width;
    EXPECT_EQ(page.height & (page.height - 1), 0) << page.height;
  }
  expect_valid_packing(charts, result);
}

// Thousands of charts on one UV area (duplicated meshes, scan debris) used to
// make every scale try of the budget search rasterise them all at full size.
TEST(PackCharts, TenThousandStackedChartsPackWithinTheLimits) {
  std::mt19937 rng(9);
  std::vector<RowMatrixX2d> charts;
  for (int i = 0; i < 10000; ++i) charts.push_back(blob(rng, 512.0, 12, 512.0, 512.0));
  PackOptions options;
  options.texel_budget = 1024 * 1024;
  const PackResult result = pack_charts(charts, options, RunControl());
  EXPECT_LE(total_page_texels(result), options.texel_budget);
  EXPECT_TRUE(result.shrunk);
  expect_valid_packing(charts, result);

  options.texel_budget = 0;
  options.max_pages = 1;
  options.max_page_size = 4096;
  const PackResult one_page = pack_charts(charts, options, RunControl());
  ASSERT_EQ(one_page.pages.size(), 1u);
  EXPECT_GT(one_page.efficiency, 0.4);
  expect_valid_packing(charts, one_page);
}

TEST(SmallestBoxTurn, TurnsATiltedRectangleUprightWithoutMirroring) {
  const double a = 0.5236;  // 30 degrees
  Eigen::Matrix2d r;
  r << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  const RowMatrixX2d tilted = (rectangle(40, 10, 5, 7) * r.transpose()).eval();
  const RowMatrixX2d upright = turned_to_smallest_box(tilted);
  const Eigen::RowVector2d extent = upright.colwise().maxCoeff() - upright.colwise().minCoeff();
  EXPECT_NEAR(extent.x() * extent.y(), 400.0, 1e-6);
  auto signed_area = [](const RowMatrixX2d& uv) {
    const Eigen::RowVector2d e1 = uv.row(1) - uv.row(0), e2 = uv.row(2) - uv.row(0);
    return e1.x() * e2.y() - e1.y() * e2.x();
  };
  EXPECT_NEAR(signed_area(upright), signed_area(tilted), 1e-9);  // a turn, not a mirror
  // Lengths are kept: the texel density does not change.
  EXPECT_NEAR((upright.row(1) - upright.row(0)).norm(), 40.0, 1e-9);

  // Nothing to turn: a point, a segment, non-finite corners.
  const RowMatrixX2d point = RowMatrixX2d::Constant(3, 2, 1.5);
  EXPECT_EQ(turned_to_smallest_box(point), point);
  RowMatrixX2d bad = tilted;
  bad(2, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(turned_to_smallest_box(bad).row(0).isApprox(bad.row(0)));
}

TEST(PackCharts, ChartLargerThanMaxPageIsScaledDown) {
  const std::vector<RowMatrixX2d> charts = {rectangle(500, 100), rectangle(20, 20)};
  PackOptions options;
  options.max_page_size = 128;
  const PackResult result = pack_charts(charts, options, RunControl());
  EXPECT_LT(result.scale, 128.0 / 500.0);
  EXPECT_EQ(result.pages.size(), 1u);
  expect_valid_packing(charts, result);
}

TEST(PackCharts, FixedPageSizeFitsOnePageAsLargeAsPossible) {
  const auto charts = random_blobs(150, 2);
  PackOptions options;
  options.padding = 2;
  options.fixed_page_size = 512;
  const PackResult result = pack_charts(charts, options, RunControl());
  ASSERT_EQ(result.pages.size(), 1u);
  EXPECT_EQ(result.pages[0].width, 512);
  EXPECT_EQ(result.pages[0].height, 512);
  EXPECT_GT(result.scale, 0.0);
  EXPECT_GT(result.efficiency, 0.4);  // the page is filled, not just fitted
  expect_valid_packing(charts, result);
  expect_reported_transform(charts, result);

  // Small charts are scaled up to fill the page.
  const PackResult grown = pack_charts({rectangle(10, 10), rectangle(5, 20)}, options, RunControl());
  EXPECT_GT(grown.scale, 5.0);
}

// A chart longer than a near-square page would be wide lies across a page
// as wide as it instead of standing and setting the page's height.
TEST(PackCharts, LongestChartLiesAcrossTheDefaultPage) {
  std::vector<RowMatrixX2d> charts = {rectangle(60, 600, 5, 5)};
  for (int i = 0; i < 20; ++i) charts.push_back(rectangle(20, 20, 30.0 * i, 700));
  PackOptions options;
  options.padding = 4;
  const PackResult result = pack_charts(charts, options, RunControl());
  ASSERT_EQ(result.pages.size(), 1u);
  EXPECT_EQ(result.chart_turns[0] % 2, 1);
  EXPECT_LT(result.pages[0].height, 600);
  EXPECT_GE(result.pages[0].width, 600);
  expect_valid_packing(charts, result);
  expect_reported_transform(charts, result);
}

// A small chart goes into the mouth of a U-shaped one (a concavity of a
// placed chart), so the page is no larger than the U's alone.
TEST(PackCharts, SmallChartFillsTheGapOfAConcaveChart) {
  RowMatrixX2d u(18, 2);
  u << rectangle(40, 200, 0, 0), rectangle(40, 200, 160, 0), rectangle(120, 40, 40, 0);
  PackOptions options;
  options.padding = 4;
  const PackResult alone = pack_charts({u}, options, RunControl());
  const std::vector<RowMatrixX2d> charts = {u, rectangle(60, 60, 300, 300)};
  const PackResult result = pack_charts(charts, options, RunControl());
  ASSERT_EQ(result.pages.size(), 1u);
  EXPECT_EQ(total_page_texels(result), total_page_texels(alone));
  // The small chart's box lies inside the U's box.
  const Eigen::RowVector2d u_lo = result.placed_uv[0].colwise().minCoeff();
  const Eigen::RowVector2d u_hi = result.placed_uv[0].colwise().maxCoeff();
  EXPECT_TRUE((result.placed_uv[1].colwise().minCoeff().array() > u_lo.array()).all());
  EXPECT_TRUE((result.placed_uv[1].colwise().maxCoeff().array() < u_hi.array()).all());
  expect_valid_packing(charts, result);
  expect_reported_transform(charts, result);
}

TEST(PackCharts, LongChartIsRotatedToFit) {
  // At the largest scale (set by the wide chart's width) the tall chart only
  // fits lying down in the strip above the wide one.
  const std::vector<RowMatrixX2d> charts = {rectangle(240, 150, 30, 40), rectangle(30, 200, -7, 3)};
  PackOptions options;
  options.padding = 2;
  options.fixed_page_size = 256;
  const PackResult result = pack_charts(charts, options, RunControl());
  EXPECT_EQ(result.chart_turns[0] % 2, 0);
  EXPECT_EQ(result.chart_turns[1] % 2, 1);
  const Eigen::RowVector2d extent =
      result.placed_uv[1].colwise().maxCoeff() - result.placed_uv[1].colwise().minCoeff();
  EXPECT_GT(extent.x(), 4.0 * extent.y());
  EXPECT_GT(result.scale, 1.0);
  expect_valid_packing(charts, result);
  expect_reported_transform(charts, result);
}

TEST(PackCharts, AChartWithoutAreaKeepsItsCornersOnThePage) {
  // Corners on one texel row: no texel overlaps the chart, but it spans 200.
  RowMatrixX2d segment(3, 2);
  segment << 0, 0, 100, 0, 200, 0;
  const PackResult result = pack_charts({segment, rectangle(6, 6)}, PackOptions(), RunControl());
  ASSERT_EQ(result.pages.size(), 1u);
  for (const RowMatrixX2d& uv : result.placed_uv) {
    EXPECT_GE(uv.minCoeff(), 0.0);
    EXPECT_LE(uv.maxCoeff(), 1.0);
  }
}

TEST(PackCharts, DegenerateInputs) {
  RowMatrixX2d point(3, 2), with_nan = rectangle(8, 8, 100, 100);
  point << 5, 5, 5, 5, 5, 5;
  with_nan(2, 0) = std::nan("");
  const std::vector<RowMatrixX2d> charts = {point, with_nan, RowMatrixX2d(0, 2), rectangle(12, 3)};
  PackOptions options;
  const PackResult result = pack_charts(charts, options, RunControl());
  for (const RowMatrixX2d& uv : result.placed_uv) EXPECT_TRUE(uv.allFinite());
  // The point still owns a texel of its own.
  RowMatrixX2d placed = result.placed_uv[0];
  placed.col(0) *= result.pages[0].width;
  placed.col(1) *= result.pages[0].height;
  EXPECT_EQ(count_set_texels(rasterize_chart(placed)), 1);
  const std::vector<RowMatrixX2d> finite = {point, rectangle(8, 8), RowMatrixX2d(0, 2), rectangle(12, 3)};
  expect_valid_packing(finite, result);
  EXPECT_GT(result.efficiency, 0.0);

  const PackResult empty = pack_charts({}, options, RunControl());
  ASSERT_EQ(empty.pages.size(), 1u);
  EXPECT_EQ(empty.pages[0].width, 4);
  EXPECT_EQ(empty.pages[0].height, 4);
  EXPECT_TRUE(empty.placed_uv.empty());
}

TEST(PackCharts, RejectsBadOptions) {
  const std::vector<RowMatrixX2d> charts = {rectangle(4, 4)};
  PackOptions options;
  options.padding = -1;
  EXPECT_THROW(pack_charts(charts, options, RunControl()), InputError);
  options = PackOptions();
  options.fixed_page_size = 64;
  options.texel_budget = 1000;
  EXPECT_THROW(pack_charts(charts, options, RunControl()), InputError);
  options = PackOptions();
  EXPECT_THROW(pack_charts({RowMatrixX2d(4, 2)}, options, RunControl()), InputError);
}

TEST(PackCharts, CancelledControlThrows) {
  RunControl control;
  control.cancel();
  EXPECT_THROW(pack_charts(random_rectangles(50, 20, 1), PackOptions(), control), Cancelled);
}

}  // namespace
}  // namespace atlas
