#include "overlap.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <queue>
#include <unordered_map>

#include "cut_to_disk.hpp"
#include "disk_merge.hpp"
#include "geometry.hpp"

namespace atlas {
namespace {

// Segments (p,q) and (r,s) intersect or touch: orientation tests with the
// collinear cases included, so touching boundaries count as overlap.
bool segments_meet(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r,
                   const Eigen::Vector2d& s) {
  const double d1 = signed_area(p, q, r), d2 = signed_area(p, q, s);
  const double d3 = signed_area(r, s, p), d4 = signed_area(r, s, q);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  auto on = [](const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c, double d) {
    return d == 0 && c.x() >= std::min(a.x(), b.x()) && c.x() <= std::max(a.x(), b.x()) &&
           c.y() >= std::min(a.y(), b.y()) && c.y() <= std::max(a.y(), b.y());
  };
  return on(p, q, r, d1) || on(p, q, s, d2) || on(r, s, p, d3) || on(r, s, q, d4);
}

std::vector<std::pair<int, int>> boundary_edges(const RowMatrixX3i& triangles) {
  std::vector<std::pair<int, int>> directed;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) directed.emplace_back(triangles(f, k), triangles(f, (k + 1) % 3));
  std::vector<std::pair<int, int>> keys(directed.size());
  for (size_t i = 0; i < directed.size(); ++i)
    keys[i] = {std::min(directed[i].first, directed[i].second), std::max(directed[i].first, directed[i].second)};
  std::vector<std::pair<int, int>> sorted = keys;
  std::sort(sorted.begin(), sorted.end());
  std::vector<std::pair<int, int>> out;
  for (size_t i = 0; i < keys.size(); ++i) {
    const auto range = std::equal_range(sorted.begin(), sorted.end(), keys[i]);
    if (range.second - range.first == 1) out.push_back(directed[i]);
  }
  return out;
}

}  // namespace

bool boundary_self_intersects(const RowMatrixX3i& triangles, const RowMatrixX2d& uv) {
  const auto edges = boundary_edges(triangles);
  if (edges.size() < 3) return false;
  Eigen::Vector2d lo(uv.col(0).minCoeff(), uv.col(1).minCoeff());
  Eigen::Vector2d hi(uv.col(0).maxCoeff(), uv.col(1).maxCoeff());
  // About one segment per cell on average keeps the pair tests near linear.
  const int n = std::max(1, static_cast<int>(std::sqrt(double(edges.size()))));
  const Eigen::Vector2d cell = ((hi - lo) / n).cwiseMax(1e-12);
  std::vector<std::vector<int>> grid(static_cast<size_t>(n) * n);
  auto cell_of = [&](double v, double origin, double size) {
    return std::clamp(static_cast<int>((v - origin) / size), 0, n - 1);
  };
  for (size_t i = 0; i < edges.size(); ++i) {
    const Eigen::Vector2d a = uv.row(edges[i].first), b = uv.row(edges[i].second);
    const int x0 = cell_of(std::min(a.x(), b.x()), lo.x(), cell.x()), x1 = cell_of(std::max(a.x(), b.x()), lo.x(), cell.x());
    const int y0 = cell_of(std::min(a.y(), b.y()), lo.y(), cell.y()), y1 = cell_of(std::max(a.y(), b.y()), lo.y(), cell.y());
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) grid[static_cast<size_t>(y) * n + x].push_back(static_cast<int>(i));
  }
  for (const auto& bucket : grid)
    for (size_t i = 0; i < bucket.size(); ++i)
      for (size_t j = i + 1; j < bucket.size(); ++j) {
        const auto& e = edges[bucket[i]];
        const auto& g = edges[bucket[j]];
        if (e.first == g.first || e.first == g.second || e.second == g.first || e.second == g.second) continue;
        if (segments_meet(uv.row(e.first), uv.row(e.second), uv.row(g.first), uv.row(g.second))) return true;
      }
  return false;
}

