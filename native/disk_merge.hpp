// Clusters of faces that stay topological disks while they grow. Used by the
// aggregation (thesis 5.2.1: a collapse whose result is not a disk has infinite
// cost) and by the overlap backtracking, which regrows clusters the same way.
#pragma once
#include <optional>
#include <vector>

#include "mesh.hpp"
#include "topology.hpp"

namespace atlas {

class DiskClusters {
 public:
  // face_cluster[f] in [0, cluster_count) or -1 for faces that take no part.
  // corner_angle (3F, may be empty) holds each corner's angle in its reference
  // triangle: when given, a merge that leaves a boundary vertex with more than
  // a full turn of reference angle is refused, because any flattening close to
  // the references must fold over there.
  DiskClusters(const Mesh& mesh, const MeshTopology& topology, std::vector<int> face_cluster,
               int cluster_count, std::vector<double> corner_angle = {});

  // Euler characteristic chi = V - E + F of the union of a and b, counting a
  // vertex once per fan of faces around it (pinches are split), when the shared
  // edges are manifold and consistently wound and the union is a disk
  // (chi == 1) or has fewer holes than the worse of the two (an island filling
  // a hole); nothing otherwise. Clusters that did not start manifold never merge.
  std::optional<int> merged_euler(int a, int b);
  // Merges the smaller cluster into the larger; returns the survivor.
  int merge(int a, int b, int merged_euler);

  // Connected, manifold, orientable and chi == 1: a topological disk once
  // pinch vertices are split.
  bool is_disk(int c) const { return manifold_[c] && euler_[c] == 1; }
  const std::vector<int>& faces(int c) const { return faces_[c]; }
  int cluster_of(int f) const { return face_cluster_[f]; }

 private:
  int euler_of(int c);
  bool manifold_inside(int c);
  int fan_count(int v, int a, int b) const;
  bool wraps_too_far(int v, int a, int b) const;
  bool in(int f, int a, int b) const { return face_cluster_[f] == a || face_cluster_[f] == b; }

  const Mesh& mesh_;
  const MeshTopology& topology_;
  std::vector<int> face_cluster_;
  std::vector<std::vector<int>> faces_;
  std::vector<int> euler_;
  std::vector<char> manifold_;
  std::vector<double> corner_angle_;
  // Visit stamps, so each check touches only the smaller cluster's faces.
  std::vector<unsigned> edge_stamp_, vertex_stamp_;
  unsigned stamp_ = 0;
};

}  // namespace atlas
