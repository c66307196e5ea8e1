// Reads an old texture page at one point, box-filtering over the footprint of one
// new texel so that minified charts average their texels instead of aliasing.
#pragma once
#include <Eigen/Core>

#include "bake/bake.hpp"
#include "bake/texel_encoding.hpp"

namespace atlas {

// The parallelogram one new texel covers in the old page: its edges are the old-texel
// offsets of a one-texel step along new x and new y (columns of the 2x2 Jacobian of
// new->old texel coordinates), sampled by a samples_x x samples_y stratified grid.
struct Footprint {
  Eigen::Matrix2d axes = Eigen::Matrix2d::Identity();
  int samples_x = 1;
  int samples_y = 1;
  // One tap reconstructed by Catmull-Rom over 4 x 4 texels, clamped to the
  // range of the 2 x 2 bilinear ones, instead of bilinear.
  bool cubic = false;
};

// One tap while a new texel spans at most ~1.5 old texels along both axes
// (magnification or ~1:1): Catmull-Rom where it spans at least ~2/3 of one
// (neither magnified nor minified much: a cubic keeps the detail bilinear
// blurs), bilinear where the map magnifies more (a cubic would only add
// overshoot the clamp cuts). Otherwise ceil(extent) taps per axis, capped, so
// that tap spacing stays <= 1 old texel and the average approximates a box filter.
Footprint footprint_of(const Eigen::Matrix2d& new_to_old_texels);

// Writes page.channels values to out: the footprint-weighted average of the page
// around `at` (old texel coordinates, centres at +0.5). Coordinates wrap (repeat).
template <class T>
void sample_texture(const ImageView<T>& page, const Eigen::Vector2d& at, const Footprint& footprint,
                    double* out);

}  // namespace atlas
