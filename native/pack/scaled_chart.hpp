// Charts rasterised at one scale, in both orientations, ready to be placed.
#pragma once
#include <array>
#include <vector>

#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "pack/placement_shape.hpp"

namespace atlas {

// Quarter turns a chart may be placed at: 0, 90, 180 and 270 degrees
// counter-clockwise, never mirrored.
constexpr int kTurns = 4;

struct ScaledChart {
  // Turn k is the chart turned k quarter turns counter-clockwise.
  std::array<PlacementShape, kTurns> turned;  // conservative raster grown by the padding
  std::array<PlacementShape, kTurns> cells;   // the same on a grid of coarser cells
  // Whole texels subtracted from scale * R * uv before rasterising, so that
  // mask coordinates stay small: mask texel (0, 0) is texel mask.origin of
  // scale * R * uv - shift.
  std::array<Eigen::RowVector2d, kTurns> shift;
  std::array<long long, kTurns> raster_texels = {};  // set before padding
  // Page texels the chart takes, for sizing pages: its padded texels, or with
  // a gap padding (half of it each side) halfway between those and the bare ones.
  long long footprint = 0;
  // Only when the padding is a gap between charts: the raster before padding,
  // its texel (0, 0) on texel (padding, padding) of `turned`.
  std::array<TexelMask, kTurns> bare;
};

// scale * R^turn * uv for uv (N,2), R the quarter turn (x, y) -> (-y, x).
RowMatrixX2d turned_corners(const RowMatrixX2d& uv, double scale, int turn);

// Every chart (corners in texels, all finite) at `scale`; `cell` texels per
// side of a coarse cell; keep_bare: also keep the rasters before padding.
// Runs on all OpenMP threads.
std::vector<ScaledChart> scale_charts(const std::vector<const RowMatrixX2d*>& chart_uv,
                                      double scale, int padding, int cell, bool keep_bare,
                                      const RunControl& control);

}  // namespace atlas
