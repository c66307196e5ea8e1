#include "charts/mesh_holes.hpp"

#include <Eigen/Geometry>
#include <algorithm>

#include "core/geometry.hpp"
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

// The border loops: per edge its loop (-1 off the border), per loop its
// piece, edge count, 3D length, the sum of its edges' end points and whether
// every edge of it may be a hole's.
struct BorderLoops {
  std::vector<int> edge_loop, piece, edges;
  std::vector<double> length;
  std::vector<Eigen::RowVector3d> ends;
  std::vector<char> may_be_hole;
};

// A loop enclosing less than this share of the area of a circle of its
// length is a crack (vertices a weld missed, a slit): filled from its middle,
// its faces would have no area, and their references, repaired to the
// chart's mean face, would force the crack open.
constexpr double kMinHoleRoundness = 0.05;

// The 3D area of the fan joining each loop's edges to the mean of their ends.
std::vector<double> fan_areas(const Mesh& mesh, const MeshTopology& topology, const BorderLoops& loops) {
  std::vector<double> area(loops.length.size(), 0.0);
  for (size_t e = 0; e < loops.edge_loop.size(); ++e) {
    const int l = loops.edge_loop[e];
    if (l < 0) continue;
    const Eigen::RowVector3d centre = loops.ends[l] / (2.0 * loops.edges[l]);
    const Eigen::RowVector3d a = mesh.positions.row(topology.edge_vertices(static_cast<int>(e), 0)) - centre;
    const Eigen::RowVector3d b = mesh.positions.row(topology.edge_vertices(static_cast<int>(e), 1)) - centre;
    area[l] += 0.5 * a.cross(b).norm();
  }
  return area;
}

BorderLoops border_loops(const Mesh& mesh, const MeshTopology& topology, const std::vector<char>& may_be_hole) {
  const int edge_count = topology.edge_count();
  UnionFind joined(edge_count + mesh.vertex_count());  // border edges joined through vertex v, node E + v
  for (int e = 0; e < edge_count; ++e)
    if (topology.edge_valence(e) == 1)
      for (int end = 0; end < 2; ++end) joined.unite(e, edge_count + topology.edge_vertices(e, end));
  const std::vector<int> face_piece = face_pieces(topology, mesh.face_count());
  std::vector<int> loop_of_root(edge_count + mesh.vertex_count(), -1);
  BorderLoops loops;
  loops.edge_loop.assign(edge_count, -1);
  for (int e = 0; e < edge_count; ++e) {
    if (topology.edge_valence(e) != 1) continue;
    int& loop = loop_of_root[joined.find(e)];
    if (loop < 0) {
      loop = static_cast<int>(loops.length.size());
      loops.length.push_back(0);
      loops.edges.push_back(0);
      loops.ends.push_back(Eigen::RowVector3d::Zero());
      loops.piece.push_back(face_piece[topology.edge_corners[topology.edge_offsets[e]] / 3]);
      loops.may_be_hole.push_back(1);
    }
    if (!may_be_hole.empty() && !may_be_hole[e]) loops.may_be_hole[loop] = 0;
    loops.edge_loop[e] = loop;
    ++loops.edges[loop];
    loops.length[loop] += edge_length(mesh, topology, e);
    for (int end = 0; end < 2; ++end) loops.ends[loop] += mesh.positions.row(topology.edge_vertices(e, end));
  }
  return loops;
}

}  // namespace

MeshHoles mesh_holes(const Mesh& mesh, const MeshTopology& topology, const std::vector<char>& may_be_hole) {
  const BorderLoops loops = border_loops(mesh, topology, may_be_hole);
  const int loop_count = static_cast<int>(loops.length.size());
  std::vector<int> outline(loops.piece.empty() ? 0 : *std::max_element(loops.piece.begin(), loops.piece.end()) + 1,
                           -1);  // per piece, its longest loop
  for (int l = 0; l < loop_count; ++l)
    if (int& o = outline[loops.piece[l]]; o < 0 || loops.length[l] > loops.length[o]) o = l;
  const std::vector<double> area = fan_areas(mesh, topology, loops);
  MeshHoles holes;
  std::vector<int> hole_of(loop_count, -1);
  for (int l = 0; l < loop_count; ++l)
    if (outline[loops.piece[l]] != l && loops.may_be_hole[l] &&
        area[l] >= kMinHoleRoundness * loops.length[l] * loops.length[l] / (4 * kPi)) {
      hole_of[l] = static_cast<int>(holes.edges.size());
      holes.edges.push_back(loops.edges[l]);
    }
  holes.edge_hole.assign(loops.edge_loop.size(), -1);
  for (size_t e = 0; e < loops.edge_loop.size(); ++e)
    if (const int l = loops.edge_loop[e]; l >= 0) holes.edge_hole[e] = hole_of[l];
  return holes;
}

std::vector<char> on_holes(const MeshHoles& holes, const MeshTopology& from, const MeshTopology& to) {
  std::vector<char> out(to.edge_count(), 0);
  for (size_t c = 0; c < to.corner_edge.size(); ++c)
    if (holes.edge_hole[from.corner_edge[c]] >= 0) out[to.corner_edge[c]] = 1;
  return out;
}

}  // namespace atlas
