#include "flatten/relief_cut.hpp"

#include <cmath>
#include <functional>
#include <limits>
#include <queue>

#include "core/corners.hpp"
#include "core/geometry.hpp"
#include "core/union_find.hpp"

namespace atlas {
namespace {

struct HalfEdge {
  int to;
  int mesh_edge;
  double length;
};

// Per local vertex: sum_f A3D(f) log(A_uv(f) / A_ref(f)) / sum_f A3D(f) over
// its faces (0 where no face has area), and per face whether it kept less
// than half its texel area.
struct Squeeze {
  std::vector<double> score;
  std::vector<char> face_lost;
};

Squeeze squeeze(const Mesh& mesh, const std::vector<int>& faces, const RowMatrixX3i& triangles, const RowMatrixX2d& uv) {
  std::vector<double> weighted(uv.rows(), 0), weight(uv.rows(), 0);
  Squeeze out{std::vector<double>(uv.rows(), 0), std::vector<char>(faces.size(), 0)};
  for (size_t i = 0; i < faces.size(); ++i) {
    const double before = std::abs(mesh.signed_area_uv(faces[i]));
    const double after = std::abs(signed_area(uv.row(triangles(i, 0)), uv.row(triangles(i, 1)),
                                              uv.row(triangles(i, 2))));
    if (before <= 0 || after <= 0) continue;
    out.face_lost[i] = after < kDensityFloor * before;
    const double a = mesh.area_3d(faces[i]), score = a * std::log(after / before);
    for (int k = 0; k < 3; ++k) weighted[triangles(i, k)] += score, weight[triangles(i, k)] += a;
  }
  for (Eigen::Index v = 0; v < uv.rows(); ++v)
    if (weight[v] > 0) out.score[v] = weighted[v] / weight[v];
  return out;
}

// One target per connected group of faces that lost half their texel area
// (connected through vertices): its interior vertex of lowest score.
std::vector<int> squeezed_targets(const RowMatrixX3i& triangles, const Squeeze& s, const std::vector<char>& on_boundary) {
  UnionFind groups(static_cast<int>(s.score.size()));
  for (Eigen::Index i = 0; i < triangles.rows(); ++i)
    if (s.face_lost[i]) groups.unite(triangles(i, 0), triangles(i, 1)), groups.unite(triangles(i, 0), triangles(i, 2));
  std::vector<int> best(s.score.size(), -1), targets;
  for (Eigen::Index i = 0; i < triangles.rows(); ++i) {
    if (!s.face_lost[i]) continue;
    for (int k = 0; k < 3; ++k) {
      const int v = triangles(i, k);
      int& b = best[groups.find(v)];
      if (!on_boundary[v] && (b < 0 || s.score[v] < s.score[b])) b = v;
    }
  }
  for (size_t root = 0; root < best.size(); ++root)
    if (best[root] >= 0 && groups.find(static_cast<int>(root)) == static_cast<int>(root)) targets.push_back(best[root]);
  return targets;
}

}  // namespace

std::vector<int> relief_cut(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& faces,
                            const RowMatrixX3i& triangles, const RowMatrixX2d& uv) {
  const int n = static_cast<int>(uv.rows());
  std::vector<std::vector<HalfEdge>> out(n);
  const auto keyed = corners_by_edge(static_cast<int>(3 * triangles.rows()),
                                     [&](int c) { return corner_vertex(triangles, c); });
  std::vector<char> on_boundary(n, 0);
  for_each_edge_run(keyed, [&](int first, int count) {
    const int c = keyed[first].second;
    const int a = corner_vertex(triangles, c), b = corner_vertex(triangles, next_corner(c));
    if (count != 2) {
      on_boundary[a] = on_boundary[b] = 1;
      return;
    }
    const int e = topology.corner_edge[3 * faces[corner_face(c)] + c % 3];
    if (!topology.may_cut(e)) return;  // the polygon's outline reaches its vertices
    const double length = edge_length(mesh, topology, e);
    out[a].push_back({b, e, length});
    out[b].push_back({a, e, length});
  });
  const std::vector<int> targets = squeezed_targets(triangles, squeeze(mesh, faces, triangles, uv), on_boundary);
  if (targets.empty()) return {};
  // Shortest paths from the whole boundary at once: their union is a forest
  // rooted on the boundary, one root per tree, so the cut chart stays a disk.
  std::vector<double> distance(n, std::numeric_limits<double>::infinity());
  std::vector<int> via(n, -1), via_edge(n, -1);
  using Entry = std::pair<double, int>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
  for (int v = 0; v < n; ++v)
    if (on_boundary[v]) distance[v] = 0, queue.push({0, v});
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > distance[v]) continue;
    for (const HalfEdge& h : out[v])
      if (!on_boundary[h.to] && d + h.length < distance[h.to]) {
        distance[h.to] = d + h.length, via[h.to] = v, via_edge[h.to] = h.mesh_edge;
        queue.push({distance[h.to], h.to});
      }
  }
  std::vector<char> taken(n, 0);
  std::vector<int> cut;
  for (int t : targets)
    for (int w = t; via[w] >= 0 && !taken[w]; w = via[w]) taken[w] = 1, cut.push_back(via_edge[w]);
  return cut;
}

}  // namespace atlas
