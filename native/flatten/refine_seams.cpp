#include "flatten/refine_seams.hpp"

#include <algorithm>
#include <cmath>
#include <queue>
#include <unordered_map>

#include "charts/disk_merge.hpp"
#include "core/geometry.hpp"
#include "core/plane_predicates.hpp"
#include "flatten/chart_rows.hpp"

namespace atlas {
namespace {

using Point = Eigen::Vector2d;

// Corner k of face f starts the edge triangles(f,k) -> triangles(f,(k+1)%3).
struct Corner {
  int face, k;
};

// A candidate move of face f into chart `to`: its edges k1 and k2 face the
// chart, across them lie faces g1 and g2, edge k3 faces its own chart.
struct Move {
  int face = -1, to = -1, k1 = -1, k2 = -1, k3 = -1, g1 = -1, g2 = -1;
  double gain = 0;
  Point uv[3] = {Point::Zero(), Point::Zero(), Point::Zero()};  // new corner UVs, texels of the chart `to`
};

std::vector<int> chart_labels(int face_count, const std::vector<FlatChart>& charts) {
  std::vector<int> label(face_count, -1);
  for (size_t c = 0; c < charts.size(); ++c)
    for (int f : charts[c].faces) label[f] = static_cast<int>(c);
  return label;
}

class Refiner {
 public:
  Refiner(const RefineInput& in, std::vector<FlatChart>& charts)
      : in_(in),
        charts_(charts),
        disks_(in.mesh, in.topology, chart_labels(in.mesh.face_count(), charts), static_cast<int>(charts.size()),
               in.seam),
        slot_(in.mesh.face_count(), -1),
        boundary_(charts.size()) {
    for (const FlatChart& chart : charts)
      for (size_t j = 0; j < chart.faces.size(); ++j) slot_[chart.faces[j]] = static_cast<int>(j);
    for (size_t c = 0; c < charts.size(); ++c)
      for (int f : charts[c].faces)
        for (int k = 0; k < 3; ++k)
          if (is_boundary(f, k)) boundary_[c].push_back({f, k});
  }

  RefineStats run() {
    std::queue<int> pending;
    for (int f = 0; f < in_.mesh.face_count(); ++f)
      if (disks_.cluster_of(f) >= 0) pending.push(f);
    for (; !pending.empty(); pending.pop()) {
      Move m;
      if (!find_move(pending.front(), m)) continue;
      apply(m);
      ++stats_.faces_moved;
      stats_.seam_removed_3d += m.gain;
      // The face behind it may now be a tooth of the same border.
      const int behind = across(m.face, m.k3);
      if (behind >= 0) pending.push(behind);
    }
    return stats_;
  }

 private:
  int chart(int f) const { return disks_.cluster_of(f); }
  int edge(int f, int k) const { return in_.topology.corner_edge[3 * f + k]; }
  int vertex(int f, int k) const { return in_.mesh.triangles(f, k); }
  int across(int f, int k) const {
    const int e = edge(f, k);
    return in_.topology.edge_valence(e) == 2 ? face_across(in_.topology, e, f) : -1;
  }
  double length(int f, int k) const { return edge_length(in_.mesh, in_.topology, edge(f, k)); }
  // UV of mesh vertex v (a corner of f) in f's chart.
  Point uv(int f, int v) const {
    return charts_[chart(f)].corner_uv.row(3 * slot_[f] + in_.mesh.corner_of(f, v)).transpose();
  }
  // Edge k of f is on its chart's boundary in UV: a mesh border, a seam, a
  // neighbour in another chart or one that puts the edge elsewhere.
  bool is_boundary(int f, int k) const {
    const int g = across(f, k);
    if (g < 0 || in_.seam[edge(f, k)] || chart(g) != chart(f)) return true;
    const int a = vertex(f, k), b = vertex(f, (k + 1) % 3);
    return uv(f, a) != uv(g, a) || uv(f, b) != uv(g, b);
  }

  bool find_move(int f, Move& m) const {
    const int from = chart(f);
    if (from < 0) return false;
    for (int k3 = 0; k3 < 3; ++k3) {
      const int k1 = (k3 + 1) % 3, k2 = (k3 + 2) % 3;
      const int g1 = across(f, k1), g2 = across(f, k2);
      if (g1 < 0 || g2 < 0 || g1 == g2 || chart(g1) != chart(g2) || chart(g1) == from || chart(g1) < 0) continue;
      if (!in_.face_group.empty() && in_.face_group[g1] != in_.face_group[f]) continue;
      if (!in_.polygons.move_keeps_whole({f}, [&](int g) { return chart(g); })) continue;
      m = {f, chart(g1), k1, k2, k3, g1, g2, 0, {Point::Zero(), Point::Zero(), Point::Zero()}};
      if (place(m) && fits(m) && disks_.move_keeps_topology(f, m.to)) return true;
    }
    return false;
  }

