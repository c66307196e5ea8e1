// Opens a chart with holes into a disk by cutting along shortest edge paths
// from one boundary loop to the next, until a single loop remains. Charts
// grown by filling islands can keep holes that no neighbour fills (mesh holes,
// or holes whose content could not merge); a few short cuts are far cheaper in
// seam length than splitting the chart back into its original charts.
#pragma once
#include <vector>

#include "core/mesh.hpp"

namespace atlas {

// triangles: local vertex indices of a chart in which every vertex has a single
// fan. vertex_source[v] is carried over to the copies a cut makes. A closed
// chart (an original chart covering a whole closed component) is first slit
// open along two edges. Returns true when the result is a disk (one boundary
// loop, chi == 1); false leaves a chart with handles or in several pieces,
// which the caller must split instead.
// triangles (F,3) and vertex_source (V) are changed in place.
// uncut (3F, or empty): 1 at a corner whose edge lies inside a polygon of the
// input (MeshTopology::inside_polygon). Cuts go around such edges; only when
// no such path joins the first loop to another is any edge taken.
// avoid (indexed by vertex_source, or empty; sources past its end are not
// avoided): vertices cuts go around first, as the border of a hole that
// fill_holes filled, which a cut through it would open again.
bool cut_to_disk(RowMatrixX3i& triangles, std::vector<int>& vertex_source, const std::vector<char>& uncut = {},
                 const std::vector<char>& avoid = {});

}  // namespace atlas
