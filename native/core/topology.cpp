#include "core/topology.hpp"

#include "core/corners.hpp"

namespace atlas {
namespace {

// CSR from a list of (key, value) pairs with keys in [0, key_count).
void bucket(const std::vector<int>& keys, int key_count, std::vector<int>& offsets,
            std::vector<int>& values) {
  offsets.assign(key_count + 1, 0);
  for (int k : keys) ++offsets[k + 1];
  for (int k = 0; k < key_count; ++k) offsets[k + 1] += offsets[k];
  values.resize(keys.size());
  std::vector<int> cursor(offsets.begin(), offsets.end() - 1);
  for (size_t i = 0; i < keys.size(); ++i) values[cursor[keys[i]]++] = static_cast<int>(i);
}

}  // namespace

MeshTopology build_topology(const RowMatrixX3i& triangles, int vertex_count, const std::vector<int>& face_polygon) {
  const int corners = static_cast<int>(3 * triangles.rows());
  const auto keyed = corners_by_edge(corners, [&](int c) { return corner_vertex(triangles, c); });

  MeshTopology t;
  t.corner_edge.resize(corners);
  std::vector<std::pair<int, int>> ends;
  for (int i = 0; i < corners; ++i) {
    if (i == 0 || keyed[i].first != keyed[i - 1].first)
      ends.emplace_back(static_cast<int>(keyed[i].first >> 32),
                        static_cast<int>(keyed[i].first & 0xffffffffu));
    t.corner_edge[keyed[i].second] = static_cast<int>(ends.size()) - 1;
  }
  t.edge_vertices.resize(static_cast<Eigen::Index>(ends.size()), 2);
  for (size_t e = 0; e < ends.size(); ++e) t.edge_vertices.row(e) << ends[e].first, ends[e].second;
  bucket(t.corner_edge, t.edge_count(), t.edge_offsets, t.edge_corners);

  std::vector<int> vertex_at(corners);
  for (int c = 0; c < corners; ++c) vertex_at[c] = corner_vertex(triangles, c);
  bucket(vertex_at, vertex_count, t.vertex_offsets, t.vertex_corners);
  if (face_polygon.empty()) return t;
  t.inside_polygon.assign(t.edge_count(), 0);
  for (int e = 0; e < t.edge_count(); ++e) {
    if (t.edge_valence(e) != 2) continue;
    const int f0 = t.edge_corners[t.edge_offsets[e]] / 3, f1 = t.edge_corners[t.edge_offsets[e] + 1] / 3;
    t.inside_polygon[e] = f0 != f1 && face_polygon[f0] == face_polygon[f1];
  }
  return t;
}

bool uv_continuous_across(const MeshTopology& topology, const RowMatrixX3i& triangles,
                          const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page, int e) {
  if (topology.edge_valence(e) != 2) return false;
  const int c0 = topology.edge_corners[topology.edge_offsets[e]];
  const int c1 = topology.edge_corners[topology.edge_offsets[e] + 1];
  if (face_page[c0 / 3] != face_page[c1 / 3]) return false;
  // Pair each end of the edge in face 0 with the corner of face 1 at the same
  // vertex; with opposite windings c0's start meets c1's end.
  const bool same_winding = corner_vertex(triangles, c0) == corner_vertex(triangles, c1);
  const int a1 = same_winding ? c1 : next_corner(c1);
  const int b1 = same_winding ? next_corner(c1) : c1;
  // 1e-7 page units is far below a texel, yet absorbs text round-off of exporters.
  constexpr double tol = 1e-7;
  return (corner_uv.row(c0) - corner_uv.row(a1)).cwiseAbs().maxCoeff() <= tol &&
         (corner_uv.row(next_corner(c0)) - corner_uv.row(b1)).cwiseAbs().maxCoeff() <= tol;
}

std::vector<char> self_seams(const MeshTopology& topology, const RowMatrixX3i& triangles,
                             const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page,
                             const std::vector<int>& face_chart) {
  std::vector<char> seam(topology.edge_count(), 0);
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (topology.edge_valence(e) != 2) continue;
    const int f0 = topology.edge_corners[topology.edge_offsets[e]] / 3;
    const int f1 = topology.edge_corners[topology.edge_offsets[e] + 1] / 3;
    seam[e] = f0 != f1 && face_chart[f0] >= 0 && face_chart[f0] == face_chart[f1] &&
              !uv_continuous_across(topology, triangles, corner_uv, face_page, e);
  }
  return seam;
}

}  // namespace atlas
