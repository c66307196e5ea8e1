#include "charts/disk_merge.hpp"

#include <algorithm>
#include <numeric>
#include <unordered_map>

#include "core/corners.hpp"
#include "core/union_find.hpp"

namespace atlas {
namespace {

constexpr double kMinWeldedShare = 0.25;
// A merge whose smaller chart has at most this many faces may weld any of
// the arcs tried: a slit left inside a chart costs flattening time and splits
// in proportion to the chart, and small charts are what is left unmerged.
constexpr size_t kAnyArcFaces = 200;

// Sorted by hole, one entry per hole: the edges summed, counted if either was.
void sum_by_hole(std::vector<HeldHole>& held) {
  std::sort(held.begin(), held.end(), [](const HeldHole& x, const HeldHole& y) { return x.hole < y.hole; });
  size_t kept = 0;
  for (size_t i = 0; i < held.size(); ++i)
    if (kept > 0 && held[kept - 1].hole == held[i].hole) {
      held[kept - 1].edges += held[i].edges;
      held[kept - 1].counted = held[kept - 1].counted || held[i].counted;
    } else {
      held[kept++] = held[i];
    }
  held.resize(kept);
}

MergeCheck refused(MergeRefusal why) {
  MergeCheck out;
  out.refusal = why;
  return out;
}

// shared (n) edges and the shared edges at each of their vertices. When they
// form one closed loop (two charts that together close a surface, as the two
// halves of a small floating blob do), the loop's edges labelled 0 for the
// first half of its length, walking from shared[0], and 1 for the rest: two
// arcs, either of which welds into a disk. Empty otherwise.
std::vector<int> loop_halves(const MeshTopology& topology, const std::vector<int>& shared,
                             const std::unordered_map<int, std::vector<int>>& edges_at_vertex,
                             const std::vector<double>& edge_lengths) {
  const int n = static_cast<int>(shared.size());
  for (const auto& [vertex, edges] : edges_at_vertex)
    if (edges.size() != 2) return {};
  const double total = std::accumulate(edge_lengths.begin(), edge_lengths.end(), 0.0);
  std::vector<int> half(n, -1);
  double walked = 0;
  int edge = 0, vertex = topology.edge_vertices(shared[0], 1);
  for (int step = 0; step < n; ++step) {
    if (half[edge] >= 0) return {};  // back at the start before visiting every edge: several loops
    half[edge] = walked < 0.5 * total ? 0 : 1;
    walked += edge_lengths[edge];
    const std::vector<int>& at = edges_at_vertex.at(vertex);
    edge = at[0] == edge ? at[1] : at[0];
    vertex = topology.edge_vertices(shared[edge], 0) == vertex ? topology.edge_vertices(shared[edge], 1)
                                                               : topology.edge_vertices(shared[edge], 0);
  }
  return half;
}

}  // namespace

DiskClusters::DiskClusters(const Mesh& mesh, const MeshTopology& topology, std::vector<int> face_cluster,
                           int cluster_count, std::vector<char> self_seam, bool partial_merges, MeshHoles holes)
    : mesh_(mesh),
      topology_(topology),
      face_cluster_(std::move(face_cluster)),
      faces_(cluster_count),
      euler_(cluster_count, 0),
      manifold_(cluster_count, 0),
      seam_(std::move(self_seam)),
      partial_merges_(partial_merges),
      holes_(std::move(holes)),
      held_(cluster_count),
      edge_stamp_(topology.edge_count(), 0),
      vertex_stamp_(mesh.vertex_count(), 0) {
  for (int f = 0; f < mesh.face_count(); ++f)
    if (face_cluster_[f] >= 0) faces_[face_cluster_[f]].push_back(f);
  hole_vertices_.resize(holes_.edges.size());
  for (int e = 0; e < static_cast<int>(holes_.edge_hole.size()); ++e)
    if (const int h = holes_.edge_hole[e]; h >= 0)
      for (int end = 0; end < 2; ++end) hole_vertices_[h].push_back(topology.edge_vertices(e, end));
  for (std::vector<int>& vertices : hole_vertices_) {
    std::sort(vertices.begin(), vertices.end());
    vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  }
  for (int c = 0; c < cluster_count; ++c) {
    held_[c] = holes_held(c);
    euler_[c] = euler_of(c) + count_enclosed(held_[c], c, c);
    manifold_[c] = !faces_[c].empty() && manifold_inside(c);
  }
}

bool DiskClusters::encloses(int hole, int a, int b) const {
  for (int v : hole_vertices_[hole])
    if (fan_count(v, a, b) != 1) return false;
  return true;
}

std::vector<HeldHole> DiskClusters::holes_held(int c) const {
  std::vector<HeldHole> held;
  if (holes_.edge_hole.empty()) return held;
  for (int f : faces_[c])
    for (int k = 0; k < 3; ++k)
      if (const int h = holes_.edge_hole[topology_.corner_edge[3 * f + k]]; h >= 0) held.push_back({h, 1, false});
  sum_by_hole(held);
  return held;
}

int DiskClusters::count_enclosed(std::vector<HeldHole>& held, int a, int b) const {
  int counted = 0;
  for (HeldHole& h : held)
    if (!h.counted && h.edges == holes_.edges[h.hole] && encloses(h.hole, a, b)) h.counted = true, ++counted;
  return counted;
}

int DiskClusters::holes_closed(int a, int b) const {
  if (held_[a].empty() && held_[b].empty()) return 0;
  std::vector<HeldHole> both = held_[a];
  both.insert(both.end(), held_[b].begin(), held_[b].end());
  sum_by_hole(both);
  return count_enclosed(both, a, b);
}

// chi = V - E + F over the faces of cluster c, where a vertex whose faces in
// c form k separate fans counts k times: touching at a single vertex costs no
// seam, so such pinches are split rather than refused (see localize in
// flatten/flatten_without_overlap.cpp).
// A seam the cluster keeps counts as two edges, one per side.
int DiskClusters::euler_of(int c) {
  ++stamp_;
  int vertices = 0, edges = 0;
  for (int f : faces_[c])
    for (int k = 0; k < 3; ++k) {
      const int e = topology_.corner_edge[3 * f + k], v = mesh_.triangles(f, k);
      if (seam_[e]) ++edges;
      else if (edge_stamp_[e] != stamp_) edge_stamp_[e] = stamp_, ++edges;
      if (vertex_stamp_[v] != stamp_) vertex_stamp_[v] = stamp_, vertices += fan_count(v, c, c);
    }
  return vertices - edges + static_cast<int>(faces_[c].size());
}

// Inside one cluster every edge has at most two of its faces, consistently
// wound. With chi == 1 (pinches split) that makes a disk. Merges keep it:
// weld_all refuses non-manifold or flipped shared edges.
bool DiskClusters::manifold_inside(int c) {
  for (int f : faces_[c])
    for (int k = 0; k < 3; ++k) {
      const int c0 = 3 * f + k, e = topology_.corner_edge[c0];
      if (seam_[e]) continue;
      int inside = 0;
      for (int i = topology_.edge_offsets[e]; i < topology_.edge_offsets[e + 1]; ++i) {
        const int ci = topology_.edge_corners[i];
        if (face_cluster_[ci / 3] != c) continue;
        ++inside;
        if (ci != c0 && corner_vertex(mesh_.triangles, ci) == mesh_.triangles(f, k)) return false;
      }
      if (inside > 2 || (inside == 2 && topology_.edge_valence(e) != 2)) return false;
    }
  return true;
}

// Number of edge-connected fans that the faces of clusters a and b form around v.
int DiskClusters::fan_count(int v, int a, int b) const {
  const int begin = topology_.vertex_offsets[v], end = topology_.vertex_offsets[v + 1];
  std::vector<int>& local_parent = fan_parent_;
  std::vector<int>& local_face = fan_faces_;
  local_parent.clear(), local_face.clear();
  for (int i = begin; i < end; ++i) {
    const int f = topology_.vertex_corners[i] / 3;
    if (in(f, a, b)) local_face.push_back(f), local_parent.push_back(static_cast<int>(local_parent.size()));
  }
  auto find = [&](int x) {
    while (local_parent[x] != x) x = local_parent[x];
    return x;
  };
  auto index_of = [&](int f) {
    return static_cast<int>(std::find(local_face.begin(), local_face.end(), f) - local_face.begin());
  };
  int fans = static_cast<int>(local_face.size());
  for (int i = begin; i < end; ++i) {
    const int c = topology_.vertex_corners[i];
    if (!in(c / 3, a, b)) continue;
    for (int e : {topology_.corner_edge[c], topology_.corner_edge[previous_corner(c)]}) {
      if (!joins(e)) continue;
      for (int j = topology_.edge_offsets[e]; j < topology_.edge_offsets[e + 1]; ++j) {
        const int g = topology_.edge_corners[j] / 3;
        if (g == c / 3 || !in(g, a, b)) continue;
        const int ra = find(index_of(c / 3)), rb = find(index_of(g));
        if (ra != rb) local_parent[ra] = rb, --fans;
      }
    }
  }
  return fans;
}

bool DiskClusters::inside(int v, int a, int b) const {
  for (int i = topology_.vertex_offsets[v]; i < topology_.vertex_offsets[v + 1]; ++i) {
    const int c = topology_.vertex_corners[i];
    if (!in(c / 3, a, b) || !joins(topology_.corner_edge[c]) || !joins(topology_.corner_edge[previous_corner(c)]))
      return false;
  }
  return topology_.vertex_offsets[v + 1] > topology_.vertex_offsets[v];
}

int DiskClusters::cluster_inside(int v) const {
  if (topology_.vertex_offsets[v + 1] == topology_.vertex_offsets[v]) return -1;
  const int c = face_cluster_[topology_.vertex_corners[topology_.vertex_offsets[v]] / 3];
  return c >= 0 && inside(v, c, c) ? c : -1;
}

// A vertex that only the union holds inside has faces of both a and b,
// edge-connected around it, so it ends an edge they share: only those edges
// of the smaller cluster's faces are looked at.
double DiskClusters::sum_inside_union(int a, int b, const std::vector<double>& per_vertex) {
  if (faces_[a].size() > faces_[b].size()) std::swap(a, b);
  ++stamp_;
  double sum = 0;
  for (int f : faces_[a])
    for (int k = 0; k < 3; ++k) {
      const int e = topology_.corner_edge[3 * f + k];
      if (!joins(e)) continue;
      if (face_cluster_[face_across(topology_, e, f)] != b) continue;
      for (int v : {topology_.edge_vertices(e, 0), topology_.edge_vertices(e, 1)}) {
        if (vertex_stamp_[v] == stamp_) continue;
        vertex_stamp_[v] = stamp_;
        if (inside(v, a, b)) sum += per_vertex[v];
      }
    }
  return sum;
}

MergeCheck DiskClusters::check_merge(int a, int b) {
  if (a == b || !manifold_[a] || !manifold_[b]) return refused(MergeRefusal::NonManifold);
  std::vector<int> shared;
  MergeCheck full = weld_all(a, b, partial_merges_ ? &shared : nullptr);
  if (full.refusal != MergeRefusal::NotDisk || shared.size() < 2) return full;
  return weld_longest_arc(a, b, shared);
}

MergeCheck DiskClusters::weld_all(int a, int b, std::vector<int>* shared) {
  if (faces_[a].size() > faces_[b].size()) std::swap(a, b);
  ++stamp_;
  int shared_edges = 0, fans_joined = 0;
  for (int f : faces_[a])
    for (int k = 0; k < 3; ++k) {
      const int c = 3 * f + k, e = topology_.corner_edge[c], v = mesh_.triangles(f, k);
      if (edge_stamp_[e] != stamp_) {
        edge_stamp_[e] = stamp_;
        for (int i = topology_.edge_offsets[e]; i < topology_.edge_offsets[e + 1]; ++i) {
          const int ci = topology_.edge_corners[i];
          if (face_cluster_[ci / 3] != b) continue;
          // Never merge across a non-manifold edge or a winding flip.
          if (topology_.edge_valence(e) != 2 || corner_vertex(mesh_.triangles, ci) == v)
            return refused(MergeRefusal::NonManifold);
          if (seam_[e]) continue;
          ++shared_edges;
          if (shared) shared->push_back(e);
        }
      }
      if (vertex_stamp_[v] != stamp_) {
        vertex_stamp_[v] = stamp_;
        bool touches_b = false;
        for (int i = topology_.vertex_offsets[v]; i < topology_.vertex_offsets[v + 1]; ++i)
          touches_b = touches_b || face_cluster_[topology_.vertex_corners[i] / 3] == b;
        if (touches_b) fans_joined += fan_count(v, a, a) + fan_count(v, b, b) - fan_count(v, a, b);
      }
    }
  if (shared_edges == 0) return refused(MergeRefusal::NotDisk);
  // Inclusion-exclusion with pinches split: every shared edge joins two faces'
  // sides into one, every fan that merges with another removes a vertex.
  const int euler = euler_[a] + euler_[b] - fans_joined + shared_edges + holes_closed(a, b);
  // Accepted: a disk; a chart with holes (chi < 1) absorbing an island, which
  // fills a hole and raises chi; or a disk joining a chart with holes along
  // one arc, which leaves chi as it was: it adds no hole, and it may be one of
  // several islands that fill a hole together (touching at vertices), which
  // no single one of them closes. Anything else adds a hole or a handle, and
  // chi == 2 would close a sphere: no boundary left to flatten.
  const int worse = std::min(euler_[a], euler_[b]);
  const bool with_disk = euler_[a] == 1 || euler_[b] == 1;
  if (euler == 1 || (euler < 1 && (euler > worse || (with_disk && euler == worse)))) {
    MergeCheck out;
    out.euler = euler;
    return out;
  }
  return refused(MergeRefusal::NotDisk);
}

// Arcs: maximal simple paths of shared edges (a closed loop counts as its two
// halves). All arcs but one are marked
// seams for the time of one weld_all, which says whether the union is then
// acceptable (two disks sharing k arcs make chi = 2 - k when all are welded,
// and a disk when one is). The longest arcs are tried first, a few of them,
// and, unless one chart is small (kAnyArcFaces), only arcs with at least
// kMinWeldedShare of the shared length: a union
// that keeps most of its border with the other chart as a slit inside costs
// more to flatten (and splits more often) than it saves.
MergeCheck DiskClusters::weld_longest_arc(int a, int b, const std::vector<int>& shared) {
  const int n = static_cast<int>(shared.size());
  // Arcs are simple paths: two edges join at a vertex only when no other
  // shared edge meets there (where two arcs touch at a vertex, they stay two).
  std::unordered_map<int, std::vector<int>> edges_at_vertex;
  for (int i = 0; i < n; ++i)
    for (int end = 0; end < 2; ++end) edges_at_vertex[topology_.edge_vertices(shared[i], end)].push_back(i);
  // Nor at a vertex where either chart touches itself: welded through it, the
  // arc would close a ring round that vertex, leaving a hole.
  UnionFind arcs(n);
  int joins = 0;
  for (const auto& [vertex, edges] : edges_at_vertex)
    if (edges.size() == 2 && fan_count(vertex, a, a) == 1 && fan_count(vertex, b, b) == 1)
      arcs.unite(edges[0], edges[1]), ++joins;
  std::vector<double> edge_lengths(n);
  for (int i = 0; i < n; ++i) edge_lengths[i] = edge_length(mesh_, topology_, shared[i]);
  std::vector<int> arc = arcs.dense_labels();
  if (*std::max_element(arc.begin(), arc.end()) == 0) {
    // One arc: a closed loop joined at every vertex can be halved; an arc
    // whose ends meet at a vertex where a chart touches itself cannot.
    if (joins != n) return refused(MergeRefusal::NotDisk);
    arc = loop_halves(topology_, shared, edges_at_vertex, edge_lengths);
    if (arc.empty()) return refused(MergeRefusal::NotDisk);
  }
  const int arc_count = *std::max_element(arc.begin(), arc.end()) + 1;
  std::vector<double> length(arc_count, 0.0);
  for (int i = 0; i < n; ++i) length[arc[i]] += edge_lengths[i];
  const double shared_length = std::accumulate(edge_lengths.begin(), edge_lengths.end(), 0.0);
  std::vector<int> order(arc_count);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int x, int y) { return length[x] > length[y]; });
  constexpr int kArcsTried = 3;
  const bool small = std::min(faces_[a].size(), faces_[b].size()) <= kAnyArcFaces;
  for (int t = 0; t < std::min(arc_count, kArcsTried); ++t) {
    if (!small && length[order[t]] < kMinWeldedShare * shared_length) break;
    MergeCheck out;
    for (int i = 0; i < n; ++i)
      if (arc[i] != order[t]) out.left_open.push_back(shared[i]), out.open_length += edge_lengths[i];
    for (int e : out.left_open) seam_[e] = 1;
    const MergeCheck welded = weld_all(a, b, nullptr);
    for (int e : out.left_open) seam_[e] = 0;
    if (welded) {
      out.euler = welded.euler;
      return out;
    }
  }
  return refused(MergeRefusal::NotDisk);
}

