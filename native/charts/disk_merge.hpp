// Clusters of faces that stay topological disks while they grow. Used by the
// aggregation (thesis 5.2.1: a collapse whose result is not a disk has infinite
// cost) and by the overlap backtracking, which regrows clusters the same way.
#pragma once
#include <vector>

#include "charts/mesh_holes.hpp"
#include "core/mesh.hpp"
#include "core/topology.hpp"

namespace atlas {

// Why two clusters may not merge: the shared border has a non-manifold edge or
// a winding flip, or the union would not be a disk.
//
// A union whose boundary wraps past a full turn of reference angle somewhere
// is allowed: SCAF (slim.cpp) keeps its flattening from crossing itself, and
// the density check splits it if that costs detail. Refusing it up front left
// markedly more charts on the shared scans (bench/README.md).
enum class MergeRefusal { None, NonManifold, NotDisk };

// A hole of the mesh that a cluster holds border edges of; counted once the
// cluster holds them all and encloses the hole, which then adds 1 to its chi.
struct HeldHole {
  int hole = 0, edges = 0;
  bool counted = false;
};

struct MergeCheck {
  MergeRefusal refusal = MergeRefusal::None;
  int euler = 0;  // of the union, when not refused
  // A partial merge (see DiskClusters): the shared edges that stay a seam
  // inside the union, and their 3D length. Empty for a full merge.
  std::vector<int> left_open;
  double open_length = 0;
  explicit operator bool() const { return refusal == MergeRefusal::None; }
};

class DiskClusters {
 public:
  // face_cluster[f] in [0, cluster_count) or -1 for faces that take no part.
  // self_seam (per edge, see self_seams) marks edges where an original chart
  // meets itself at a UV seam: they stay boundary on both sides for good.
  // partial_merges: when welding the whole shared border would not leave a
  // disk, check_merge offers to weld only its longest arc (a maximal run of
  // shared edges joined at vertices) and keep the other arcs as seams inside
  // the union, as the thesis allows in 5.2 ("unless cuts are introduced").
  // false: such pairs are refused.
  // holes (mesh_holes, or empty): a hole of the mesh that a cluster holds
  // whole and encloses counts as filled in its chi, as no merge could fill
  // it; the flattening fills it (flatten/fill_holes.hpp). Empty: such holes
  // count as holes.
  DiskClusters(const Mesh& mesh, const MeshTopology& topology, std::vector<int> face_cluster,
               int cluster_count, std::vector<char> self_seam, bool partial_merges = false,
               MeshHoles holes = {});

  // Euler characteristic chi = V - E + F of the union of a and b, counting a
  // vertex once per fan of faces around it (pinches are split), when the shared
  // edges are manifold and consistently wound and the union is a disk
  // (chi == 1) or has fewer holes than the worse of the two (an island filling
  // a hole), or as many when one of them is a disk (joined along one arc, it
  // adds no hole); the refusal otherwise. Clusters that did not start manifold never merge.
  MergeCheck check_merge(int a, int b);
  // Merges the smaller cluster into the larger; returns the survivor. The
  // check's left_open edges become seams the union keeps.
  int merge(int a, int b, const MergeCheck& check);

  // True when face f may leave its cluster for cluster `to` with both keeping
  // their topology: f joins `to` across an edge, has exactly one neighbour
  // left in its own cluster (so that cluster stays connected), touches no
  // seam, and chi of both is unchanged (counted at f's vertices and edges).
  // For clusters built without holes only (a move would change their count).
  bool move_keeps_topology(int f, int to);
  void move(int f, int to);

  // The cluster that holds vertex v inside it: every face at v is in it and
  // every edge at v joins two of its faces (no mesh border, no kept seam);
  // -1 when there is none.
  int cluster_inside(int v) const;
  // Sum of per_vertex (V) over the vertices that the union of a and b would
  // hold inside it (as cluster_inside) and neither holds alone. The shared
  // edges count as welded, those a partial merge would leave open included.
  double sum_inside_union(int a, int b, const std::vector<double>& per_vertex);

  // Connected, manifold, orientable and chi == 1: a topological disk once
  // pinch vertices are split (and the counted holes it holds filled).
  bool is_disk(int c) const { return manifold_[c] && euler_[c] == 1; }
  const std::vector<int>& faces(int c) const { return faces_[c]; }
  int cluster_of(int f) const { return face_cluster_[f]; }
  // Per edge: the self seams given, plus the arcs partial merges left open.
  const std::vector<char>& seams() const { return seam_; }

 private:
  // Outcome of welding every shared edge of a and b that is not a seam;
  // shared (if given) receives those edges.
  MergeCheck weld_all(int a, int b, std::vector<int>* shared);
  MergeCheck weld_longest_arc(int a, int b, const std::vector<int>& shared);
  int euler_of(int c);
  // Holes of the mesh that c holds edges of, by hole, none counted yet.
  std::vector<HeldHole> holes_held(int c) const;
  // Marks counted, in held (the holes of a and b together), every hole not
  // counted yet whose edges they hold all of and which they enclose; returns
  // how many.
  int count_enclosed(std::vector<HeldHole>& held, int a, int b) const;
  // The holes the union of a and b would count that neither counts alone.
  int holes_closed(int a, int b) const;
  // Whether the faces of a and b hold one fan at every vertex of the hole's
  // border: it is then a loop of its own. Where the border meets a seam or
  // touches the clusters' other border at a vertex, the vertex is split and
  // the hole is part of that border; filling it would make no disk.
  bool encloses(int hole, int a, int b) const;
  int local_euler(int f, int c) const;
  bool manifold_inside(int c);
  int fan_count(int v, int a, int b) const;
  // Every face at v is in a or b, every edge at v joins two faces.
  bool inside(int v, int a, int b) const;
  bool in(int f, int a, int b) const { return face_cluster_[f] == a || face_cluster_[f] == b; }
  // Faces of a cluster are joined across e: manifold and not a seam the cluster keeps.
  bool joins(int e) const { return topology_.edge_valence(e) == 2 && !seam_[e]; }

  const Mesh& mesh_;
  const MeshTopology& topology_;
  std::vector<int> face_cluster_;
  std::vector<std::vector<int>> faces_;
  std::vector<int> euler_;
  std::vector<char> manifold_;
  std::vector<char> seam_;  // per edge: the self seams given, plus the arcs partial merges left open
  bool partial_merges_;
  MeshHoles holes_;
  std::vector<std::vector<HeldHole>> held_;  // per cluster: holes_held, counted once enclosed
  std::vector<std::vector<int>> hole_vertices_;  // per hole: the vertices of its border, ascending
  // Visit stamps, so each check touches only the smaller cluster's faces.
  std::vector<unsigned> edge_stamp_, vertex_stamp_;
  unsigned stamp_ = 0;
  // fan_count's work space (the faces at a vertex and their union-find
  // parents), kept so that the many counts allocate nothing.
  mutable std::vector<int> fan_faces_, fan_parent_;
};

}  // namespace atlas
