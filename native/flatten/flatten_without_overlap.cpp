#include "flatten/flatten_without_overlap.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <optional>
#include <queue>
#include <unordered_map>

#include "charts/disk_merge.hpp"
#include "core/corners.hpp"
#include "core/geometry.hpp"
#include "core/parallel_for.hpp"
#include "core/segment_crossing.hpp"
#include "core/union_find.hpp"
#include "flatten/cut_to_disk.hpp"
#include "flatten/fill_holes.hpp"
#include "flatten/relief_cut.hpp"

namespace atlas {
namespace {

struct BoundaryEdge {
  int from, to, face;
};

// Directed boundary edges (used by one face only), with their face.
std::vector<BoundaryEdge> boundary_edges(const RowMatrixX3i& triangles) {
  const auto keyed = corners_by_edge(static_cast<int>(3 * triangles.rows()),
                                     [&](int c) { return corner_vertex(triangles, c); });
  std::vector<BoundaryEdge> out;
  for_each_edge_run(keyed, [&](int first, int count) {
    if (count != 1) return;
    const int c = keyed[first].second;
    out.push_back({corner_vertex(triangles, c), corner_vertex(triangles, next_corner(c)), corner_face(c)});
  });
  return out;
}

}  // namespace

std::optional<std::pair<int, int>> boundary_crossing(const RowMatrixX3i& triangles, const RowMatrixX2d& uv) {
  const auto edges = boundary_edges(triangles);
  std::vector<Eigen::Vector2d> points(uv.rows());
  for (Eigen::Index v = 0; v < uv.rows(); ++v) points[v] = uv.row(v).transpose();
  std::vector<Segment> segments;
  for (const BoundaryEdge& e : edges) segments.push_back({e.from, e.to});
  const auto crossing = first_crossing(points, segments);
  if (!crossing) return std::nullopt;
  return std::make_pair(edges[crossing->first].face, edges[crossing->second].face);
}

bool boundary_self_intersects(const RowMatrixX3i& triangles, const RowMatrixX2d& uv) {
  return boundary_crossing(triangles, uv).has_value();
}

ChartProblem chart_problem(const Mesh& mesh, const ChartGraph& graph, const std::vector<int>& faces,
                           const RowMatrixX3i& triangles, const std::vector<int>& vertices,
                           const RowMatrixX3d& fill_positions) {
  ChartProblem p;
  p.triangles = triangles;
  p.positions.resize(static_cast<Eigen::Index>(vertices.size()), 3);
  for (size_t i = 0; i < vertices.size(); ++i)
    p.positions.row(i) = vertices[i] < mesh.vertex_count() ? mesh.positions.row(vertices[i])
                                                           : fill_positions.row(vertices[i] - mesh.vertex_count());
  p.reference_uv = RowMatrixX2d::Zero(3 * triangles.rows(), 2);
  p.mirrored = Eigen::VectorXi::Zero(triangles.rows());
  for (size_t i = 0; i < faces.size(); ++i) {
    const int f = faces[i];
    for (int k = 0; k < 3; ++k) p.reference_uv.row(3 * i + k) = mesh.uv_texels(f, k).transpose();
    p.mirrored[i] = graph.charts[graph.face_chart[f]].mirrored() ? 1 : 0;
  }
  return p;
}

namespace {

struct LocalChart {
  std::vector<int> faces;
  RowMatrixX3i triangles;  // local vertex indices
  std::vector<int> vertices;  // local -> mesh vertex
};

// Calls visit(i, j, e) for every two faces i != j of `faces` (positions in
// it) that share the manifold edge e, once from each side.
template <class Visit>
void for_each_shared_edge(const MeshTopology& topology, const std::vector<int>& faces, Visit visit) {
  std::unordered_map<int, int> local;
  for (int i = 0; i < static_cast<int>(faces.size()); ++i) local[faces[i]] = i;
  for (int i = 0; i < static_cast<int>(faces.size()); ++i)
    for (int k = 0; k < 3; ++k) {
      const int e = topology.corner_edge[3 * faces[i] + k];
      if (topology.edge_valence(e) != 2) continue;
      for (int j = topology.edge_offsets[e]; j < topology.edge_offsets[e + 1]; ++j) {
        const auto other = local.find(topology.edge_corners[j] / 3);
        if (other != local.end() && other->second != i) visit(i, other->second, e);
      }
    }
}

// Local vertex numbering of a chart. Corners at one mesh vertex share a local
// vertex only when their faces connect through edges inside the chart, so a
// vertex where the chart merely touches itself (a pinch) is split in two.
// An original chart that meets itself at a UV seam keeps it open
// (graph.self_seam), as DiskClusters does, and so do the edges `cuts` (sorted).
LocalChart localize(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                    std::vector<int> faces, const std::vector<int>& cuts = {}) {
  LocalChart c;
  c.faces = std::move(faces);
  const int n = static_cast<int>(c.faces.size());
  UnionFind corners(3 * n);
  auto local_corner_at = [&](int i, int v) { return 3 * i + mesh.corner_of(c.faces[i], v); };
  for_each_shared_edge(topology, c.faces, [&](int i, int j, int e) {
    if (graph.self_seam[e] || std::binary_search(cuts.begin(), cuts.end(), e)) return;
    for (int end = 0; end < 2; ++end) {
      const int v = topology.edge_vertices(e, end);
      corners.unite(local_corner_at(i, v), local_corner_at(j, v));
    }
  });
  vertices_from_corner_classes(
      corners, n, [&](int corner) { return mesh.triangles(c.faces[corner / 3], corner % 3); }, c.triangles,
      c.vertices);
  return c;
}

// Per corner of `rows` faces, `faces` first (3 per face, in order): 1 where
// its edge lies inside an input polygon (see cut_to_disk), and on every face
// past `faces` (those filling holes, which no cut needs to cross); empty
// when neither is.
std::vector<char> uncut_corners(const MeshTopology& topology, const std::vector<int>& faces, Eigen::Index rows) {
  if (topology.inside_polygon.empty() && rows == static_cast<Eigen::Index>(faces.size())) return {};
  std::vector<char> out(3 * rows, 1);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k) out[3 * i + k] = !topology.may_cut(topology.corner_edge[3 * faces[i] + k]);
  return out;
}

// Per source vertex (indexed by c.vertices' values): 1 on the border of a
// hole fill_holes filled (the first two corners of each face past c.faces;
// the third is the hole's centre).
std::vector<char> filled_hole_borders(const LocalChart& c) {
  std::vector<char> out(*std::max_element(c.vertices.begin(), c.vertices.end()) + 1, 0);
  for (Eigen::Index i = static_cast<Eigen::Index>(c.faces.size()); i < c.triangles.rows(); ++i)
    out[c.vertices[c.triangles(i, 0)]] = out[c.vertices[c.triangles(i, 1)]] = 1;
  return out;
}

ChartProblem make_problem(const Mesh& mesh, const ChartGraph& graph, const LocalChart& c,
                          const RowMatrixX3d& fill_positions) {
  return chart_problem(mesh, graph, c.faces, c.triangles, c.vertices, fill_positions);
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

// Below this height over its longest edge, in texels, a face's UVs are a
// point or a line (texturers put faces no camera saw there): it covers no
// texel, and float32 may store it turned over.
constexpr double kMinUvHeight = 1e-3;

bool flat_in_uv(const Mesh& mesh, int f) {
  double longest = 0;
  for (int k = 0; k < 3; ++k)
    longest = std::max(longest, (mesh.uv_texels(f, (k + 1) % 3) - mesh.uv_texels(f, k)).norm());
  return !(2 * std::abs(mesh.signed_area_uv(f)) > kMinUvHeight * longest);
}

// A face alone in its chart whose UVs are flat (flat_in_uv): the two ends
// of its longest UV edge stay, and its third corner moves a texel off that
// line, counter-clockwise (a unit triangle at a point). Its texels then
// sample the point or line the renderer shows there, at the line's length and
// a texel's width; kept as it was, it came out in the fill colour.
FlatChart thickened_lone_face(const Mesh& mesh, int f) {
  FlatChart out = keep_original(mesh, {f});
  int k = 0;  // the longest edge runs from corner k to k + 1
  for (int j = 1; j < 3; ++j)
    if ((out.corner_uv.row((j + 1) % 3) - out.corner_uv.row(j)).norm() >
        (out.corner_uv.row((k + 1) % 3) - out.corner_uv.row(k)).norm())
      k = j;
  const Eigen::RowVector2d edge = out.corner_uv.row((k + 1) % 3) - out.corner_uv.row(k);
  if (edge.norm() > 0) {
    out.corner_uv.row((k + 2) % 3) += Eigen::RowVector2d(-edge.y(), edge.x()) / edge.norm();
  } else {
    out.corner_uv.row(1) += Eigen::RowVector2d(1, 0);
    out.corner_uv.row(2) += Eigen::RowVector2d(0, 1);
  }
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
  out.iteration_seconds = s.iteration_seconds;
  out.factorize_seconds = s.factorize_seconds;
  return out;
}

struct SubMesh {
  Mesh mesh;
  MeshTopology topology;
};

// The given faces as a mesh of their own, in the given order.
SubMesh sub_mesh(const Mesh& mesh, const std::vector<int>& faces) {
  SubMesh sub;
  const int n = static_cast<int>(faces.size());
  std::unordered_map<int, int> vertex;
  sub.mesh.triangles.resize(n, 3);
  sub.mesh.corner_uv.resize(3 * n, 2);
  sub.mesh.face_page.resize(n);
  std::vector<int> source;
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const auto [it, fresh] = vertex.emplace(mesh.triangles(faces[i], k), static_cast<int>(source.size()));
      if (fresh) source.push_back(it->first);
      sub.mesh.triangles(i, k) = it->second;
      sub.mesh.corner_uv.row(3 * i + k) = mesh.corner_uv.row(3 * faces[i] + k);
    }
    sub.mesh.face_page[i] = mesh.face_page[faces[i]];
  }
  sub.mesh.positions.resize(static_cast<Eigen::Index>(source.size()), 3);
  for (size_t v = 0; v < source.size(); ++v) sub.mesh.positions.row(v) = mesh.positions.row(source[v]);
  sub.mesh.pages = mesh.pages;
  sub.topology = build_topology(sub.mesh.triangles, sub.mesh.vertex_count());
  return sub;
}

