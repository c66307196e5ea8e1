#include "flatten/straighten_borders.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <map>
#include <set>
#include <utility>

#include <Eigen/SparseCholesky>

#include "core/geometry.hpp"
#include "core/min_cut.hpp"
#include "core/plane_predicates.hpp"
#include "flatten/chart_rows.hpp"

namespace atlas {
namespace {

using Point = Eigen::Vector2d;

// Rings of faces on either side of a border the cut may relabel: wider
// bands make wider strips, which the receiver takes less often
// (bench/README.md).
constexpr int kBandRings = 1;
// Enough for a strip a ring or two deep to settle between its shared vertices.
constexpr int kArapIterations = 10;

// A strip of faces leaving chart `from` for chart `to`, with its new corner UVs.
struct Strip {
  std::vector<int> faces;
  int from = -1, to = -1;
  std::vector<Point> uv;  // 3 per face, texels of `to`
  double gain = 0;        // 3D seam length removed
};

class Straightener {
 public:
  Straightener(const RefineInput& in, std::vector<FlatChart>& charts)
      : in_(in), charts_(charts), least_gain_(1e-9 * in.mesh.positions.cwiseAbs().maxCoeff()),
        label_(in.mesh.face_count(), -1), slot_(in.mesh.face_count(), -1), mark_(in.mesh.face_count(), 0),
        node_(in.mesh.face_count(), -1), triangles_(charts.size()) {
    for (size_t c = 0; c < charts.size(); ++c)
      for (size_t j = 0; j < charts[c].faces.size(); ++j) {
        label_[charts[c].faces[j]] = static_cast<int>(c);
        slot_[charts[c].faces[j]] = static_cast<int>(j);
      }
  }

  RefineStats run() {
    for (const auto& [a, b] : adjacent_pairs()) straighten(a, b);
    return stats_;
  }

 private:
  int edge(int f, int k) const { return in_.topology.corner_edge[3 * f + k]; }
  int vertex(int f, int k) const { return in_.mesh.triangles(f, k); }
  double length(int f, int k) const { return edge_length(in_.mesh, in_.topology, edge(f, k)); }
  // The face across edge k of f, if the edge is manifold and no kept seam.
  int across(int f, int k) const {
    const int e = edge(f, k);
    return in_.topology.edge_valence(e) == 2 && !in_.seam[e] ? face_across(in_.topology, e, f) : -1;
  }
  Point uv(int f, int v) const {
    return charts_[label_[f]].corner_uv.row(3 * slot_[f] + in_.mesh.corner_of(f, v)).transpose();
  }
  bool solved(int c) const { return c >= 0 && !charts_[c].kept_original && !charts_[c].faces.empty(); }
  int group(int f) const { return in_.face_group.empty() ? 0 : in_.face_group[f]; }
  bool touches_seam(int f) const {
    for (int k = 0; k < 3; ++k)
      if (in_.seam[edge(f, k)]) return true;
    return false;
  }
  // Sign of chart c's winding in UV: that of its first face with area (a
  // face of none, which a flattening may leave, has no sign).
  double winding(int c) const {
    for (int f : charts_[c].faces) {
      const double area = signed_area(uv(f, vertex(f, 0)), uv(f, vertex(f, 1)), uv(f, vertex(f, 2)));
      if (area != 0) return area > 0 ? 1.0 : -1.0;
    }
    return 1.0;
  }

  // Solved charts of one face group that share an edge, longest border first.
  std::vector<std::pair<int, int>> adjacent_pairs() const {
    std::map<std::pair<int, int>, double> border;
    for (int f = 0; f < in_.mesh.face_count(); ++f)
      for (int k = 0; k < 3; ++k) {
        const int g = across(f, k);
        if (g > f && label_[g] != label_[f] && solved(label_[f]) && solved(label_[g]) && group(f) == group(g))
          border[std::minmax(label_[f], label_[g])] += length(f, k);
      }
    std::vector<std::pair<double, std::pair<int, int>>> order;
    for (const auto& [pair, l] : border) order.push_back({l, pair});
    std::sort(order.rbegin(), order.rend());
    std::vector<std::pair<int, int>> pairs;
    for (const auto& [l, pair] : order) pairs.push_back(pair);
    return pairs;
  }

