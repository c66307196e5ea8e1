// Faces moving between flattened charts. A FlatChart holds three rows of
// corner_uv per entry of faces, in the same order; slot[f] is the index of
// face f in the faces of its chart.
#pragma once
#include <vector>

#include "flatten/flatten_without_overlap.hpp"

namespace atlas {

// Takes face f out of `chart`: the chart's last face takes its place (rows
// and slot). Returns the index f had, which now holds that last face unless
// f was the last.
int take_out_face(FlatChart& chart, int f, std::vector<int>& slot);

// Appends faces (F) to `chart` with their corner UVs uv (3F x 2, three rows
// per face in order) in one resize, and sets their slots.
void append_faces(FlatChart& chart, const std::vector<int>& faces, const RowMatrixX2d& uv, std::vector<int>& slot);

}  // namespace atlas