// Per member (its position in `members`), the members it shares a mergeable
// adjacency of the graph with.
std::vector<std::vector<int>> member_neighbours(const ChartGraph& graph, const std::vector<int>& members) {
  std::unordered_map<int, int> local;
  for (int i = 0; i < static_cast<int>(members.size()); ++i) local[members[i]] = i;
  std::vector<std::vector<int>> neighbours(members.size());
  for (const ChartAdjacency& adj : graph.adjacency) {
    const auto a = local.find(adj.a), b = local.find(adj.b);
    if (a == local.end() || b == local.end() || !adj.mergeable) continue;
    neighbours[a->second].push_back(b->second);
    neighbours[b->second].push_back(a->second);
  }
  return neighbours;
}

// Per edge of `sub` (the faces `faces`, labelled by member in `label`), the
// seams its DiskClusters keeps: where a member meets itself in UV, and where
// the graph keeps a seam.
std::vector<char> member_seams(const MeshTopology& topology, const ChartGraph& graph, const std::vector<int>& faces,
                               const SubMesh& sub, const std::vector<int>& label) {
  // The graph's seams (partial merges' open arcs among them) stay open too.
  std::vector<char> seams = self_seams(sub.topology, sub.mesh.triangles, sub.mesh.corner_uv, sub.mesh.face_page, label);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k)
      if (graph.self_seam[topology.corner_edge[3 * faces[i] + k]]) seams[sub.topology.corner_edge[3 * i + k]] = 1;
  return seams;
}