// chi of cluster c restricted to what face f can change: the fans of c at
// f's vertices minus the edges of f that c uses (a seam once per side).
int DiskClusters::local_euler(int f, int c) const {
  int count = 0;
  for (int k = 0; k < 3; ++k) {
    count += fan_count(mesh_.triangles(f, k), c, c);
    const int e = topology_.corner_edge[3 * f + k];
    int uses = 0;
    for (int i = topology_.edge_offsets[e]; i < topology_.edge_offsets[e + 1]; ++i)
      uses += face_cluster_[topology_.edge_corners[i] / 3] == c;
    count -= seam_[e] ? uses : std::min(uses, 1);
  }
  return count;
}

bool DiskClusters::move_keeps_topology(int f, int to) {
  const int from = face_cluster_[f];
  if (from < 0 || to < 0 || from == to || faces_[from].size() < 2 || !manifold_[from] || !manifold_[to]) return false;
  int inside = 0, joined = 0;
  for (int k = 0; k < 3; ++k) {
    const int c = 3 * f + k, e = topology_.corner_edge[c];
    if (seam_[e] || topology_.edge_valence(e) > 2) return false;
    for (int i = topology_.edge_offsets[e]; i < topology_.edge_offsets[e + 1]; ++i) {
      const int ci = topology_.edge_corners[i];
      if (ci == c) continue;
      if (corner_vertex(mesh_.triangles, ci) == mesh_.triangles(f, k)) return false;  // winding flip
      inside += face_cluster_[ci / 3] == from;
      joined += face_cluster_[ci / 3] == to;
    }
  }
  if (inside != 1 || joined == 0) return false;
  int fans_before[2][3], fans_after[2][3];
  for (int k = 0; k < 3; ++k)
    fans_before[0][k] = fan_count(mesh_.triangles(f, k), from, from), fans_before[1][k] = fan_count(mesh_.triangles(f, k), to, to);
  const int from_before = local_euler(f, from), to_before = local_euler(f, to);
  face_cluster_[f] = to;
  for (int k = 0; k < 3; ++k)
    fans_after[0][k] = fan_count(mesh_.triangles(f, k), from, from), fans_after[1][k] = fan_count(mesh_.triangles(f, k), to, to);
  const int from_after = local_euler(f, from), to_after = local_euler(f, to);
  face_cluster_[f] = from;
  // No new pinch: a chart that touches itself at a vertex is a disk once the
  // vertex is split, but one that closes a ring round a hole that way
  // flattens like an annulus, squeezing the inner side.
  for (int c = 0; c < 2; ++c)
    for (int k = 0; k < 3; ++k)
      if (fans_after[c][k] > std::max(1, fans_before[c][k])) return false;
  // chi = V - E + F: the face itself leaves one cluster and joins the other.
  return from_after - 1 == from_before && to_after + 1 == to_before;
}

void DiskClusters::move(int f, int to) {
  std::vector<int>& from = faces_[face_cluster_[f]];
  *std::find(from.begin(), from.end(), f) = from.back();
  from.pop_back();
  faces_[to].push_back(f);
  face_cluster_[f] = to;
}

int DiskClusters::merge(int a, int b, const MergeCheck& check) {
  for (int e : check.left_open) seam_[e] = 1;
  if (faces_[a].size() > faces_[b].size()) std::swap(a, b);
  for (int f : faces_[a]) face_cluster_[f] = b;
  faces_[b].insert(faces_[b].end(), faces_[a].begin(), faces_[a].end());
  faces_[a].clear();
  faces_[a].shrink_to_fit();
  euler_[b] = check.euler;
  manifold_[a] = 0;
  held_[b].insert(held_[b].end(), held_[a].begin(), held_[a].end());
  sum_by_hole(held_[b]);
  count_enclosed(held_[b], b, b);  // as holes_closed counted them in check.euler
  held_[a].clear();
  return b;
}

}  // namespace atlas

