// Exact texel-centre coverage of one 2D triangle. Vertices are snapped to
// 1/256 texel and every test is done in 64-bit integers, so two triangles that
// share an edge (same snapped vertices) never both claim a texel and never
// both miss one: a centre exactly on an edge goes to the triangle that owns
// the edge under a top-left style rule applied after orienting the triangle
// counter-clockwise (x right, y up; texel (x, y) has its centre at x+0.5, y+0.5).
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace atlas {

class TexelTriangle {
 public:
  static constexpr int kSubTexelBits = 8;
  // Vertex coordinates are clamped to +-kMaxTexelCoord texels: keeps every
  // edge function below 2^60, so no overflow whatever the input.
  static constexpr double kMaxTexelCoord = 1 << 20;

  // a, b, c in texels, any winding. Returns false (claims nothing) when the
  // snapped triangle has zero area. Call before anything else.
  bool setup(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
    const Eigen::Vector2d in[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      x_[k] = to_fixed(in[k].x());
      y_[k] = to_fixed(in[k].y());
    }
    const std::int64_t twice_area = (x_[1] - x_[0]) * (y_[2] - y_[0]) - (y_[1] - y_[0]) * (x_[2] - x_[0]);
    if (twice_area == 0) {
      row_begin = row_end = 0;
      return false;
    }
    if (twice_area < 0) {
      std::swap(x_[1], x_[2]);
      std::swap(y_[1], y_[2]);
    }
    const std::int64_t half = std::int64_t(1) << (kSubTexelBits - 1), one = std::int64_t(1) << kSubTexelBits;
    for (int k = 0; k < 3; ++k) {
      const int n = (k + 1) % 3;
      const std::int64_t dx = x_[n] - x_[k], dy = y_[n] - y_[k];
      // Of the two directions of an edge exactly one owns its centres.
      const bool owned = dy < 0 || (dy == 0 && dx > 0);
      threshold_[k] = owned ? 0 : 1;
      dx_[k] = dx;
      step_[k] = -dy * one;                 // change of the edge function per texel along x
      base_[k] = -dy * (half - x_[k]);      // x-part of the edge function at column 0
    }
    const std::int64_t ylo = std::min({y_[0], y_[1], y_[2]}), yhi = std::max({y_[0], y_[1], y_[2]});
    const std::int64_t xlo = std::min({x_[0], x_[1], x_[2]}), xhi = std::max({x_[0], x_[1], x_[2]});
    // Rows / columns whose centre lies inside the bounding box.
    row_begin = static_cast<int>(ceil_div(ylo - half, one));
    row_end = static_cast<int>(floor_div(yhi - half, one)) + 1;
    col_begin = static_cast<int>(ceil_div(xlo - half, one));
    col_end = static_cast<int>(floor_div(xhi - half, one)) + 1;
    return true;
  }

  // Columns [x0, x1) of row y whose centres the triangle claims; x0 >= x1 when none.
  // Not clipped to any page; rows outside [row_begin, row_end) give empty spans.
  void row_span(int y, int& x0, int& x1) const {
    std::int64_t lo = col_begin, hi = static_cast<std::int64_t>(col_end) - 1;
    const std::int64_t py = (static_cast<std::int64_t>(y) << kSubTexelBits) + (std::int64_t(1) << (kSubTexelBits - 1));
    for (int k = 0; k < 3 && lo <= hi; ++k) {
      // Edge function at column x: c + s * x, must be >= threshold.
      const std::int64_t c = dx_[k] * (py - y_[k]) + base_[k], s = step_[k], t = threshold_[k];
      if (s == 0) {
        if (c < t) hi = lo - 1;
      } else if (s > 0) {
        lo = std::max(lo, ceil_div(t - c, s));
      } else {
        hi = std::min(hi, floor_div(c - t, -s));
      }
    }
    x0 = static_cast<int>(lo);
    x1 = static_cast<int>(std::max(lo, hi + 1));
  }

  int row_begin = 0, row_end = 0;  // rows with a centre inside the bounding box: [begin, end)
  int col_begin = 0, col_end = 0;

 private:
  static std::int64_t to_fixed(double texels) {
    const double clamped = std::min(kMaxTexelCoord, std::max(-kMaxTexelCoord, texels));
    return static_cast<std::int64_t>(std::llround(clamped * (1 << kSubTexelBits)));
  }
  static std::int64_t floor_div(std::int64_t a, std::int64_t b) {  // b > 0
    return a >= 0 ? a / b : -((-a + b - 1) / b);
  }
  static std::int64_t ceil_div(std::int64_t a, std::int64_t b) { return -floor_div(-a, b); }

  std::int64_t x_[3], y_[3];
  std::int64_t dx_[3], step_[3], base_[3];
  int threshold_[3];
};

}  // namespace atlas