// The member reached last from `from` through the neighbours (breadth first;
// the first of the farthest, never `from` itself).
int farthest_member(const std::vector<std::vector<int>>& neighbours, int from) {
  const int m = static_cast<int>(neighbours.size());
  std::vector<int> distance(m, -1);
  std::queue<int> bfs;
  bfs.push(from);
  distance[from] = 0;
  while (!bfs.empty()) {
    const int i = bfs.front();
    bfs.pop();
    for (int n : neighbours[i])
      if (distance[n] < 0) distance[n] = distance[i] + 1, bfs.push(n);
  }
  int farthest = from == 0 ? 1 : 0;
  for (int i = 0; i < m; ++i)
    if (i != from && distance[i] > distance[farthest]) farthest = i;
  return farthest;
}

// The two seeds of split_members (positions in `members`, areas `area`): the
// largest member other than the culprit, and the culprit or else the member
// farthest from the largest.
std::pair<int, int> split_seeds(const std::vector<int>& members, const std::vector<double>& area,
                                const std::vector<std::vector<int>>& neighbours, int culprit) {
  const int m = static_cast<int>(members.size());
  const int culprit_index = culprit < 0 ? -1 : static_cast<int>(std::find(members.begin(), members.end(), culprit) - members.begin());
  int seed0 = culprit_index == 0 ? 1 : 0;
  for (int i = 0; i < m; ++i)
    if (i != culprit_index && area[i] > area[seed0]) seed0 = i;
  return {seed0, culprit_index < 0 ? farthest_member(neighbours, seed0) : culprit_index};
}