  // Faces of a or b within kBandRings rings of their border, off kept seams.
  std::vector<int> band(int a, int b) const {
    auto in_pair = [&](int g) { return g >= 0 && (label_[g] == a || label_[g] == b); };
    std::vector<int> ring, out, seen;
    for (int f : charts_[a].faces)
      for (int k = 0; k < 3; ++k) {
        const int g = across(f, k);
        if (g < 0 || label_[g] != b) continue;
        for (int h : {f, g})
          if (!mark_[h]) mark_[h] = 1, ring.push_back(h), seen.push_back(h);
      }
    for (int r = 0; r <= kBandRings && !ring.empty(); ++r) {
      std::vector<int> next;
      for (int f : ring) {
        if (!touches_seam(f)) out.push_back(f);
        for (int k = 0; r < kBandRings && k < 3; ++k) {
          const int g = across(f, k);
          if (in_pair(g) && !mark_[g]) mark_[g] = 1, next.push_back(g), seen.push_back(g);
        }
      }
      ring.swap(next);
    }
    for (int f : seen) mark_[f] = 0;
    return out;
  }

  // The band's faces that the minimum cut puts on the other side.
  std::vector<int> cut_moves(int a, int b, const std::vector<int>& faces) const {
    const int n = static_cast<int>(faces.size()), source = n, sink = n + 1;
    for (int i = 0; i < n; ++i) node_[faces[i]] = i;
    std::vector<CutEdge> edges;
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        const int g = across(faces[i], k);
        if (g < 0 || (label_[g] != a && label_[g] != b)) continue;
        if (node_[g] < 0) edges.push_back({i, label_[g] == a ? source : sink, length(faces[i], k)});
        else if (node_[g] > i) edges.push_back({i, node_[g], length(faces[i], k)});
      }
    for (int f : faces) node_[f] = -1;
    const std::vector<char> side = min_cut_source_side(n + 2, edges, source, sink);
    std::vector<int> moves;
    for (int i = 0; i < n; ++i)
      if ((label_[faces[i]] == a) != static_cast<bool>(side[i])) moves.push_back(faces[i]);
    return moves;
  }

  void straighten(int a, int b) {
    const std::vector<int> moves = cut_moves(a, b, band(a, b));
    for (const std::vector<int>& faces : strips(moves)) {
      Strip strip{faces, label_[faces.front()], label_[faces.front()] == a ? b : a, {}, 0};
      if (place(strip) && fits(strip)) apply(strip);
    }
  }

  // The moves split into strips: edge-connected runs leaving the same chart.
  std::vector<std::vector<int>> strips(const std::vector<int>& moves) const {
    std::set<int> left(moves.begin(), moves.end());
    std::vector<std::vector<int>> out;
    while (!left.empty()) {
      std::vector<int> strip{*left.begin()};
      left.erase(left.begin());
      for (size_t i = 0; i < strip.size(); ++i)
        for (int k = 0; k < 3; ++k) {
          const int g = across(strip[i], k);
          if (g >= 0 && label_[g] == label_[strip[i]] && left.erase(g)) strip.push_back(g);
        }
      out.push_back(std::move(strip));
    }
    return out;
  }

