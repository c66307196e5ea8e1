#include "pack/coarse_mask.hpp"

#include <algorithm>

namespace atlas {

TexelMask coarsen_mask(const TexelMask& mask, int x, int y, int factor, int cells_wide,
                       int cells_high) {
  const int cx = x / factor, cy = y / factor;
  const int width = std::min(cells_wide, (x + mask.width - 1) / factor + 1) - cx;
  const int height = std::min(cells_high, (y + mask.height - 1) / factor + 1) - cy;
  if (width <= 0 || height <= 0) return TexelMask();
  TexelMask cells(width, height, cx, cy);
  for (int r = 0; r < mask.height && (y + r) / factor - cy < height; ++r) {
    const std::uint64_t* row = mask.row(r);
    std::uint64_t* cell_row = cells.row((y + r) / factor - cy);
    for (int b = find_bit(row, 0, mask.width, true); b < mask.width;) {
      const int e = find_bit(row, b, mask.width, false);
      // Texels [x + b, x + e) lie in cells [(x + b) / f, (x + e - 1) / f].
      set_bits(cell_row, (x + b) / factor - cx, std::min(width, (x + e - 1) / factor - cx + 1));
      b = find_bit(row, e, mask.width, true);
    }
  }
  return cells;
}

}  // namespace atlas