// Groups of members (positions in the members) that grow a neighbour at a
// time while DiskClusters finds the union a disk.
class MemberGroups {
 public:
  MemberGroups(DiskClusters& disks, const std::vector<std::vector<int>>& neighbours, const std::vector<double>& area)
      : disks_(disks), neighbours_(neighbours), area_(area), group_of_(area.size(), -1) {}

  // Starts a group of member i alone.
  void seed(int i) {
    group_of_[i] = static_cast<int>(groups_.size());
    groups_.push_back({i});
    cluster_.push_back(i);
    group_area_.push_back(area_[i]);
  }

  // Whether group g took a member: the first neighbour of its members, in
  // their order, that no group holds and whose merge DiskClusters allows.
  bool grow(int g) {
    for (int i : groups_[g])
      for (int n : neighbours_[i]) {
        if (group_of_[n] >= 0) continue;
        if (const MergeCheck check = disks_.check_merge(cluster_[g], n)) {
          cluster_[g] = disks_.merge(cluster_[g], n, check);
          group_of_[n] = g;
          groups_[g].push_back(n);
          group_area_[g] += area_[n];
          return true;
        }
      }
    return false;
  }

  bool grouped(int i) const { return group_of_[i] >= 0; }
  double area(int g) const { return group_area_[g]; }
  const std::vector<std::vector<int>>& groups() const { return groups_; }

 private:
  DiskClusters& disks_;
  const std::vector<std::vector<int>>& neighbours_;
  const std::vector<double>& area_;
  std::vector<int> group_of_;
  std::vector<std::vector<int>> groups_;
  std::vector<int> cluster_;
  std::vector<double> group_area_;
};

// Two seeds grow in turn, the smaller group first; members neither can take
// seed further groups of their own, so pieces stay as large as topology allows.
// Returns the groups, as positions in the members.
std::vector<std::vector<int>> grown_groups(MemberGroups& groups, int members, std::pair<int, int> seeds) {
  groups.seed(seeds.first);
  groups.seed(seeds.second);
  for (bool grew = true; grew;) {
    const int small = groups.area(0) <= groups.area(1) ? 0 : 1;
    grew = groups.grow(small) || groups.grow(1 - small);
  }
  for (int i = 0; i < members; ++i) {
    if (groups.grouped(i)) continue;
    groups.seed(i);
    while (groups.grow(static_cast<int>(groups.groups().size()) - 1)) {
    }
  }
  return groups.groups();
}