  // New UVs: the receiver's at vertices it shares with the strip across an
  // edge; elsewhere each face unfolded, in the giver's shape, across an edge
  // already placed (the faces nearest the receiver first); and the seam the
  // move removes.
  bool place(Strip& s) const {
    std::map<int, Point> placed, old_uv;
    for (int f : s.faces)
      for (int k = 0; k < 3; ++k) {
        const int v = vertex(f, k);
        if (!old_uv.emplace(v, uv(f, v)).second && old_uv[v] != uv(f, v)) return false;
        const int g = across(f, k);
        if (g < 0 || label_[g] != s.to) continue;
        for (int w : {v, vertex(f, (k + 1) % 3)}) {
          const auto [it, added] = placed.emplace(w, uv(g, w));
          if (!added && it->second != uv(g, w)) return false;
        }
      }
    const std::set<int> shared = keys(placed);
    if (!unfold(s, old_uv, placed)) return false;
    relax(s, old_uv, shared, placed);
    const std::set<int> moving(s.faces.begin(), s.faces.end());
    for (int f : s.faces)
      for (int k = 0; k < 3; ++k) {
        s.uv.push_back(placed.at(vertex(f, k)));
        const int g = across(f, k);
        if (g < 0 || (moving.count(g) && g < f)) continue;
        const int after = moving.count(g) ? s.to : label_[g];
        s.gain += (label_[g] != label_[f] ? length(f, k) : 0.0) - (after != s.to ? length(f, k) : 0.0);
      }
    return s.gain > least_gain_;
  }

  static std::set<int> keys(const std::map<int, Point>& m) {
    std::set<int> out;
    for (const auto& [k, v] : m) out.insert(k);
    return out;
  }

  // The strip's faces as an ARAP problem: the giver triangles (mirrored when
  // the charts wind oppositely), per face and corner k half the cotangent at
  // k (the weight of the opposite edge, obtuse ones clamped to 0), and the
  // free vertices (all but the shared ones) numbered.
  struct Arap {
    std::map<int, Point> shape;
    std::vector<std::array<double, 3>> weight;
    std::map<int, int> index;
  };

  Arap arap_problem(const Strip& s, const std::map<int, Point>& old_uv, const std::set<int>& shared,
                    const std::map<int, Point>& placed) const {
    const double mirror = winding(s.from) * winding(s.to);
    Arap arap;
    for (const auto& [v, p] : old_uv) arap.shape[v] = Point(p.x(), mirror * p.y());
    for (const auto& [v, p] : placed)
      if (!shared.count(v)) arap.index.emplace(v, static_cast<int>(arap.index.size()));
    arap.weight.resize(s.faces.size());
    for (size_t i = 0; i < s.faces.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const int f = s.faces[i];
        const Point a = arap.shape[vertex(f, k)];
        const Point u = arap.shape[vertex(f, (k + 1) % 3)] - a, w = arap.shape[vertex(f, (k + 2) % 3)] - a;
        const double twice_area = std::abs(u.x() * w.y() - u.y() * w.x());
        arap.weight[i][k] = twice_area > 0 ? std::max(0.0, 0.5 * u.dot(w) / twice_area) : 0.0;
      }
    return arap;
  }

  // Calls visit(free index of x, x, y, weight) for each directed edge x -> y
  // of the strip's faces whose start is free.
  template <class Visit>
  void for_each_free_edge(const Strip& s, const Arap& arap, Visit visit) const {
    for (size_t i = 0; i < s.faces.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const int p = vertex(s.faces[i], (k + 1) % 3), q = vertex(s.faces[i], (k + 2) % 3);
        for (const auto& [x, y] : {std::pair{p, q}, std::pair{q, p}})
          if (const auto it = arap.index.find(x); it != arap.index.end()) visit(i, it->second, x, y, arap.weight[i][k]);
      }
  }

  // The rotation taking face f's giver shape closest to where it is placed,
  // over its three edges weighted as in the ARAP energy.
  Eigen::Matrix2d best_rotation(int f, const std::array<double, 3>& weight, const Arap& arap,
                                std::map<int, Point>& placed) const {
    Eigen::Matrix2d t = Eigen::Matrix2d::Zero();
    for (int k = 0; k < 3; ++k) {
      const int p = vertex(f, (k + 1) % 3), q = vertex(f, (k + 2) % 3);
      t += weight[k] * (placed[p] - placed[q]) * (arap.shape.at(p) - arap.shape.at(q)).transpose();
    }
    return Eigen::Rotation2Dd(std::atan2(t(1, 0) - t(0, 1), t(0, 0) + t(1, 1))).toRotationMatrix();
  }

