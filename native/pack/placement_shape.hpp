// A dilated chart mask prepared for placement: its runs of set texels per
// row (for the hole search) and its lower outline per column (for dropping it
// onto the page horizon).
#pragma once
#include <vector>

#include "pack/texel_mask.hpp"

namespace atlas {

struct Span {
  int begin, end;  // texels [begin, end) of one row
};

struct PlacementShape {
  TexelMask mask;
  long long texels = 0;           // set texels
  int centroid_row = 0;           // row of the set texels' centroid, rounded down
  std::vector<Span> runs;         // runs of set texels, row by row, left to right
  std::vector<int> row_start;     // runs of row r: runs[row_start[r], row_start[r + 1])
  std::vector<int> longest_run;   // per row
  int widest_row = 0;             // row holding the longest run
  std::vector<int> row_order;     // rows in the order the hole search tests them
  // A large rectangle of set texels: columns core_columns, rows
  // [core_bottom, core_bottom + core_height). Wherever the shape fits, a free
  // rectangle this size does too, which bounds the hole search from below.
  Span core_columns = {0, 1};
  int core_bottom = 0, core_height = 1;
  std::vector<int> column_bottom;  // per column: lowest set row, mask.height if none
  std::vector<int> column_order;   // set columns, lowest column_bottom first
  std::vector<int> key_columns;    // a few set columns spread over the width, for bounds
};

// Requires a mask with at least one set texel.
PlacementShape make_placement_shape(TexelMask mask);

}  // namespace atlas
