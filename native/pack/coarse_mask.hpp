// Coarse copy of a texel mask: texels grouped into factor x factor cells, a
// cell set when any of its texels is. Where a coarse mask fits among coarse
// occupied cells, the texel mask fits among the occupied texels too.
#pragma once
#include "pack/texel_mask.hpp"

namespace atlas {

// Cells of a grid of `cells_wide` x `cells_high` cells that the mask covers
// when its texel (0, 0) sits at texel (x, y) >= 0; origin = the cell of (x, y).
// Cells outside the grid are dropped; all of them gives a 0 x 0 mask.
TexelMask coarsen_mask(const TexelMask& mask, int x, int y, int factor, int cells_wide,
                       int cells_high);

}  // namespace atlas
