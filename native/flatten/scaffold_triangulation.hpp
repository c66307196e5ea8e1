// Scaffold of a flattened chart (SCAF, Jiang et al. 2017): the free space
// between the chart's boundary and a box around it, triangulated. Solving the
// chart together with its scaffold under a flip-free line search keeps the
// boundary from crossing itself: a boundary that touched itself would squash
// a scaffold triangle to zero area first.
#pragma once
#include <vector>

#include "core/mesh.hpp"

namespace atlas {

struct Scaffold {
  // Local indices: 0..n-1 the chart's vertices, n..n+3 the box corners.
  RowMatrixX3i triangles;
  RowMatrixX2d box_corners;  // 4 x 2, counter-clockwise
};

// Triangulates the box minus the chart. uv holds the n chart vertices; loop is
// the chart's boundary, counter-clockwise around the chart (the direction of
// the face winding), and must not cross itself. The box extends the chart's
// bounding box by `margin` times its larger side on every side.
// Ear clipping after bridging the chart's rightmost boundary vertex to the
// box, then Lawson flips towards the constrained Delaunay triangulation, so
// the scaffold has no needless slivers. Returns false (scaffold unspecified)
// when no ear is left to clip. A crossing loop may fail that way or yield an
// overlapping scaffold, so callers pass loops that do not cross.
bool triangulate_scaffold(const RowMatrixX2d& uv, const std::vector<int>& loop, double margin, Scaffold& scaffold);

}  // namespace atlas
