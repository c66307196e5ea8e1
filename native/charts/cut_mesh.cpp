#include "charts/cut_mesh.hpp"

#include "core/corners.hpp"

namespace atlas {
namespace {

bool keeps_edge(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph, int e) {
  if (topology.edge_valence(e) != 2) return false;
  const int c0 = topology.edge_corners[topology.edge_offsets[e]];
  const int c1 = topology.edge_corners[topology.edge_offsets[e] + 1];
  if (corner_vertex(mesh.triangles, c0) == corner_vertex(mesh.triangles, c1)) return false;  // winding flip
  if (mesh.repeats_vertex(c0 / 3) || mesh.repeats_vertex(c1 / 3)) return false;
  const int chart = graph.face_chart[c0 / 3];
  const bool same_chart = chart >= 0 && chart == graph.face_chart[c1 / 3];
  return !same_chart || uv_continuous_across(topology, mesh.triangles, mesh.corner_uv, mesh.face_page, e);
}

}  // namespace

Mesh cut_internal_seams(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph) {
  // Corners at the same vertex are joined across every edge that stays; each
  // resulting class of corners becomes one vertex of the cut surface.
  UnionFind corners(3 * mesh.face_count());
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (!keeps_edge(mesh, topology, graph, e)) continue;
    const int f0 = topology.edge_corners[topology.edge_offsets[e]] / 3;
    const int f1 = topology.edge_corners[topology.edge_offsets[e] + 1] / 3;
    for (int j = 0; j < 2; ++j) {
      const int v = topology.edge_vertices(e, j);
      corners.unite(3 * f0 + mesh.corner_of(f0, v), 3 * f1 + mesh.corner_of(f1, v));
    }
  }
  Mesh cut;
  std::vector<int> source_vertex;
  vertices_from_corner_classes(
      corners, mesh.face_count(), [&](int c) { return corner_vertex(mesh.triangles, c); }, cut.triangles,
      source_vertex);
  cut.positions.resize(static_cast<Eigen::Index>(source_vertex.size()), 3);
  for (size_t v = 0; v < source_vertex.size(); ++v) cut.positions.row(v) = mesh.positions.row(source_vertex[v]);
  cut.corner_uv = mesh.corner_uv;
  cut.face_page = mesh.face_page;
  cut.pages = mesh.pages;
  return cut;
}

}  // namespace atlas
