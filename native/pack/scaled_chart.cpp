#include "pack/scaled_chart.hpp"

#include "core/parallel_for.hpp"
#include "pack/chart_raster.hpp"
#include "pack/coarse_mask.hpp"

namespace atlas {
namespace {

ScaledChart scale_chart(const RowMatrixX2d& uv, double scale, int padding, int cell,
                        bool keep_bare) {
  ScaledChart chart;
  for (int turn = 0; turn < 2; ++turn) {
    RowMatrixX2d corners = turned_corners(uv, scale, turn);
    // Whole texels keep the texel grid, so texels copy 1:1 at scale 1.
    if (corners.rows() > 0) chart.shift[turn] = corners.colwise().minCoeff().array().floor();
    corners.rowwise() -= chart.shift[turn];
    const TexelMask raster = rasterize_chart(corners);
    chart.raster_texels[turn] = count_set_texels(raster);
    TexelMask dilated = dilate_mask(raster, padding);
    if (keep_bare) chart.bare[turn] = raster;
    chart.cells[turn] = make_placement_shape(coarsen_mask(
        dilated, 0, 0, cell, (dilated.width + cell - 1) / cell, (dilated.height + cell - 1) / cell));
    chart.turned[turn] = make_placement_shape(std::move(dilated));
  }
  chart.footprint = chart.turned[0].texels;
  if (keep_bare) chart.footprint = (chart.footprint + chart.raster_texels[0]) / 2;
  return chart;
}

}  // namespace

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

std::vector<ScaledChart> scale_charts(const std::vector<const RowMatrixX2d*>& chart_uv,
                                      double scale, int padding, int cell, bool keep_bare,
                                      const RunControl& control) {
  control.throw_if_cancelled();
  std::vector<ScaledChart> charts(chart_uv.size());
  const int n = static_cast<int>(chart_uv.size());
  parallel_for(n, 16, [&](int c) {
    control.throw_if_cancelled();
    charts[c] = scale_chart(*chart_uv[c], scale, padding, cell, keep_bare);
  });
  control.throw_if_cancelled();
  return charts;
}

}  // namespace atlas