  // The new corner UVs from the two neighbours, which must agree at the
  // shared vertex; the seam removed; orientation and texel area.
  bool place(Move& m) const {
    const int f = m.face, apex = vertex(f, m.k2);  // edge k1 ends and edge k2 starts at the apex
    if (uv(m.g1, apex) != uv(m.g2, apex)) return false;
    m.uv[m.k1] = uv(m.g1, vertex(f, m.k1));
    m.uv[m.k2] = uv(m.g1, apex);
    m.uv[m.k3] = uv(m.g2, vertex(f, m.k3));
    const bool k3_was_seam = is_boundary(f, m.k3);
    m.gain = length(f, m.k1) + length(f, m.k2) - (k3_was_seam ? 0.0 : length(f, m.k3));
    if (!(m.gain > 1e-9 * (length(f, m.k1) + length(f, m.k2)))) return false;
    const int g1 = m.g1;
    const double chart_winding = signed_area(uv(g1, vertex(g1, 0)), uv(g1, vertex(g1, 1)), uv(g1, vertex(g1, 2)));
    const double area = signed_area(m.uv[0], m.uv[1], m.uv[2]);
    return area * chart_winding > 0 && std::abs(area) >= in_.needed_area(f);
  }

  // The face lies outside the chart next to the two boundary edges it
  // fills; it overlaps the chart only if some boundary edge reaches into it,
  // through its new boundary edge or from one of its corners.
  bool fits(const Move& m) const {
    const Point& a = m.uv[m.k3];  // the new boundary edge runs between a and b
    const Point& b = m.uv[m.k1];
    const Point& apex = m.uv[m.k2];
    for (const Corner& s : boundary_[m.to]) {
      const int e = edge(s.face, s.k);
      if (e == edge(m.face, m.k1) || e == edge(m.face, m.k2)) continue;  // the two edges the face fills
      const Point p = uv(s.face, vertex(s.face, s.k)), q = uv(s.face, vertex(s.face, (s.k + 1) % 3));
      const bool at_a = p == a || q == a, at_b = p == b || q == b;
      if (at_a || at_b) {
        const Point& far = (p == a || p == b) ? q : p;
        if (far != a && far != b && in_or_on_triangle(a, b, apex, far)) return false;
        if (at_a && at_b) return false;  // the chart already has an edge a-b: the face would close a hole
        continue;
      }
      if (segments_touch(a, b, p, q) || in_or_on_triangle(a, b, apex, p)) return false;
    }
    return true;
  }

  void remove_boundary(int c, int f, int k) {
    auto& list = boundary_[c];
    for (size_t i = 0; i < list.size(); ++i)
      if (list[i].face == f && (k < 0 || list[i].k == k)) list[i] = list.back(), list.pop_back(), --i;
  }

  void apply(const Move& m) {
    const int f = m.face, from = chart(f);
    const int behind = across(f, m.k3);
    const bool behind_joined = behind >= 0 && chart(behind) == from && !is_boundary(f, m.k3);
    remove_boundary(from, f, -1);
    remove_boundary(m.to, m.g1, corner_on(m.g1, edge(f, m.k1)));
    remove_boundary(m.to, m.g2, corner_on(m.g2, edge(f, m.k2)));
    take_out_face(charts_[from], f, slot_);
    RowMatrixX2d uv(3, 2);
    for (int k = 0; k < 3; ++k) uv.row(k) = m.uv[k].transpose();
    append_faces(charts_[m.to], {f}, uv, slot_);
    disks_.move(f, m.to);
    boundary_[m.to].push_back({f, m.k3});
    if (behind_joined) boundary_[from].push_back({behind, corner_on(behind, edge(f, m.k3))});
  }

  // The corner of face g that starts edge e.
  int corner_on(int g, int e) const {
    for (int k = 0; k < 3; ++k)
      if (edge(g, k) == e) return k;
    return -1;
  }

  const RefineInput in_;
  std::vector<FlatChart>& charts_;
  mutable DiskClusters disks_;  // its move check marks faces for a moment
  std::vector<int> slot_;  // row of each face in its chart
  std::vector<std::vector<Corner>> boundary_;  // per chart, its boundary edges in UV
  RefineStats stats_;
};

}  // namespace

Polygons::Polygons(const std::vector<int>& face_polygon) {
  if (face_polygon.empty()) return;
  std::unordered_map<int, int> number;
  polygon_.reserve(face_polygon.size());
  for (int id : face_polygon) polygon_.push_back(number.emplace(id, static_cast<int>(number.size())).first->second);
  start_.assign(number.size() + 1, 0);
  for (int p : polygon_) ++start_[p + 1];
  for (size_t p = 0; p + 1 < start_.size(); ++p) start_[p + 1] += start_[p];
  members_.resize(polygon_.size());
  std::vector<int> next(start_.begin(), start_.end() - 1);
  for (size_t f = 0; f < polygon_.size(); ++f) members_[next[polygon_[f]]++] = static_cast<int>(f);
}

RefineStats refine_seams(const RefineInput& input, std::vector<FlatChart>& charts) {
  if (input.options.min_area_ratio <= 0) return {};
  return Refiner(input, charts).run();
}

}  // namespace atlas