// Regrows the members into disk groups from two seeds that grow in turn, the
// smaller group first: the largest member, and the culprit (the original chart
// at a boundary crossing, so the crossing ends up between the groups) or else
// the member farthest from the largest. Every group is strictly smaller than
// the input, so the recursion ends.
std::vector<std::vector<int>> split_members(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                            const std::vector<std::vector<int>>& chart_faces,
                                            const std::vector<int>& members, int culprit) {
  const int m = static_cast<int>(members.size());
  const std::vector<std::vector<int>> neighbours = member_neighbours(graph, members);
  // DiskClusters on the members' faces alone: its work and memory then scale
  // with this chart rather than with the whole scan.
  std::vector<int> faces, label;
  for (int i = 0; i < m; ++i)
    for (int f : chart_faces[members[i]]) faces.push_back(f), label.push_back(i);
  const SubMesh sub = sub_mesh(mesh, faces);
  DiskClusters disks(sub.mesh, sub.topology, label, m, member_seams(topology, graph, faces, sub, label));

  std::vector<double> area(m);
  for (int i = 0; i < m; ++i) area[i] = graph.charts[members[i]].area_uv;
  MemberGroups groups(disks, neighbours, area);
  std::vector<std::vector<int>> out;
  for (const auto& g : grown_groups(groups, m, split_seeds(members, area, neighbours, culprit))) {
    out.emplace_back();
    for (int i : g) out.back().push_back(members[i]);
  }
  return out;
}

// The members undone into the two clusters the aggregation's last merge among
// them joined (merges: (survivor, absorbed) in order, see Aggregation). Both
// were disks when it made them, and gave way to the merge that failed, the
// costliest the greedy order took. Empty when the members are not one cluster
// of that history (a regrown group).
std::vector<std::vector<int>> undo_last_merge(const std::vector<std::pair<int, int>>& merges,
                                              const std::vector<int>& members) {
  std::unordered_map<int, int> local;
  for (int i = 0; i < static_cast<int>(members.size()); ++i) local[members[i]] = i;
  int last = -1;
  for (int i = 0; i < static_cast<int>(merges.size()); ++i)
    if (local.count(merges[i].first) && local.count(merges[i].second)) last = i;
  if (last < 0) return {};
  UnionFind before(static_cast<int>(members.size()));
  int joined = 0;
  for (int i = 0; i < last; ++i) {
    const auto a = local.find(merges[i].first), b = local.find(merges[i].second);
    if (a != local.end() && b != local.end()) before.unite(a->second, b->second), ++joined;
  }
  // A tree of merges over m members has m - 1 of them, the last one included.
  if (joined + 2 != static_cast<int>(members.size())) return {};
  const int side = before.find(local[merges[last].second]);
  std::vector<std::vector<int>> out(2);
  for (int i = 0; i < static_cast<int>(members.size()); ++i)
    out[before.find(i) == side ? 1 : 0].push_back(members[i]);
  return out;
}

double edges_length(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& edges) {
  double length = 0;
  for (int e : edges) length += edge_length(mesh, topology, e);
  return length;
}

constexpr double kNoLimit = std::numeric_limits<double>::infinity();

// 3D length of the edges between the faces of two groups of original charts.
double shared_border_length(const Mesh& mesh, const MeshTopology& topology,
                            const std::vector<std::vector<int>>& chart_faces,
                            const std::vector<std::vector<int>>& groups) {
  std::unordered_map<int, int> group_of_face;
  for (int g = 0; g < 2; ++g)
    for (int c : groups[g])
      for (int f : chart_faces[c]) group_of_face[f] = g;
  std::vector<int> border;
  for (int c : groups[0])
    for (int f : chart_faces[c])
      for (int k = 0; k < 3; ++k) {
        const int e = topology.corner_edge[3 * f + k];
        for (int i = topology.edge_offsets[e]; i < topology.edge_offsets[e + 1]; ++i) {
          const auto other = group_of_face.find(topology.edge_corners[i] / 3);
          if (other != group_of_face.end() && other->second == 1) border.push_back(e);
        }
      }
  return edges_length(mesh, topology, border);
}

// The 3D area of a flattened chart's faces that end with less than half their
// original texel area (eq.: new UV area / original UV area < 1/2), and the
// original chart that lost the most of it (-1 when none did). SLIM balances
// distortion, it does not bound it: FlattenOptions::max_density_loss bounds the loss.
struct DensityLoss {
  double lost_area = 0, total_area = 0;
  int culprit = -1;
};

