// Minimum s-t cut of an undirected graph (Dinic's maximum flow).
#pragma once
#include <vector>

namespace atlas {

struct CutEdge {
  int a, b;         // nodes
  double capacity;  // >= 0, the same both ways
};

// Nodes 0..node_count-1; source != sink. Per node, 1 when it lies on the
// source's side of a minimum cut (reachable from the source in the residual
// graph of a maximum flow), else 0. Capacities below 1e-12 of the largest
// count as none, so round-off cannot keep a path open.
std::vector<char> min_cut_source_side(int node_count, const std::vector<CutEdge>& edges, int source, int sink);

}  // namespace atlas
