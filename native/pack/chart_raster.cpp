#include "pack/chart_raster.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace atlas {
namespace {

// Texel squares are shrunk by this margin before the overlap test. It turns
// "touches the border" into "does not overlap", and it is far larger than the
// rounding of placed UVs (texels / page size * page size), so a chart
// re-rasterised from page units marks the texels it was packed with.
constexpr double kBorderSlack = 1e-6;

struct TexelRun {
  int y, x_begin, x_end;  // texels [x_begin, x_end) of row y
};

// x extent of the triangle cut to the strip y0 <= y <= y1. The cut is convex,
// so its extent comes from the corners inside the strip and the points where
// edges cross the strip's two lines. Returns false if it is empty.
bool strip_x_extent(const Eigen::Vector2d p[3], double y0, double y1, double& lo, double& hi) {
  lo = std::numeric_limits<double>::infinity();
  hi = -lo;
  auto include = [&](double x) {
    lo = std::min(lo, x);
    hi = std::max(hi, x);
  };
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d& a = p[k];
    const Eigen::Vector2d& b = p[(k + 1) % 3];
    if (a.y() >= y0 && a.y() <= y1) include(a.x());
    if (a.y() == b.y()) continue;
    for (double line : {y0, y1}) {
      const double t = (line - a.y()) / (b.y() - a.y());
      if (t >= 0.0 && t <= 1.0) include(a.x() + t * (b.x() - a.x()));
    }
  }
  return lo <= hi;
}

// Texel i overlaps [lo, hi] (after shrinking) iff lo <= i + 1 - slack and
// hi >= i + slack.
int first_texel(double lo) { return static_cast<int>(std::ceil(lo - 1.0 + kBorderSlack)); }
int last_texel(double hi) { return static_cast<int>(std::floor(hi - kBorderSlack)); }

// One run per texel row the triangle overlaps: in each row the overlapped
// texels are exactly those meeting the x extent of the triangle cut to the
// (shrunk) row, since a texel spans the row's full height.
void append_triangle_runs(const Eigen::Vector2d p[3], std::vector<TexelRun>& runs) {
  const double y_min = std::min({p[0].y(), p[1].y(), p[2].y()});
  const double y_max = std::max({p[0].y(), p[1].y(), p[2].y()});
  for (int y = first_texel(y_min); y <= last_texel(y_max); ++y) {
    double lo, hi;
    if (!strip_x_extent(p, y + kBorderSlack, y + 1 - kBorderSlack, lo, hi)) continue;
    const int x_first = first_texel(lo), x_last = last_texel(hi);
    if (x_first <= x_last) runs.push_back({y, x_first, x_last + 1});
  }
}

}  // namespace

TexelMask rasterize_chart(const RowMatrixX2d& corner_texels) {
  std::vector<TexelRun> runs;
  runs.reserve(corner_texels.rows());  // about one row per face for dense meshes
  for (Eigen::Index f = 0; f + 2 < corner_texels.rows(); f += 3) {
    const Eigen::Vector2d p[3] = {corner_texels.row(f).transpose(),
                                  corner_texels.row(f + 1).transpose(),
                                  corner_texels.row(f + 2).transpose()};
    append_triangle_runs(p, runs);
  }
  if (runs.empty()) {
    // No area (a point, or segments along texel borders): the texels of its
    // corners' box, so that a placed chart keeps every corner on its page.
    Eigen::Vector2d lo = Eigen::Vector2d::Zero(), hi = Eigen::Vector2d::Zero();
    if (corner_texels.rows() > 0) {
      lo = corner_texels.colwise().minCoeff().transpose().array().floor();
      hi = corner_texels.colwise().maxCoeff().transpose().array().floor();
    }
    for (int y = static_cast<int>(lo.y()); y <= static_cast<int>(hi.y()); ++y)
      runs.push_back({y, static_cast<int>(lo.x()), static_cast<int>(hi.x()) + 1});
  }
  int x_min = runs[0].x_begin, x_max = runs[0].x_end, y_min = runs[0].y, y_max = runs[0].y;
  for (const TexelRun& run : runs) {
    x_min = std::min(x_min, run.x_begin);
    x_max = std::max(x_max, run.x_end);
    y_min = std::min(y_min, run.y);
    y_max = std::max(y_max, run.y);
  }
  TexelMask mask(x_max - x_min, y_max - y_min + 1, x_min, y_min);
  for (const TexelRun& run : runs)
    set_bits(mask.row(run.y - y_min), run.x_begin - x_min, run.x_end - x_min);
  return mask;
}

TexelMask dilate_mask(const TexelMask& mask, int padding) {
  if (padding <= 0) return mask;
  // Square dilation is separable: widen every run of each row by padding on
  // both sides, then OR each output row with its 2*padding neighbours.
  TexelMask out(mask.width + 2 * padding, mask.height + 2 * padding, mask.origin_x - padding,
                mask.origin_y - padding);
  TexelMask widened(out.width, mask.height, out.origin_x, mask.origin_y);
  for (int y = 0; y < mask.height; ++y) {
    const std::uint64_t* row = mask.row(y);
    for (int x = find_bit(row, 0, mask.width, true); x < mask.width;) {
      const int end = find_bit(row, x, mask.width, false);
      set_bits(widened.row(y), x, end + 2 * padding);  // [x - p, end + p) shifted by +p
      x = find_bit(row, end, mask.width, true);
    }
  }
  for (int y = 0; y < out.height; ++y) {
    std::uint64_t* dst = out.row(y);
    // out row y = source rows y - 2p .. y (out is shifted up by padding).
    for (int src = std::max(0, y - 2 * padding); src <= std::min(mask.height - 1, y); ++src) {
      const std::uint64_t* s = widened.row(src);
      for (int k = 0; k < out.words_per_row; ++k) dst[k] |= s[k];
    }
  }
  return out;
}

}  // namespace atlas
