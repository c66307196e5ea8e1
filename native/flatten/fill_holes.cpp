#include "flatten/fill_holes.hpp"

#include <map>

namespace atlas {
namespace {

// Whether the directed edges (from, to) form one closed loop that passes each
// vertex once. Where a slit or a cut the chart keeps runs into the hole, its
// vertex is split in two and the border is an open path: a centre joined to
// it would leave the chart as open as it was there.
bool one_loop(const std::vector<std::pair<int, int>>& edges) {
  std::map<int, int> next;
  for (const auto& [from, to] : edges)
    if (!next.emplace(from, to).second) return false;
  int at = edges.front().first;
  for (size_t step = 0; step < edges.size(); ++step) {
    const auto it = next.find(at);
    if (it == next.end()) return false;
    at = it->second;
    if (at == edges.front().first) return step + 1 == edges.size();
  }
  return false;
}

}  // namespace

RowMatrixX3d fill_holes(const Mesh& mesh, const MeshTopology& topology, const MeshHoles& holes,
                        const std::vector<int>& faces, RowMatrixX3i& triangles, std::vector<int>& vertex_source) {
  if (holes.edge_hole.empty()) return {};
  // The border edges of each hole the chart touches, as (from, to) local vertices.
  std::map<int, std::vector<std::pair<int, int>>> border;
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k)
      if (const int h = holes.edge_hole[topology.corner_edge[3 * faces[i] + k]]; h >= 0)
        border[h].emplace_back(triangles(i, k), triangles(i, (k + 1) % 3));
  // The chart's face runs from -> to along the border, so the filling face runs to -> from.
  std::vector<Eigen::RowVector3i> fill;
  RowMatrixX3d centres(static_cast<Eigen::Index>(border.size()), 3);
  Eigen::Index whole = 0;
  for (const auto& [h, edges] : border) {
    if (static_cast<int>(edges.size()) != holes.edges[h] || !one_loop(edges)) continue;
    Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
    for (const auto& [from, to] : edges) sum += mesh.positions.row(vertex_source[from]);
    centres.row(whole) = sum / static_cast<double>(edges.size());
    const int centre = static_cast<int>(vertex_source.size());
    vertex_source.push_back(mesh.vertex_count() + static_cast<int>(whole++));
    for (const auto& [from, to] : edges) fill.emplace_back(to, from, centre);
  }
  centres.conservativeResize(whole, 3);
  const Eigen::Index first = triangles.rows();
  triangles.conservativeResize(first + static_cast<Eigen::Index>(fill.size()), 3);
  for (size_t i = 0; i < fill.size(); ++i) triangles.row(first + static_cast<Eigen::Index>(i)) = fill[i];
  return centres;
}

}  // namespace atlas
