// Degenerate stacks and fans: faces that repeat another face, and edges shared
// by many faces. Both must cost linear time and memory.
//
// Why: k faces on one edge make k(k-1)/2 pairs of faces there, and the chart
// graph pays for every pair: 1M copies of one triangle, or a mesh whose
// vertices all weld onto one point, would need memory quadratic in k.
//  * A copy coincides with the face it repeats on the surface: it is set
//    aside before the stages and takes that face's new UVs (and so its texels),
//    so the stages see each repeated face once.
//  * A fan edge (more than kFanValence faces, all distinct) is a boundary of
//    every chart on it and joins none of them: no merge could cross it anyway
//    (the charts stage cuts the surface open along every non-manifold edge).
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "core/topology.hpp"

namespace atlas {

struct DuplicateFaces {
  std::vector<int> kept;    // faces that go through the stages, ascending
  // Per input face f: the kept face it repeats (f itself when kept), and the
  // corner of that face sitting at corner 0 of f (its vertices in the same
  // cyclic order, so corner k of f is corner (shift + k) % 3 of the original).
  std::vector<int> original;
  std::vector<int> shift;
  int copies() const { return static_cast<int>(original.size() - kept.size()); }
};

// Two faces repeat each other when they name the same welded vertices in the
// same cyclic order (a face wound the other way is a back face, not a copy),
// lie in the same face_group (may be empty: one group) and are both textured
// or both untextured. The first in index order is kept. O(F) expected.
DuplicateFaces find_duplicate_faces(const Mesh& mesh, const std::vector<int>& face_group);

// The faces that draw a triangle no earlier face draws: the same page and
// bit-identical corner UVs (3F x 2 rows), in the same cyclic order from any
// corner, make a repeat. Ascending. The copies
// the pipeline gave the UVs of the face they repeat cover its texels again:
// baking them once is enough. O(F) expected.
std::vector<int> first_of_equal_faces(const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page);

// The corner UVs (3 rows per face) and pages of `faces`, in that order, into
// uv (3n x 2) and page (n).
void take_face_uvs(const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page, const std::vector<int>& faces,
                   RowMatrixX2d& uv, Eigen::VectorXi& page);

// mesh restricted to faces (all vertices kept).
Mesh mesh_of_faces(const Mesh& mesh, const std::vector<int>& faces);

// Edges on more faces than this make no chart adjacency: the pairs of charts
// on one edge grow as its valence squared.
constexpr int kFanValence = 16;

inline bool is_fan_edge(const MeshTopology& topology, int e) { return topology.edge_valence(e) > kFanValence; }

}  // namespace atlas