  // Ten as-rigid-as-possible iterations (Sorkine and Alexa 2007) on the
  // strip's free vertices, the shared ones fixed.
  void relax(const Strip& s, const std::map<int, Point>& old_uv, const std::set<int>& shared,
             std::map<int, Point>& placed) const {
    const Arap arap = arap_problem(s, old_uv, shared, placed);
    const int n = static_cast<int>(arap.index.size());
    if (n == 0) return;
    std::vector<Eigen::Triplet<double>> entries;
    for_each_free_edge(s, arap, [&](size_t, int row, int, int y, double w) {
      entries.emplace_back(row, row, w);
      if (const auto it = arap.index.find(y); it != arap.index.end()) entries.emplace_back(row, it->second, -w);
    });
    Eigen::SparseMatrix<double> laplacian(n, n);
    laplacian.setFromTriplets(entries.begin(), entries.end());
    for (int d = 0; d < n; ++d) laplacian.coeffRef(d, d) += 1e-12;  // a vertex on obtuse corners only
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(laplacian);
    if (solver.info() != Eigen::Success) return;
    for (int iteration = 0; iteration < kArapIterations; ++iteration) {
      std::vector<Eigen::Matrix2d> turn(s.faces.size());
      for (size_t i = 0; i < s.faces.size(); ++i) turn[i] = best_rotation(s.faces[i], arap.weight[i], arap, placed);
      Eigen::MatrixX2d rhs = Eigen::MatrixX2d::Zero(n, 2);
      for_each_free_edge(s, arap, [&](size_t i, int row, int x, int y, double w) {
        Point b = w * (turn[i] * (arap.shape.at(x) - arap.shape.at(y)));
        if (!arap.index.count(y)) b += w * placed[y];
        rhs.row(row) += b.transpose();
      });
      const Eigen::MatrixX2d x = solver.solve(rhs);
      if (!x.allFinite()) return;
      for (const auto& [v, i] : arap.index) placed[v] = x.row(i).transpose();
    }
  }

  // Places every vertex of the strip: a face with two corners placed gets its
  // third where the similarity taking its giver triangle's two onto them
  // puts it (mirrored when the charts wind oppositely). False when some face
  // never has two corners placed.
  bool unfold(const Strip& s, const std::map<int, Point>& old_uv, std::map<int, Point>& placed) const {
    const double mirror = winding(s.from) * winding(s.to);
    auto giver = [&](int v) { return std::complex<double>(old_uv.at(v).x(), mirror * old_uv.at(v).y()); };
    std::vector<char> done(s.faces.size(), 0);
    for (bool progress = true; progress;) {
      progress = false;
      for (size_t i = 0; i < s.faces.size(); ++i) {
        if (done[i]) continue;
        const int f = s.faces[i];
        int missing = -1, count = 0;
        for (int k = 0; k < 3; ++k)
          if (placed.count(vertex(f, k))) ++count;
          else missing = k;
        if (count < 2) continue;
        done[i] = 1, progress = true;
        if (count == 3) continue;
        const int p = vertex(f, (missing + 1) % 3), q = vertex(f, (missing + 2) % 3), r = vertex(f, missing);
        const std::complex<double> from_p = giver(p), from_q = giver(q);
        if (from_q == from_p) return false;
        const std::complex<double> at_p(placed[p].x(), placed[p].y()), at_q(placed[q].x(), placed[q].y());
        const std::complex<double> at_r = at_p + (at_q - at_p) * ((giver(r) - from_p) / (from_q - from_p));
        placed[r] = Point(at_r.real(), at_r.imag());
      }
    }
    return std::all_of(done.begin(), done.end(), [](char d) { return d != 0; });
  }

