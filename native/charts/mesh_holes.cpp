#include "charts/mesh_holes.hpp"

#include <algorithm>

#include "core/union_find.hpp"

namespace atlas {
namespace {

// Piece of each face: faces joined across any edge.
std::vector<int> face_pieces(const MeshTopology& topology, int face_count) {
  UnionFind pieces(face_count);
  for (int e = 0; e < topology.edge_count(); ++e)
    for (int i = topology.edge_offsets[e] + 1; i < topology.edge_offsets[e + 1]; ++i)
      pieces.unite(topology.edge_corners[i] / 3, topology.edge_corners[topology.edge_offsets[e]] / 3);
  return pieces.dense_labels();
}

}  // namespace

MeshHoles mesh_holes(const Mesh& mesh, const MeshTopology& topology, const std::vector<char>& may_be_hole) {
  const int edge_count = topology.edge_count();
  // Loops: border edges joined through their vertices (vertex v is node E + v).
  UnionFind loops(edge_count + mesh.vertex_count());
  for (int e = 0; e < edge_count; ++e)
    if (topology.edge_valence(e) == 1)
      for (int end = 0; end < 2; ++end) loops.unite(e, edge_count + topology.edge_vertices(e, end));
  const std::vector<int> piece = face_pieces(topology, mesh.face_count());
  std::vector<int> loop_of(edge_count + mesh.vertex_count(), -1), loop_piece;
  std::vector<double> loop_length;
  std::vector<char> loop_may_be_hole;
  MeshHoles holes;
  holes.edge_hole.assign(edge_count, -1);
  for (int e = 0; e < edge_count; ++e) {
    if (topology.edge_valence(e) != 1) continue;
    int& loop = loop_of[loops.find(e)];
    if (loop < 0) {
      loop = static_cast<int>(loop_length.size());
      loop_length.push_back(0);
      loop_piece.push_back(piece[topology.edge_corners[topology.edge_offsets[e]] / 3]);
      loop_may_be_hole.push_back(1);
    }
    if (!may_be_hole.empty() && !may_be_hole[e]) loop_may_be_hole[loop] = 0;
    holes.edge_hole[e] = loop;
    loop_length[loop] += edge_length(mesh, topology, e);
  }
  // The longest loop of each piece is its outer border; the others are
  // holes, numbered in the order of their loops.
  std::vector<int> outer(piece.empty() ? 0 : *std::max_element(piece.begin(), piece.end()) + 1, -1);
  for (int l = 0; l < static_cast<int>(loop_length.size()); ++l)
    if (int& o = outer[loop_piece[l]]; o < 0 || loop_length[l] > loop_length[o]) o = l;
  std::vector<int> hole_of(loop_length.size(), -1);
  for (int l = 0; l < static_cast<int>(loop_length.size()); ++l)
    if (outer[loop_piece[l]] != l && loop_may_be_hole[l]) hole_of[l] = static_cast<int>(holes.edges.size()), holes.edges.push_back(0);
  for (int& h : holes.edge_hole)
    if (h >= 0 && (h = hole_of[h]) >= 0) ++holes.edges[h];
  return holes;
}

std::vector<char> on_holes(const MeshHoles& holes, const MeshTopology& from, const MeshTopology& to) {
  std::vector<char> out(to.edge_count(), 0);
  for (size_t c = 0; c < to.corner_edge.size(); ++c)
    if (holes.edge_hole[from.corner_edge[c]] >= 0) out[to.corner_edge[c]] = 1;
  return out;
}

}  // namespace atlas
