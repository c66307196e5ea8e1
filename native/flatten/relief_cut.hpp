// A slit that relieves a flattening's compression. A chart that bends too far
// from flat (a cap, a bulge) flattens with its middle squeezed: faces there
// keep less than half their texel area. A cut from the chart's boundary to
// the most squeezed vertex lets the solve open the chart there, as a peeled
// orange opens, at the cost of the cut's length in seam, where splitting the
// chart back into two would add a whole border between them.
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "core/topology.hpp"

namespace atlas {

// faces (F) mesh faces of a flattened chart; triangles (F,3) their local
// vertices, corner k of row i being corner k of mesh face faces[i]; uv
// (V,2) the flattening in texels. Returns the mesh edges of shortest 3D edge paths to
// the chart's boundary, one from each group of faces that kept less than half
// their texel area, starting at the group's interior vertex of lowest
//   score(v) = sum_f A3D(f) log(A_uv(f) / A_ref(f)) / sum_f A3D(f) over faces f at v;
// nothing when no such group has an interior vertex. No path runs inside an
// input polygon (MeshTopology::inside_polygon).
std::vector<int> relief_cut(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& faces,
                            const RowMatrixX3i& triangles, const RowMatrixX2d& uv);

}  // namespace atlas