  // Windings, texel areas, the receiver's boundary and the giver's connectivity.
  bool fits(const Strip& s) const {
    if (!in_.polygons.move_keeps_whole(s.faces, [&](int g) { return label_[g]; })) return false;
    const double w = winding(s.to);
    for (size_t i = 0; i < s.faces.size(); ++i) {
      const double area = signed_area(s.uv[3 * i], s.uv[3 * i + 1], s.uv[3 * i + 2]);
      if (!(area * w > 0) || std::abs(area) < in_.needed_area(s.faces[i])) return false;
    }
    return giver_stays_connected(s) && !overlaps_receiver(s);
  }

  // Every part the strip would cut off the giver touches the strip, so the
  // giver stays as connected as it was when the faces next to the strip
  // still reach each other; the search stops once they all do.
  bool giver_stays_connected(const Strip& s) const {
    if (charts_[s.from].faces.size() == s.faces.size()) return false;
    for (int f : s.faces) mark_[f] = 1;
    std::vector<int> next_to;  // giver faces next to the strip, marked 2
    for (int f : s.faces)
      for (int k = 0; k < 3; ++k) {
        const int g = across(f, k);
        if (g >= 0 && label_[g] == s.from && !mark_[g]) mark_[g] = 2, next_to.push_back(g);
      }
    size_t found = next_to.empty() ? 0 : 1;
    std::vector<int> reached;
    if (!next_to.empty()) reached.push_back(next_to.front()), mark_[next_to.front()] = 3;
    for (size_t i = 0; i < reached.size() && found < next_to.size(); ++i)
      for (int k = 0; k < 3; ++k) {
        const int g = across(reached[i], k);
        if (g < 0 || label_[g] != s.from || mark_[g] == 1 || mark_[g] == 3) continue;
        found += mark_[g] == 2;
        mark_[g] = 3, reached.push_back(g);
      }
    for (int f : s.faces) mark_[f] = 0;
    for (int f : next_to) mark_[f] = 0;
    for (int f : reached) mark_[f] = 0;
    return found == next_to.size();
  }

  // A UV triangle with its mesh vertices, to tell shared corners apart.
  struct Triangle {
    int vertex[3];
    Point corner[3];
  };

  // Two triangles overlap: an edge crosses or touches one of the other's
  // (unless they share an end), or a corner the other does not share lies
  // in it or on its border.
  static bool overlap(const Triangle& a, const Triangle& b) {
    auto shared = [](const Triangle& t, int v, const Point& p) {
      for (int k = 0; k < 3; ++k)
        if (t.vertex[k] == v && t.corner[k] == p) return true;
      return false;
    };
    for (int i = 0; i < 3; ++i) {
      const bool ai = shared(b, a.vertex[i], a.corner[i]), aj = shared(b, a.vertex[(i + 1) % 3], a.corner[(i + 1) % 3]);
      if (!ai && in_or_on_triangle(b.corner[0], b.corner[1], b.corner[2], a.corner[i])) return true;
      if (!shared(a, b.vertex[i], b.corner[i]) && in_or_on_triangle(a.corner[0], a.corner[1], a.corner[2], b.corner[i]))
        return true;
      for (int j = 0; j < 3; ++j) {
        const bool bi = shared(a, b.vertex[j], b.corner[j]);
        const bool bj = shared(a, b.vertex[(j + 1) % 3], b.corner[(j + 1) % 3]);
        if (ai || aj || bi || bj) continue;
        if (segments_touch(a.corner[i], a.corner[(i + 1) % 3], b.corner[j], b.corner[(j + 1) % 3])) return true;
      }
    }
    return false;
  }

  // A chart's UV triangles and their boxes, kept until the chart changes.
  struct ChartTriangles {
    std::vector<Triangle> triangles;
    std::vector<Eigen::AlignedBox2d> boxes;
    bool current = false;
  };

  const ChartTriangles& triangles_of(int c) const {
    ChartTriangles& cache = triangles_[c];
    if (cache.current) return cache;
    const FlatChart& chart = charts_[c];
    cache.triangles.resize(chart.faces.size());
    cache.boxes.assign(chart.faces.size(), Eigen::AlignedBox2d());
    for (size_t j = 0; j < chart.faces.size(); ++j)
      for (int k = 0; k < 3; ++k) {
        cache.triangles[j].vertex[k] = vertex(chart.faces[j], k);
        cache.triangles[j].corner[k] = chart.corner_uv.row(3 * j + k).transpose();
        cache.boxes[j].extend(cache.triangles[j].corner[k]);
      }
    cache.current = true;
    return cache;
  }

