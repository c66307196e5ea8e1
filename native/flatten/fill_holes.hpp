// Holes of the mesh inside a chart, closed for its flattening. Each hole
// whose whole border the chart holds (MeshHoles, charts/mesh_holes.hpp) gets
// a vertex at the mean of its border vertices, joined to every border edge
// by a face. The chart is then a disk there without a cut, and the filled
// faces keep the hole open in the new UVs much as it is in 3D; they are
// dropped after the solve. A cut (cut_to_disk) would add seam instead.
#pragma once
#include <vector>

#include "charts/mesh_holes.hpp"
#include "core/mesh.hpp"
#include "core/topology.hpp"

namespace atlas {

// faces (F): the mesh face of each row of triangles (F x 3, local vertices);
// vertex_source (V): the mesh vertex of each local vertex. Appends one face
// per border edge of each whole hole to triangles, wound like the chart, and
// one vertex per hole to vertex_source, numbered mesh.vertex_count() + its
// row in the returned centres (H' x 3, their 3D positions).
RowMatrixX3d fill_holes(const Mesh& mesh, const MeshTopology& topology, const MeshHoles& holes,
                        const std::vector<int>& faces, RowMatrixX3i& triangles, std::vector<int>& vertex_source);

}  // namespace atlas
