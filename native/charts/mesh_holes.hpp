// Holes of a mesh: the loops of border edges (edges with one face) that are
// not the outer border of their piece. Scans have many (phone LiDAR and
// photogrammetry leave gaps where nothing was seen). A chart round a hole is
// not a disk, yet flattens as one with the hole filled (flatten/fill_holes.hpp),
// so the aggregation counts a hole inside a chart as filled (charts/disk_merge.hpp).
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "core/topology.hpp"

namespace atlas {

struct MeshHoles {
  std::vector<int> edge_hole;  // E: the hole of each border edge, -1 for every other edge
  std::vector<int> edges;      // H: how many edges each hole has
};

// The border edges joined at shared vertices form loops (loops touching at a
// vertex count as one); in each connected piece of the mesh the loop of
// greatest 3D length is its outer border, and every other loop is a hole,
// unless it is a crack (see kMinHoleRoundness in mesh_holes.cpp).
// may_be_hole (E, or empty: every edge may): a loop with an edge not marked is
// no hole.
MeshHoles mesh_holes(const Mesh& mesh, const MeshTopology& topology, const std::vector<char>& may_be_hole = {});

// Per edge of `to`, a topology of the same faces (the cut surface of the
// mesh, charts/cut_mesh.hpp): whether the edge lies on a hole of `from`.
// On the cut surface a hole's border can run into a slit the cut opened;
// mesh_holes with this mask then keeps only the loops that are holes in both.
std::vector<char> on_holes(const MeshHoles& holes, const MeshTopology& from, const MeshTopology& to);

}  // namespace atlas
