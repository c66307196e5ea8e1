// Edge and vertex incidence of a welded triangle mesh, in flat CSR arrays.
// Corner c = 3*f + k is corner k of face f; it starts the face's edge
// from triangles(f,k) to triangles(f,(k+1)%3).
#pragma once
#include <vector>

#include "core/mesh.hpp"

namespace atlas {

using RowMatrixX2i = Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor>;

struct MeshTopology {
  RowMatrixX2i edge_vertices;        // E x 2, smaller index first
  std::vector<int> corner_edge;      // 3F: edge started by each corner
  std::vector<int> edge_offsets;     // E+1: CSR into edge_corners
  std::vector<int> edge_corners;     // corners whose edge is e (1: border, 2: manifold, >2: non-manifold)
  std::vector<int> vertex_offsets;   // V+1: CSR into vertex_corners
  std::vector<int> vertex_corners;   // corners sitting at vertex v
  // E, or empty when build_topology had no face_polygon: 1 where both faces
  // of the edge triangulate one polygon of the input (a quad's diagonal).
  // Each corner of a polygon holds one UV where the mesh came from, so no
  // cut may run along such an edge.
  std::vector<char> inside_polygon;

  int edge_count() const { return static_cast<int>(edge_vertices.rows()); }
  int edge_valence(int e) const { return edge_offsets[e + 1] - edge_offsets[e]; }
  bool may_cut(int e) const { return inside_polygon.empty() || !inside_polygon[e]; }
};

// triangles (F,3) indices into vertex_count vertices: every undirected edge
// once, with the corners on it and each corner's edge.
// face_polygon (F): the polygon each face triangulates (any ints), which
// sets inside_polygon; empty: every face is a polygon of its own.
MeshTopology build_topology(const RowMatrixX3i& triangles, int vertex_count,
                            const std::vector<int>& face_polygon = {});

// The other face at edge e from face f; e has two faces (edge_valence 2).
inline int face_across(const MeshTopology& topology, int e, int f) {
  const int g0 = topology.edge_corners[topology.edge_offsets[e]] / 3;
  return g0 == f ? topology.edge_corners[topology.edge_offsets[e] + 1] / 3 : g0;
}

// 3D length of edge e.
inline double edge_length(const Mesh& mesh, const MeshTopology& topology, int e) {
  return (mesh.positions.row(topology.edge_vertices(e, 0)) - mesh.positions.row(topology.edge_vertices(e, 1))).norm();
}

// For a manifold edge e (valence 2): true when both faces put the edge's two
// end vertices at the same UVs on the same page, i.e. the edge is not a seam.
bool uv_continuous_across(const MeshTopology& topology, const RowMatrixX3i& triangles,
                          const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page, int e);

// Per edge: true for a manifold edge whose two faces lie in the same chart
// (face_chart) yet disagree in UV along it, so the chart meets itself at a
// seam, as a cylinder unrolled into one strip does. The chart's own UVs make
// such an edge boundary on both sides: its topology and its flattening must too.
std::vector<char> self_seams(const MeshTopology& topology, const RowMatrixX3i& triangles,
                             const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page,
                             const std::vector<int>& face_chart);

}  // namespace atlas
