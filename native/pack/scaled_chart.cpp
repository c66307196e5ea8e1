#include "pack/scaled_chart.hpp"

#include "core/parallel_for.hpp"
#include "pack/chart_raster.hpp"
#include "pack/coarse_mask.hpp"

namespace atlas {
namespace {

// The mask turned by a half turn about the frame's origin: texel (i, j) of
// the frame goes to texel (-i - 1, -j - 1).
TexelMask half_turned(const TexelMask& mask) {
  TexelMask out(mask.width, mask.height, -(mask.origin_x + mask.width),
                -(mask.origin_y + mask.height));
  for (int y = 0; y < mask.height; ++y) {
    const std::uint64_t* row = mask.row(y);
    std::uint64_t* turned = out.row(mask.height - 1 - y);
    for (int x = find_bit(row, 0, mask.width, true); x < mask.width;) {
      const int end = find_bit(row, x, mask.width, false);
      set_bits(turned, mask.width - end, mask.width - x);
      x = find_bit(row, end, mask.width, true);
    }
  }
  return out;
}

void set_turn(ScaledChart& chart, int turn, int cell, TexelMask dilated) {
  chart.cells[turn] = make_placement_shape(coarsen_mask(
      dilated, 0, 0, cell, (dilated.width + cell - 1) / cell, (dilated.height + cell - 1) / cell));
  chart.turned[turn] = make_placement_shape(std::move(dilated));
}

ScaledChart scale_chart(const RowMatrixX2d& uv, double scale, int padding, int cell,
                        bool keep_bare) {
  ScaledChart chart;
  for (int turn = 0; turn < 2; ++turn) {
    RowMatrixX2d corners = turned_corners(uv, scale, turn);
    // Whole texels keep the texel grid, so texels copy 1:1 at scale 1.
    chart.shift[turn].setZero();
    if (corners.rows() > 0) chart.shift[turn] = corners.colwise().minCoeff().array().floor();
    corners.rowwise() -= chart.shift[turn];
    const TexelMask raster = rasterize_chart(corners);
    chart.raster_texels[turn] = count_set_texels(raster);
    if (keep_bare) chart.bare[turn] = raster;
    set_turn(chart, turn, cell, dilate_mask(raster, padding));
  }
  // Turns 2 and 3 negate the corners of turns 0 and 1, and the conservative
  // raster is symmetric under that (texel i <-> -i - 1), as is the square
  // dilation: half-turning the masks gives the rasters of the turned corners
  // exactly, without rasterising them.
  for (int turn = 2; turn < kTurns; ++turn) {
    chart.shift[turn] = -chart.shift[turn - 2];
    chart.raster_texels[turn] = chart.raster_texels[turn - 2];
    if (keep_bare) chart.bare[turn] = half_turned(chart.bare[turn - 2]);
    set_turn(chart, turn, cell, half_turned(chart.turned[turn - 2].mask));
  }
  chart.footprint = chart.turned[0].texels;
  if (keep_bare) chart.footprint = (chart.footprint + chart.raster_texels[0]) / 2;
  return chart;
}

}  // namespace

RowMatrixX2d turned_corners(const RowMatrixX2d& uv, double scale, int turn) {
  RowMatrixX2d out(uv.rows(), 2);
  switch (turn & 3) {
    case 0:
      out = scale * uv;
      break;
    case 1:
      out.col(0) = -scale * uv.col(1);
      out.col(1) = scale * uv.col(0);
      break;
    case 2:
      out = -scale * uv;
      break;
    default:
      out.col(0) = scale * uv.col(1);
      out.col(1) = -scale * uv.col(0);
  }
  return out;
}

std::vector<ScaledChart> scale_charts(const std::vector<const RowMatrixX2d*>& chart_uv,
                                      double scale, int padding, int cell, bool keep_bare,
                                      const RunControl& control) {
  control.throw_if_cancelled();
  std::vector<ScaledChart> charts(chart_uv.size());
  const int n = static_cast<int>(chart_uv.size());
  // One chart at a time: a few large charts take most of the work, and
  // chunks of several left a core idle once they landed in one chunk.
  parallel_for(n, 1, [&](int c) {
    control.throw_if_cancelled();
    charts[c] = scale_chart(*chart_uv[c], scale, padding, cell, keep_bare);
  });
  control.throw_if_cancelled();
  return charts;
}

}  // namespace atlas