DensityLoss density_loss(const Mesh& mesh, const ChartGraph& graph, const LocalChart& local, const RowMatrixX2d& uv) {
  std::unordered_map<int, double> lost;
  DensityLoss out;
  for (size_t i = 0; i < local.faces.size(); ++i) {
    const int f = local.faces[i];
    const double area_3d = mesh.area_3d(f);
    out.total_area += area_3d;
    const double before = std::abs(mesh.signed_area_uv(f));
    const double after = std::abs(signed_area(uv.row(local.triangles(i, 0)), uv.row(local.triangles(i, 1)),
                                              uv.row(local.triangles(i, 2))));
    if (before > 0 && after < kDensityFloor * before) lost[graph.face_chart[f]] += area_3d, out.lost_area += area_3d;
  }
  if (!lost.empty())
    out.culprit = std::max_element(lost.begin(), lost.end(), [](const auto& a, const auto& b) { return a.second < b.second; })->first;
  return out;
}

// True when some faces wind one way in UV and some the other (faces of zero
// UV area count for neither). A closed piece always does: its signed areas sum
// to zero. Slivers count here, as in the metrics: enlarge_tiny_charts may
// make them visible.
bool folds_over(const Mesh& mesh, const std::vector<int>& faces) {
  bool positive = false, negative = false;
  for (int f : faces) {
    const double a = mesh.signed_area_uv(f);
    positive = positive || a > 0;
    negative = negative || a < 0;
  }
  return positive && negative;
}

// Faces as two edge-connected halves, each face going to the nearer of two
// far-apart seeds (breadth first, over manifold edges inside the set), the
// triangles of an input polygon together unless that leaves a half empty.
// Faces not connected to the first are returned as the second part instead.
std::vector<std::vector<int>> halves(const MeshTopology& topology, const std::vector<int>& faces,
                                     bool whole_polygons = true) {
  const int n = static_cast<int>(faces.size());
  std::vector<std::vector<int>> neighbours(n);
  UnionFind polygon(n);
  for_each_shared_edge(topology, faces, [&](int i, int j, int e) {
    neighbours[i].push_back(j);
    if (whole_polygons && !topology.may_cut(e)) polygon.unite(i, j);
  });
  std::vector<std::vector<int>> mates(n);
  for (int i = 0; i < n; ++i) mates[polygon.find(i)].push_back(i);
  // Multi-source breadth-first search: label[i] is the seed that reached i
  // (its polygon) first.
  auto grow = [&](const std::vector<int>& seeds, std::vector<int>& label) {
    label.assign(n, -1);
    std::queue<int> queue;
    auto claim = [&](int i, int l) {
      for (int m : mates[polygon.find(i)])
        if (label[m] < 0) label[m] = l, queue.push(m);
    };
    for (size_t s = 0; s < seeds.size(); ++s) claim(seeds[s], static_cast<int>(s));
    int last = seeds.front();
    for (; !queue.empty(); queue.pop()) {
      last = queue.front();
      for (int m : neighbours[last])
        if (label[m] < 0) claim(m, label[last]);
    }
    return last;
  };
  std::vector<int> label;
  const int far = grow({0}, label);
  std::vector<std::vector<int>> out(2);
  if (std::count(label.begin(), label.end(), -1) == 0) grow({far, grow({far}, label)}, label);
  for (int i = 0; i < n; ++i) out[label[i] == 0 ? 0 : 1].push_back(faces[i]);
  if (out[1].empty() && whole_polygons && n > 1) return halves(topology, faces, false);
  return out;
}

// Of the two faces at a boundary crossing, the original chart with less area.
int smaller_chart(const ChartGraph& graph, int face_a, int face_b) {
  const int a = graph.face_chart[face_a], b = graph.face_chart[face_b];
  return graph.charts[a].area_uv <= graph.charts[b].area_uv ? a : b;
}

// One flattening attempt of the faces as a chart of their own: cut open to a
// disk, solved, and refused if the solve failed, the boundary crosses itself
// or texel density is lost (see density_loss).
struct Attempt {
  std::optional<FlatChart> chart;             // set unless refused
  int FlattenStats::*refusal = nullptr;       // the counter of the reason, when refused
  int culprit = -1;                           // the original chart to seed a split at, or -1
};

