#include "flatten/cut_to_disk.hpp"

#include <algorithm>
#include <cstdint>
#include <queue>

#include "core/corners.hpp"

namespace atlas {
namespace {

// Corners of t sorted by their undirected edge (see corners_by_edge).
std::vector<std::pair<std::int64_t, int>> keyed_corners(const RowMatrixX3i& t) {
  return corners_by_edge(static_cast<int>(3 * t.rows()), [&](int c) { return corner_vertex(t, c); });
}

// Boundary loop id of every vertex (-1 inside); returns the number of loops.
int label_boundary_loops(const RowMatrixX3i& t, int vertex_count, std::vector<int>& loop_of) {
  std::vector<char> on_boundary(3 * t.rows(), 0);
  const auto keyed = keyed_corners(t);
  for_each_edge_run(keyed, [&](int first, int count) {
    for (int i = first; i < first + count; ++i) on_boundary[keyed[i].second] = count == 1;
  });
  std::vector<int> next(vertex_count, -1);
  for (int c = 0; c < static_cast<int>(on_boundary.size()); ++c)
    if (on_boundary[c]) next[corner_vertex(t, c)] = corner_vertex(t, next_corner(c));
  loop_of.assign(vertex_count, -1);
  int loops = 0;
  for (int v = 0; v < vertex_count; ++v) {
    if (next[v] < 0 || loop_of[v] >= 0) continue;
    for (int w = v; w >= 0 && loop_of[w] < 0; w = next[w]) loop_of[w] = loops;
    ++loops;
  }
  return loops;
}

// Shortest path (in edges) from loop 0 to any other loop through interior
// vertices, along no edge whose corner is set in `uncut` (empty: any edge)
// and through no vertex that `avoided` names.
template <class Avoided>
std::vector<int> path_between_loops(const RowMatrixX3i& t, const std::vector<int>& loop_of,
                                    const std::vector<char>& uncut, Avoided avoided) {
  const int n = static_cast<int>(loop_of.size());
  std::vector<std::vector<int>> adjacent(n);
  for (Eigen::Index f = 0; f < t.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      if (!uncut.empty() && uncut[3 * f + k]) continue;
      adjacent[t(f, k)].push_back(t(f, (k + 1) % 3)), adjacent[t(f, (k + 1) % 3)].push_back(t(f, k));
    }
  std::vector<int> from(n, -2);
  std::queue<int> bfs;
  for (int v = 0; v < n; ++v)
    if (loop_of[v] == 0) from[v] = -1, bfs.push(v);
  while (!bfs.empty()) {
    const int v = bfs.front();
    bfs.pop();
    for (int w : adjacent[v]) {
      if (from[w] != -2 || avoided(w)) continue;
      from[w] = v;
      if (loop_of[w] > 0) {
        std::vector<int> path;
        for (int x = w; x >= 0; x = from[x]) path.push_back(x);
        return path;
      }
      if (loop_of[w] < 0) bfs.push(w);
    }
  }
  return {};
}

// Renumbers vertices so corners share a vertex only across edges not in
// `cut` (edge keys, sorted). Every later corner of an edge joins its first.
void split_along(RowMatrixX3i& t, std::vector<int>& vertex_source, const std::vector<std::int64_t>& cut) {
  UnionFind classes(static_cast<int>(3 * t.rows()));
  const auto keyed = keyed_corners(t);
  for_each_edge_run(keyed, [&](int first, int count) {
    if (std::binary_search(cut.begin(), cut.end(), keyed[first].first)) return;
    // The other face runs b -> a: its corner at b is o, at a the next one.
    const int o = keyed[first].second;
    for (int i = first + 1; i < first + count; ++i) {
      const int c = keyed[i].second;
      classes.unite(c, next_corner(o));
      classes.unite(next_corner(c), o);
    }
  });
  std::vector<int> source;
  RowMatrixX3i out;
  vertices_from_corner_classes(
      classes, static_cast<int>(t.rows()), [&](int c) { return vertex_source[corner_vertex(t, c)]; }, out, source);
  t = std::move(out);
  vertex_source = std::move(source);
}

// The corner of a face whose edge and the one before it may both be cut
// (corner 0 of the first face when no corner has both).
int slit_corner(const RowMatrixX3i& t, const std::vector<char>& uncut) {
  if (uncut.empty()) return 0;
  for (int c = 0; c < 3 * static_cast<int>(t.rows()); ++c)
    if (!uncut[c] && !uncut[next_corner(next_corner(c))]) return c;
  return 0;
}

}  // namespace

bool cut_to_disk(RowMatrixX3i& triangles, std::vector<int>& vertex_source, const std::vector<char>& uncut,
                 const std::vector<char>& avoid) {
  auto avoided = [&](int v) { return vertex_source[v] < static_cast<int>(avoid.size()) && avoid[vertex_source[v]]; };
  auto anywhere = [](int) { return false; };
  std::vector<int> loop_of;
  for (;;) {
    const int loops = label_boundary_loops(triangles, static_cast<int>(vertex_source.size()), loop_of);
    if (loops == 0) {
      // Closed: slit open along two edges of one face, which makes a loop of
      // four edges (two would put the whole boundary on one segment).
      if (triangles.rows() == 0) return false;
      const int c = slit_corner(triangles, uncut), v = corner_vertex(triangles, c);
      std::vector<std::int64_t> cut = {edge_key(v, corner_vertex(triangles, next_corner(c))),
                                       edge_key(v, corner_vertex(triangles, next_corner(next_corner(c))))};
      std::sort(cut.begin(), cut.end());
      split_along(triangles, vertex_source, cut);
      continue;
    }
    if (loops == 1) break;
    std::vector<int> path = path_between_loops(triangles, loop_of, uncut, avoided);
    if (path.empty() && !avoid.empty()) path = path_between_loops(triangles, loop_of, uncut, anywhere);
    if (path.empty() && !uncut.empty()) path = path_between_loops(triangles, loop_of, {}, anywhere);
    if (path.empty()) return false;
    // Named in the current numbering; once split, these edges are boundary.
    std::vector<std::int64_t> cut;
    for (size_t i = 0; i + 1 < path.size(); ++i) cut.push_back(edge_key(path[i], path[i + 1]));
    std::sort(cut.begin(), cut.end());
    split_along(triangles, vertex_source, cut);
  }
  // One loop: a disk exactly when chi = V - E + F == 1 (otherwise handles remain).
  long long edges = 0;
  for_each_edge_run(keyed_corners(triangles), [&](int, int) { ++edges; });
  return static_cast<long long>(vertex_source.size()) - edges + triangles.rows() == 1;
}

}  // namespace atlas
