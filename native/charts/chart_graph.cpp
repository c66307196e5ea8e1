#include "charts/chart_graph.hpp"

#include <cmath>
#include <unordered_map>

#include "charts/degenerate_faces.hpp"
#include "core/corners.hpp"
#include "core/union_find.hpp"

namespace atlas {
namespace {

// Charts numbered in order of their first face, so numbering is deterministic.
// A chart never spans two face groups, even where the UVs run on.
std::vector<int> label_charts(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& face_group,
                              int& count) {
  UnionFind uf(mesh.face_count());
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (!uv_continuous_across(topology, mesh.triangles, mesh.corner_uv, mesh.face_page, e)) continue;
    const int f0 = topology.edge_corners[topology.edge_offsets[e]] / 3;
    const int f1 = topology.edge_corners[topology.edge_offsets[e] + 1] / 3;
    if (!face_group.empty() && face_group[f0] != face_group[f1]) continue;
    if (mesh.repeats_vertex(f0) || mesh.repeats_vertex(f1)) continue;
    if (mesh.face_page[f0] >= 0) uf.unite(f0, f1);
  }
  std::vector<int> label(mesh.face_count(), -1), root_label(mesh.face_count(), -1);
  count = 0;
  for (int f = 0; f < mesh.face_count(); ++f) {
    if (mesh.face_page[f] < 0) continue;
    int& l = root_label[uf.find(f)];
    if (l < 0) l = count++;
    label[f] = l;
  }
  return label;
}

double edge_length_3d(const Mesh& mesh, int c) {
  return (mesh.positions.row(corner_vertex(mesh.triangles, c)) -
          mesh.positions.row(corner_vertex(mesh.triangles, next_corner(c)))).norm();
}

double edge_length_uv(const Mesh& mesh, int c) {
  return (mesh.uv_texels(c / 3, c % 3) - mesh.uv_texels(c / 3, next_corner(c) % 3)).norm();
}

void accumulate_face_stats(const Mesh& mesh, ChartGraph& g) {
  for (int f = 0; f < mesh.face_count(); ++f) {
    const int chart = g.face_chart[f];
    if (chart < 0) continue;
    ChartStats& s = g.charts[chart];
    s.area_3d += mesh.area_3d(f);
    const double a = mesh.signed_area_uv(f);
    s.area_uv += std::abs(a);
    s.signed_area_uv += a;
  }
}

// Every corner whose edge leads out of its chart adds to that chart's
// perimeter; corners of different charts on one edge make an adjacency.
void accumulate_boundaries(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& face_group,
                           ChartGraph& g) {
  std::unordered_map<long long, int> pair_index;
  for (int e = 0; e < topology.edge_count(); ++e) {
    const int begin = topology.edge_offsets[e], end = topology.edge_offsets[e + 1];
    for (int i = begin; i < end; ++i) {
      const int ci = topology.edge_corners[i], chart_i = g.face_chart[ci / 3];
      if (chart_i < 0) continue;
      bool outside = (end - begin) != 2 || g.self_seam[e];
      for (int j = begin; !outside && j < end; ++j)
        if (j != i && g.face_chart[topology.edge_corners[j] / 3] != chart_i) outside = true;
      if (outside) {
        g.charts[chart_i].perimeter_3d += edge_length_3d(mesh, ci);
        g.charts[chart_i].perimeter_uv += edge_length_uv(mesh, ci);
      }
      for (int j = i + 1; j < end && !is_fan_edge(topology, e); ++j) {
        const int cj = topology.edge_corners[j], chart_j = g.face_chart[cj / 3];
        if (chart_j < 0 || chart_j == chart_i) continue;
        if (!face_group.empty() && face_group[ci / 3] != face_group[cj / 3]) continue;
        const int a = std::min(chart_i, chart_j), b = std::max(chart_i, chart_j);
        auto [it, fresh] = pair_index.emplace((static_cast<long long>(a) << 32) | b, g.adjacency.size());
        if (fresh) g.adjacency.push_back({a, b});
        ChartAdjacency& adj = g.adjacency[it->second];
        const int ca = chart_i == a ? ci : cj, cb = chart_i == a ? cj : ci;
        adj.length_3d += edge_length_3d(mesh, ci);
        adj.uv_length_a += edge_length_uv(mesh, ca);
        adj.uv_length_b += edge_length_uv(mesh, cb);
        ++adj.shared_edges;
        // Same-direction traversal means the two faces disagree on orientation.
        const bool flipped = mesh.triangles(ci / 3, ci % 3) == mesh.triangles(cj / 3, cj % 3);
        if (end - begin != 2 || flipped || mesh.repeats_vertex(ci / 3) || mesh.repeats_vertex(cj / 3))
          adj.mergeable = false;
      }
    }
  }
}

}  // namespace

ChartGraph build_chart_graph(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& face_group) {
  require_face_groups(face_group, mesh.face_count());
  ChartGraph g;
  int count = 0;
  g.face_chart = label_charts(mesh, topology, face_group, count);
  g.charts.resize(count);
  g.self_seam = self_seams(topology, mesh.triangles, mesh.corner_uv, mesh.face_page, g.face_chart);
  accumulate_face_stats(mesh, g);
  accumulate_boundaries(mesh, topology, face_group, g);
  return g;
}

double seam_length_ratio(const Mesh& mesh, const MeshTopology& topology, const RowMatrixX2d& corner_uv,
                         const Eigen::VectorXi& face_page) {
  double seam = 0;
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (topology.edge_valence(e) < 2) continue;
    const int c0 = topology.edge_corners[topology.edge_offsets[e]];
    bool textured = true;
    for (int i = topology.edge_offsets[e]; i < topology.edge_offsets[e + 1]; ++i)
      textured = textured && face_page[topology.edge_corners[i] / 3] >= 0;
    if (textured && !uv_continuous_across(topology, mesh.triangles, corner_uv, face_page, e))
      seam += edge_length_3d(mesh, c0);
  }
  return per_sqrt_area(seam, mesh);
}

double per_sqrt_area(double length, const Mesh& mesh) {
  double area = 0;
  for (int f = 0; f < mesh.face_count(); ++f) area += mesh.area_3d(f);
  return area > 0 ? length / std::sqrt(area) : 0.0;
}

void require_face_groups(const std::vector<int>& face_group, int face_count) {
  if (!face_group.empty() && static_cast<int>(face_group.size()) != face_count)
    throw InputError("face_group must hold one group per triangle");
}

std::vector<std::vector<int>> faces_of_charts(const ChartGraph& graph) {
  std::vector<std::vector<int>> out(graph.chart_count());
  for (size_t f = 0; f < graph.face_chart.size(); ++f)
    if (graph.face_chart[f] >= 0) out[graph.face_chart[f]].push_back(static_cast<int>(f));
  return out;
}

}  // namespace atlas