  // The strip overlaps the receiver or itself: each strip triangle against
  // the receiver's triangles whose box meets the strip's, and the others of
  // the strip.
  bool overlaps_receiver(const Strip& s) const {
    std::vector<Triangle> strip(s.faces.size());
    std::vector<Eigen::AlignedBox2d> boxes(s.faces.size());
    Eigen::AlignedBox2d box;
    for (size_t i = 0; i < s.faces.size(); ++i) {
      for (int k = 0; k < 3; ++k) {
        strip[i].vertex[k] = vertex(s.faces[i], k);
        strip[i].corner[k] = s.uv[3 * i + k];
        boxes[i].extend(s.uv[3 * i + k]);
      }
      box.extend(boxes[i]);
    }
    const ChartTriangles& receiver = triangles_of(s.to);
    std::vector<size_t> near;
    for (size_t j = 0; j < receiver.boxes.size(); ++j)
      if (receiver.boxes[j].intersects(box)) near.push_back(j);
    for (size_t i = 0; i < strip.size(); ++i) {
      for (size_t j : near)
        if (receiver.boxes[j].intersects(boxes[i]) && overlap(strip[i], receiver.triangles[j])) return true;
      for (size_t j = i + 1; j < strip.size(); ++j)
        if (boxes[j].intersects(boxes[i]) && overlap(strip[i], strip[j])) return true;
    }
    return false;
  }

  // Moves the strip's faces to the end of the receiver, the giver's last
  // faces taking their rows; the charts' cached triangles follow.
  void apply(const Strip& s) {
    ChartTriangles& from_cache = triangles_[s.from];
    ChartTriangles& to_cache = triangles_[s.to];
    RowMatrixX2d uv(3 * static_cast<Eigen::Index>(s.faces.size()), 2);
    for (size_t i = 0; i < s.faces.size(); ++i) {
      const int f = s.faces[i];
      const int j = take_out_face(charts_[s.from], f, slot_);
      if (from_cache.current) {
        from_cache.triangles[j] = from_cache.triangles.back(), from_cache.triangles.pop_back();
        from_cache.boxes[j] = from_cache.boxes.back(), from_cache.boxes.pop_back();
      }
      Triangle t;
      Eigen::AlignedBox2d box;
      for (int k = 0; k < 3; ++k) {
        uv.row(3 * static_cast<Eigen::Index>(i) + k) = s.uv[3 * i + k].transpose();
        t.vertex[k] = vertex(f, k), t.corner[k] = s.uv[3 * i + k], box.extend(t.corner[k]);
      }
      if (to_cache.current) to_cache.triangles.push_back(t), to_cache.boxes.push_back(box);
      label_[f] = s.to;
    }
    append_faces(charts_[s.to], s.faces, uv, slot_);
    stats_.faces_moved += static_cast<int>(s.faces.size());
    stats_.seam_removed_3d += s.gain;
  }

  const RefineInput in_;
  std::vector<FlatChart>& charts_;
  // A move must remove more 3D seam than this: round-off at the mesh's scale.
  const double least_gain_;
  std::vector<int> label_, slot_;  // chart of each face, and its row there
  // Work space, reset after each use: marks (0) and band indices (-1) per face.
  mutable std::vector<char> mark_;
  mutable std::vector<int> node_;
  mutable std::vector<ChartTriangles> triangles_;  // per chart, see triangles_of
  RefineStats stats_;
};

}  // namespace

RefineStats straighten_borders(const RefineInput& input, std::vector<FlatChart>& charts) {
  if (input.options.min_area_ratio <= 0) return {};
  return Straightener(input, charts).run();
}

}  // namespace atlas