namespace {

struct LocalChart {
  std::vector<int> faces;
  RowMatrixX3i triangles;  // local vertex indices
  std::vector<int> vertices;  // local -> mesh vertex
};

int find_root(std::vector<int>& parent, int x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

// Local vertex numbering of a chart. Corners at one mesh vertex share a local
// vertex only when their faces connect through edges inside the chart, so a
// vertex where the chart merely touches itself (a pinch) is split in two.
LocalChart localize(const Mesh& mesh, const MeshTopology& topology, std::vector<int> faces) {
  LocalChart c;
  c.faces = std::move(faces);
  const int n = static_cast<int>(c.faces.size());
  std::unordered_map<int, int> local_face;
  for (int i = 0; i < n; ++i) local_face[c.faces[i]] = i;
  std::vector<int> parent(3 * n);
  std::iota(parent.begin(), parent.end(), 0);
  auto local_corner_at = [&](int i, int v) {
    for (int k = 0; k < 3; ++k)
      if (mesh.triangles(c.faces[i], k) == v) return 3 * i + k;
    return -1;
  };
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const int e = topology.corner_edge[3 * c.faces[i] + k];
      if (topology.edge_valence(e) != 2) continue;
      for (int j = topology.edge_offsets[e]; j < topology.edge_offsets[e + 1]; ++j) {
        const auto other = local_face.find(topology.edge_corners[j] / 3);
        if (other == local_face.end() || other->second == i) continue;
        for (int end = 0; end < 2; ++end) {
          const int v = topology.edge_vertices(e, end);
          parent[find_root(parent, local_corner_at(i, v))] = find_root(parent, local_corner_at(other->second, v));
        }
      }
    }
  c.triangles.resize(n, 3);
  std::vector<int> vertex_of_root(3 * n, -1);
  for (int corner = 0; corner < 3 * n; ++corner) {
    int& id = vertex_of_root[find_root(parent, corner)];
    if (id < 0) id = static_cast<int>(c.vertices.size()), c.vertices.push_back(mesh.triangles(c.faces[corner / 3], corner % 3));
    c.triangles(corner / 3, corner % 3) = id;
  }
  return c;
}

ChartProblem make_problem(const Mesh& mesh, const ChartGraph& graph, const LocalChart& c) {
  ChartProblem p;
  p.triangles = c.triangles;
  p.positions.resize(static_cast<Eigen::Index>(c.vertices.size()), 3);
  for (size_t i = 0; i < c.vertices.size(); ++i) p.positions.row(i) = mesh.positions.row(c.vertices[i]);
  p.reference_uv.resize(3 * static_cast<Eigen::Index>(c.faces.size()), 2);
  p.mirrored.resize(static_cast<Eigen::Index>(c.faces.size()));
  for (size_t i = 0; i < c.faces.size(); ++i) {
    const int f = c.faces[i];
    for (int k = 0; k < 3; ++k) p.reference_uv.row(3 * i + k) = mesh.uv_texels(f, k).transpose();
    p.mirrored[i] = graph.charts[graph.face_chart[f]].mirrored() ? 1 : 0;
  }
  return p;
}

FlatChart keep_original(const Mesh& mesh, const std::vector<int>& faces) {
  FlatChart out;
  out.faces = faces;
  out.kept_original = true;
  out.corner_uv.resize(3 * static_cast<Eigen::Index>(faces.size()), 2);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k) out.corner_uv.row(3 * i + k) = mesh.uv_texels(faces[i], k).transpose();
  return out;
}

FlatChart from_solution(const LocalChart& c, const ChartSolution& s) {
  FlatChart out;
  out.faces = c.faces;
  out.corner_uv.resize(3 * c.triangles.rows(), 2);
  for (Eigen::Index i = 0; i < c.triangles.rows(); ++i)
    for (int k = 0; k < 3; ++k) out.corner_uv.row(3 * i + k) = s.uv.row(c.triangles(i, k));
  out.energy_initial = s.energy_initial;
  out.energy_final = s.energy_final;
  out.iterations = s.iterations;
  return out;
}

