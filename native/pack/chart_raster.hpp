// Conservative rasterisation of a chart into a texel mask, and the padding
// ring around it. The packer places these masks; tests reuse them to check
// that placed charts never share a texel.
#pragma once
#include "core/mesh.hpp"
#include "pack/texel_mask.hpp"

namespace atlas {

// Marks every texel that any triangle of the chart overlaps with positive
// area (texel (i, j) is the square [i, i+1] x [j, j+1]; corners are in texels,
// 3 rows per triangle, all finite). Touching a texel only along its border does
// not count, so a chart spanning exactly [0, 10] covers texels 0..9. The mask
// is cropped to the marked texels; a chart that marks none (no faces, or zero
// area on grid lines) still gets the one texel holding its first corner.
TexelMask rasterize_chart(const RowMatrixX2d& corner_texels);

// Grows the mask by `padding` texels in x, y and diagonally (a square
// neighbourhood), so that bilinear and mip sampling next to the chart read only
// texels the chart owns.
TexelMask dilate_mask(const TexelMask& mask, int padding);

}  // namespace atlas
