#include "core/min_cut.hpp"

#include <algorithm>
#include <queue>

namespace atlas {
namespace {

// Residual arcs: an undirected edge is two arcs, each the other's reverse,
// both starting with the edge's capacity.
struct Arc {
  int to, reverse;
  double residual;
};

class FlowGraph {
 public:
  FlowGraph(int node_count, const std::vector<CutEdge>& edges) : arcs_(node_count) {
    double largest = 0;
    for (const CutEdge& e : edges) largest = std::max(largest, e.capacity);
    epsilon_ = 1e-12 * largest;
    for (const CutEdge& e : edges) {
      if (!(e.capacity > epsilon_) || e.a == e.b) continue;
      arcs_[e.a].push_back({e.b, static_cast<int>(arcs_[e.b].size()), e.capacity});
      arcs_[e.b].push_back({e.a, static_cast<int>(arcs_[e.a].size()) - 1, e.capacity});
    }
  }

  void max_flow(int source, int sink) {
    for (levels_from(source); level_[sink] >= 0; levels_from(source)) {
      next_.assign(arcs_.size(), 0);
      while (push(source, sink, kUnbounded) > epsilon_) {
      }
    }
  }

  // After max_flow: nodes the source still reaches.
  std::vector<char> source_side(int source) {
    levels_from(source);
    std::vector<char> side(arcs_.size());
    for (size_t v = 0; v < arcs_.size(); ++v) side[v] = level_[v] >= 0;
    return side;
  }

 private:
  static constexpr double kUnbounded = 1e300;

  // Breadth-first levels over arcs with residual capacity (-1: not reached).
  void levels_from(int source) {
    level_.assign(arcs_.size(), -1);
    std::queue<int> queue;
    level_[source] = 0;
    for (queue.push(source); !queue.empty(); queue.pop())
      for (const Arc& a : arcs_[queue.front()])
        if (a.residual > epsilon_ && level_[a.to] < 0) {
          level_[a.to] = level_[queue.front()] + 1;
          queue.push(a.to);
        }
  }

  // One augmenting path of the level graph from v, at most `limit`; the flow pushed.
  double push(int v, int sink, double limit) {
    if (v == sink) return limit;
    for (int& i = next_[v]; i < static_cast<int>(arcs_[v].size()); ++i) {
      Arc& a = arcs_[v][i];
      if (!(a.residual > epsilon_) || level_[a.to] != level_[v] + 1) continue;
      const double pushed = push(a.to, sink, std::min(limit, a.residual));
      if (pushed > epsilon_) {
        a.residual -= pushed;
        arcs_[a.to][a.reverse].residual += pushed;
        return pushed;
      }
    }
    return 0;
  }

  std::vector<std::vector<Arc>> arcs_;
  std::vector<int> level_, next_;
  double epsilon_ = 0;
};

}  // namespace

std::vector<char> min_cut_source_side(int node_count, const std::vector<CutEdge>& edges, int source, int sink) {
  FlowGraph graph(node_count, edges);
  graph.max_flow(source, sink);
  return graph.source_side(source);
}

}  // namespace atlas