// Regrows the members into disk groups from two far-apart seeds. Every group
// is strictly smaller than the input, so the recursion ends.
std::vector<std::vector<int>> split_members(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                            const std::vector<std::vector<int>>& chart_faces,
                                            const std::vector<int>& members) {
  const int m = static_cast<int>(members.size());
  std::unordered_map<int, int> local;
  for (int i = 0; i < m; ++i) local[members[i]] = i;
  std::vector<std::vector<int>> neighbours(m);
  for (const ChartAdjacency& adj : graph.adjacency) {
    const auto a = local.find(adj.a), b = local.find(adj.b);
    if (a == local.end() || b == local.end() || !adj.mergeable) continue;
    neighbours[a->second].push_back(b->second);
    neighbours[b->second].push_back(a->second);
  }
  std::vector<int> label(mesh.face_count(), -1);
  for (int i = 0; i < m; ++i)
    for (int f : chart_faces[members[i]]) label[f] = i;
  DiskClusters disks(mesh, topology, label, m);

  auto area = [&](int i) { return graph.charts[members[i]].area_uv; };
  int seed0 = 0;
  for (int i = 1; i < m; ++i)
    if (area(i) > area(seed0)) seed0 = i;
  // The member farthest from seed0 in the adjacency graph seeds the other group.
  std::vector<int> distance(m, -1);
  std::queue<int> bfs;
  bfs.push(seed0);
  distance[seed0] = 0;
  while (!bfs.empty()) {
    const int i = bfs.front();
    bfs.pop();
    for (int n : neighbours[i])
      if (distance[n] < 0) distance[n] = distance[i] + 1, bfs.push(n);
  }
  int seed1 = seed0 == 0 ? 1 : 0;
  for (int i = 0; i < m; ++i)
    if (i != seed0 && distance[i] > distance[seed1]) seed1 = i;

  // Two seeds grow in turn, the smaller group first; members neither can take
  // seed further groups of their own, so pieces stay as large as topology allows.
  std::vector<int> group_of(m, -1);
  std::vector<std::vector<int>> groups;
  std::vector<int> cluster;
  std::vector<double> group_area;
  auto seed = [&](int i) {
    group_of[i] = static_cast<int>(groups.size());
    groups.push_back({i});
    cluster.push_back(i);
    group_area.push_back(area(i));
  };
  auto grow = [&](int g) {
    for (int i : groups[g])
      for (int n : neighbours[i]) {
        if (group_of[n] >= 0) continue;
        if (const auto euler = disks.merged_euler(cluster[g], n)) {
          cluster[g] = disks.merge(cluster[g], n, *euler);
          group_of[n] = g;
          groups[g].push_back(n);
          group_area[g] += area(n);
          return true;
        }
      }
    return false;
  };
  seed(seed0);
  seed(seed1);
  for (bool grew = true; grew;) {
    const int small = group_area[0] <= group_area[1] ? 0 : 1;
    grew = grow(small) || grow(1 - small);
  }
  for (int i = 0; i < m; ++i) {
    if (group_of[i] >= 0) continue;
    seed(i);
    while (grow(static_cast<int>(groups.size()) - 1)) {
    }
  }
  std::vector<std::vector<int>> out;
  for (const auto& g : groups) {
    out.emplace_back();
    for (int i : g) out.back().push_back(members[i]);
  }
  return out;
}

bool usable(const ChartSolution& s, const RowMatrixX3i& triangles, FlattenStats& stats) {
  if (!s.failure.empty() || s.flipped > 0) return ++stats.solver_failed, false;
  if (boundary_self_intersects(triangles, s.uv)) return ++stats.overlapped, false;
  return true;
}

}  // namespace

std::vector<FlatChart> flatten_without_overlap(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                               const std::vector<std::vector<int>>& chart_faces,
                                               const std::vector<int>& members, const SlimOptions& options,
                                               const RunControl& control, FlattenStats& stats) {
  std::vector<FlatChart> done;
  std::vector<std::vector<int>> pending = {members};
  while (!pending.empty()) {
    const std::vector<int> group = std::move(pending.back());
    pending.pop_back();
    if (group.size() == 1) {
      done.push_back(keep_original(mesh, chart_faces[group[0]]));
      continue;
    }
    std::vector<int> faces;
    for (int c : group) faces.insert(faces.end(), chart_faces[c].begin(), chart_faces[c].end());
    LocalChart local = localize(mesh, topology, std::move(faces));
    if (!cut_to_disk(local.triangles, local.vertices)) {
      ++stats.not_disk;
    } else {
      const ChartSolution solution = parameterize_chart(make_problem(mesh, graph, local), options, control);
      if (usable(solution, local.triangles, stats)) {
        done.push_back(from_solution(local, solution));
        continue;
      }
    }
    for (auto& piece : split_members(mesh, topology, graph, chart_faces, group)) pending.push_back(std::move(piece));
  }
  return done;
}

}  // namespace atlas
