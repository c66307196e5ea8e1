// Turning a chart so that its bounding box is the smallest over all angles:
// scan charts come out of the flattening at arbitrary angles, and a chart
// whose box fits it closely leaves less room unused beside it when packed.
#pragma once
#include "core/mesh.hpp"

namespace atlas {

// uv: N x 2 points (any N; the corners of a chart). Returns them turned about
// the origin by the angle that minimises the area of their axis-aligned
// bounding box. That box has a side along an edge of the convex hull (Freeman
// and Shapira 1975), so only the hull's edge directions are tried. Fewer than
// three distinct points, or non-finite ones, come back unchanged.
RowMatrixX2d turned_to_smallest_box(const RowMatrixX2d& uv);

}  // namespace atlas