// max_cut_length: the 3D length relief cuts may add in all (the seam a split
// would add instead); the chart is refused rather than cut longer.
Attempt flatten_faces(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                      const std::vector<int>& faces, double max_cut_length, const FlattenOptions& options,
                      const RunControl& control, FlattenStats& stats) {
  std::vector<int> cuts;
  double cut_length = 0;
  for (int round = 0;; ++round) {
    LocalChart local = localize(mesh, topology, graph, faces, cuts);
    const RowMatrixX3d fill = fill_holes(mesh, topology, graph.holes, local.faces, local.triangles, local.vertices);
    if (!cut_to_disk(local.triangles, local.vertices, uncut_corners(topology, local.faces, local.triangles.rows()),
                     fill.rows() ? filled_hole_borders(local) : std::vector<char>()))
      return {std::nullopt, &FlattenStats::not_disk};
    const ChartSolution solution =
        parameterize_chart(make_problem(mesh, graph, local, fill), options.slim, control);
    local.triangles.conservativeResize(static_cast<Eigen::Index>(local.faces.size()), 3);  // the fill dropped
    stats.scaffolded += solution.scaffolded;
    if (!solution.status.ok() || solution.flipped > 0) return {std::nullopt, &FlattenStats::solver_failed};
    if (const auto crossing = boundary_crossing(local.triangles, solution.uv))
      return {std::nullopt, &FlattenStats::overlapped,
              smaller_chart(graph, local.faces[crossing->first], local.faces[crossing->second])};
    const DensityLoss loss = density_loss(mesh, graph, local, solution.uv);
    if (loss.lost_area > options.max_density_loss * loss.total_area && loss.lost_area > options.density_loss_allowance) {
      if (round < options.relief_cuts) {
        const std::vector<int> cut = relief_cut(mesh, topology, local.faces, local.triangles, solution.uv);
        cut_length += edges_length(mesh, topology, cut);
        if (!cut.empty() && cut_length <= max_cut_length) {
          cuts.insert(cuts.end(), cut.begin(), cut.end());
          std::sort(cuts.begin(), cuts.end());
          ++stats.relief_cuts;
          continue;
        }
      }
      return {std::nullopt, &FlattenStats::density_lost, loss.culprit};
    }
    stats.density_repaired += solution.density_repaired;
    stats.holes_filled += static_cast<int>(fill.rows());
    FlatChart chart = from_solution(local, solution);
    chart.density_lost_area = loss.lost_area;
    return {std::move(chart)};
  }
}

// True when the faces' original UVs cover some part of them twice without a
// fold: their boundary crosses itself.
bool original_boundary_crosses(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                               const std::vector<int>& faces) {
  const LocalChart local = localize(mesh, topology, graph, faces);
  RowMatrixX2d uv(static_cast<Eigen::Index>(local.vertices.size()), 2);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k) uv.row(local.triangles(i, k)) = mesh.uv_texels(faces[i], k).transpose();
  return boundary_self_intersects(local.triangles, uv);
}

// A lone original chart whose UVs overlap themselves (folding over, as every
// closed component mapped as one chart does, or with a boundary that crosses
// itself): it is flattened whole if it can be, else its faces are halved, each
// half kept as it was if its UVs no longer overlap, else flattened or halved
// again. A single face cannot overlap itself, so this ends, and no face is
// left flipped and no boundary crossing.
void flatten_lone_chart(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                        const std::vector<int>& chart, const FlattenOptions& options, const RunControl& control,
                        std::vector<FlatChart>& done, FlattenStats& stats) {
  std::vector<std::vector<int>> pending = {chart};
  while (!pending.empty()) {
    std::vector<int> faces = std::move(pending.back());
    pending.pop_back();
    const bool flat = std::any_of(faces.begin(), faces.end(), [&](int f) { return flat_in_uv(mesh, f); });
    if (faces.size() == 1 && flat) {
      done.push_back(thickened_lone_face(mesh, faces[0]));
    } else if (!flat && !folds_over(mesh, faces) && !original_boundary_crosses(mesh, topology, graph, faces)) {
      done.push_back(keep_original(mesh, faces));
    } else if (Attempt attempt = flatten_faces(mesh, topology, graph, faces, kNoLimit, options, control, stats);
               attempt.chart) {
      done.push_back(std::move(*attempt.chart));
    } else {
      ++stats.overlap_halved;
      for (auto& half : halves(topology, faces)) pending.push_back(std::move(half));
    }
  }
}

}  // namespace

std::vector<char> charts_with_handles(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                      const std::vector<std::vector<int>>& chart_faces) {
  std::vector<char> out(chart_faces.size(), 0);
  parallel_for(static_cast<int>(chart_faces.size()), 16, [&](int c) {
    if (chart_faces[c].empty()) return;
    LocalChart local = localize(mesh, topology, graph, chart_faces[c]);
    // chi = V - E + F = 2 - 2 genus - loops is 1 for a disk only.
    int edges = 0;
    for_each_edge_run(corners_by_edge(static_cast<int>(3 * local.triangles.rows()),
                                      [&](int k) { return corner_vertex(local.triangles, k); }),
                      [&](int, int) { ++edges; });
    const long long chi = static_cast<long long>(local.vertices.size()) - edges + local.triangles.rows();
    out[c] = chi != 1 && !cut_to_disk(local.triangles, local.vertices);  // which edges it cuts cannot matter here
  });
  return out;
}

// After a split each piece is solved by a recursive call in an OpenMP task,
// which a thread with no chart left to start takes up: one large chart that
// splits again and again no longer leaves the other cores idle. The pieces
// come back in a fixed order. An exception (Cancelled included) cannot leave
// a task: it is caught there and rethrown after the wait.
std::vector<FlatChart> flatten_without_overlap(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                               const std::vector<std::vector<int>>& chart_faces,
                                               const std::vector<int>& members,
                                               const std::vector<std::pair<int, int>>& merges,
                                               const FlattenOptions& options, const RunControl& control,
                                               FlattenStats& stats) {
  std::vector<FlatChart> done;
  if (members.size() == 1) {
    flatten_lone_chart(mesh, topology, graph, chart_faces[members[0]], options, control, done, stats);
    return done;
  }
  std::vector<int> faces;
  for (int c : members) faces.insert(faces.end(), chart_faces[c].begin(), chart_faces[c].end());
  // Relief cuts are worth it only while not much longer than the border a
  // split opens: a split costs a chart as well.
  constexpr double kCutPerSplitSeam = 3;
  std::vector<std::vector<int>> pieces = undo_last_merge(merges, members);
  const double split_seam =
      pieces.empty() ? kNoLimit : kCutPerSplitSeam * shared_border_length(mesh, topology, chart_faces, pieces);
  Attempt attempt = flatten_faces(mesh, topology, graph, faces, split_seam, options, control, stats);
  if (attempt.chart) {
    done.push_back(std::move(*attempt.chart));
    return done;
  }
  ++(stats.*attempt.refusal);
  if (pieces.empty()) pieces = split_members(mesh, topology, graph, chart_faces, members, attempt.culprit);
  std::vector<std::vector<FlatChart>> parts(pieces.size());
  std::vector<FlattenStats> part_stats(pieces.size());
  std::vector<std::exception_ptr> errors(pieces.size());
  for (size_t k = 0; k < pieces.size(); ++k) {
#pragma omp task default(shared) firstprivate(k)
    try {
      parts[k] = flatten_without_overlap(mesh, topology, graph, chart_faces, pieces[k], merges, options, control,
                                         part_stats[k]);
    } catch (...) {
      errors[k] = std::current_exception();
    }
  }
#pragma omp taskwait
  for (const std::exception_ptr& error : errors)
    if (error) std::rethrow_exception(error);
  for (size_t k = 0; k < pieces.size(); ++k) {
    stats += part_stats[k];
    for (FlatChart& chart : parts[k]) done.push_back(std::move(chart));
  }
  return done;
}

}  // namespace atlas
