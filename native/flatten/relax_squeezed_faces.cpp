#include "flatten/relax_squeezed_faces.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include "core/bucket_grid.hpp"
#include "core/geometry.hpp"
#include "core/plane_predicates.hpp"
#include "core/segment_crossing.hpp"
#include "core/topology.hpp"
#include "flatten/symmetric_dirichlet.hpp"

namespace atlas {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kFullTurn = 2 * kPi;
// Armijo sufficient decrease, and the share of the step at which a face
// would degenerate that the line search starts from.
constexpr double kArmijo = 1e-4;
constexpr double kToDegenerate = 0.8;
constexpr int kHalvings = 20;

// What stays fixed per face: the reference's area, and the gradients g_k of
// J = sum_k u_k g_k^T (g_1, g_2 the rows of the inverse reference edges).
struct ReferenceFace {
  Eigen::Vector3i corners;
  double area = 0;
  Eigen::Vector2d gradient[3];
};

std::vector<ReferenceFace> reference_faces(const RowMatrixX3i& triangles, const RowMatrixX2d& reference) {
  std::vector<ReferenceFace> faces(static_cast<size_t>(triangles.rows()));
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    ReferenceFace& face = faces[static_cast<size_t>(f)];
    face.corners = triangles.row(f).transpose();
    Eigen::Matrix2d edges;
    edges.col(0) = (reference.row(3 * f + 1) - reference.row(3 * f)).transpose();
    edges.col(1) = (reference.row(3 * f + 2) - reference.row(3 * f)).transpose();
    face.area = edges.determinant() / 2;
    const Eigen::Matrix2d inverse = edges.inverse();
    face.gradient[1] = inverse.row(0).transpose();
    face.gradient[2] = inverse.row(1).transpose();
    face.gradient[0] = -face.gradient[1] - face.gradient[2];
  }
  return faces;
}

Eigen::Matrix2d jacobian(const ReferenceFace& face, const RowMatrixX2d& uv) {
  Eigen::Matrix2d j = Eigen::Matrix2d::Zero();
  for (int k = 0; k < 3; ++k) j += uv.row(face.corners[k]).transpose() * face.gradient[k].transpose();
  return j;
}

// sum_f A_ref(f) psi(J_f) over the faces `which` (every face if empty).
double energy(const std::vector<ReferenceFace>& faces, const std::vector<int>& which, const RowMatrixX2d& uv) {
  double sum = 0;
  const size_t count = which.empty() ? faces.size() : which.size();
  for (size_t i = 0; i < count; ++i) {
    const size_t f = which.empty() ? i : static_cast<size_t>(which[i]);
    sum += faces[f].area * symmetric_dirichlet_density(jacobian(faces[f], uv));
  }
  return sum;
}

// Reference area of the faces `which` whose area ratio det J is below 1/2.
double area_below_half(const std::vector<ReferenceFace>& faces, const std::vector<int>& which, const RowMatrixX2d& uv) {
  double area = 0;
  for (int f : which)
    if (jacobian(faces[f], uv).determinant() < kDensityFloor) area += faces[f].area;
  return area;
}

// 1 for every vertex on an edge that only one face uses.
std::vector<char> boundary_vertices(const MeshTopology& topology, int vertex_count) {
  std::vector<char> out(static_cast<size_t>(vertex_count), 0);
  for (int e = 0; e < topology.edge_count(); ++e)
    if (topology.edge_valence(e) == 1) out[topology.edge_vertices(e, 0)] = out[topology.edge_vertices(e, 1)] = 1;
  return out;
}

// The vertices within `rings` vertex rings of the faces `squeezed`, in the
// order they were reached: the interior ones, and with free_border the
// boundary ones too (boundary: see boundary_vertices). A squeezed face at the
// border is often held by boundary vertices a ring or two away; freeing only
// its own corners moves the squeeze to its neighbours.
std::vector<int> free_vertices(const std::vector<ReferenceFace>& faces, const MeshTopology& topology,
                               const std::vector<char>& boundary, const std::vector<int>& squeezed, int rings,
                               bool free_border) {
  std::vector<char> reached(boundary.size(), 0);
  std::vector<int> order;
  auto reach = [&](int f) {
    for (int k = 0; k < 3; ++k)
      if (!reached[faces[f].corners[k]]) reached[faces[f].corners[k]] = 1, order.push_back(faces[f].corners[k]);
  };
  for (int f : squeezed) reach(f);
  for (size_t ring_start = 0, ring = 0; ring < static_cast<size_t>(rings); ++ring) {
    const size_t ring_end = order.size();
    for (size_t i = ring_start; i < ring_end; ++i)
      for (int s = topology.vertex_offsets[order[i]]; s < topology.vertex_offsets[order[i] + 1]; ++s)
        reach(topology.vertex_corners[s] / 3);
    ring_start = ring_end;
  }
  std::vector<int> out;
  for (int v : order)
    if (free_border || !boundary[v]) out.push_back(v);
  return out;
}

// The boundary of a chart whose boundary vertices move, kept a simple
// closed curve, so that the flip-free map stays one to one: no boundary edge
// meets another, and the faces at each boundary vertex turn less than once
// around it (beyond that its first and last faces overlap, and its two
// boundary edges, which share it, cannot show it). Outputs are snapped to
// 1/256 texel when rasterised (core/rasterize_triangle.hpp), so a move may
// not bring an edge closer than kClearance texels to another, nor a vertex's
// faces closer than kTurnClearance to a full turn, unless they already were
// and it does not bring them closer.
//
// allows() tests one move. It reads the edges bucketed as the sweep began,
// their boxes grown by kBorderStep of the mean boundary edge, and no boundary
// vertex may move further than that in the sweep: every edge stays within
// the cells it was put in. Small boxes keep the test short; a vertex that
// must go further takes several sweeps.
constexpr double kBorderStep = 0.25;
constexpr double kClearance = 0.05;
constexpr double kTurnClearance = 0.05;
class BorderGuard {
 public:
  BorderGuard(const MeshTopology& topology, const RowMatrixX3i& triangles)
      : topology_(topology), triangles_(triangles), at_(topology.vertex_offsets.size() - 1) {
    for (int e = 0; e < topology.edge_count(); ++e)
      if (topology.edge_valence(e) == 1) {
        const Segment segment{topology.edge_vertices(e, 0), topology.edge_vertices(e, 1)};
        at_[segment.from].push_back(static_cast<int>(segments_.size()));
        at_[segment.to].push_back(static_cast<int>(segments_.size()));
        segments_.push_back(segment);
      }
  }

  // Buckets the edges where they are at the start of a sweep.
  void bucket(const RowMatrixX2d& uv) {
    start_ = uv;
    Eigen::Vector2d lo = uv.colwise().minCoeff().transpose(), hi = uv.colwise().maxCoeff().transpose();
    margin_ = 0;
    for (const Segment& s : segments_) margin_ += (uv.row(s.to) - uv.row(s.from)).norm();
    margin_ *= kBorderStep / static_cast<double>(std::max<size_t>(segments_.size(), 1));
    const Eigen::Vector2d grow = Eigen::Vector2d::Constant(margin_);
    grid_.emplace(lo - grow, hi + grow, segments_.size());
    for (size_t i = 0; i < segments_.size(); ++i) {
      const Eigen::Vector2d a = uv.row(segments_[i].from).transpose(), b = uv.row(segments_[i].to).transpose();
      grid_->insert(static_cast<int>(i), a.cwiseMin(b) - grow, a.cwiseMax(b) + grow);
    }
  }

  // Whether v may move to p: always for an interior vertex, whose faces stay
  // positive; a boundary vertex must keep its edges clear of the others and
  // the boundary vertices of its faces clear of a full turn.
  bool allows(int v, const Eigen::Vector2d& p, RowMatrixX2d& uv) const {
    if (at_[v].empty()) return true;
    if ((p - start_.row(v).transpose()).cwiseAbs().maxCoeff() > margin_) return false;
    return edges_stay_clear(v, p, uv) && turns_stay_clear(v, p, uv);
  }

  // The whole boundary is a simple closed curve.
  bool simple(const RowMatrixX2d& uv) const {
    for (size_t u = 0; u < at_.size(); ++u)
      if (!at_[u].empty() && !(turn(static_cast<int>(u), uv) < kFullTurn)) return false;
    std::vector<Eigen::Vector2d> points(static_cast<size_t>(uv.rows()));
    for (Eigen::Index v = 0; v < uv.rows(); ++v) points[static_cast<size_t>(v)] = uv.row(v).transpose();
    return !first_crossing(points, segments_).has_value();
  }

 private:
  // v's boundary edges, with v at p, come no closer than kClearance to
  // another boundary edge, or no closer than they are.
  bool edges_stay_clear(int v, const Eigen::Vector2d& p, const RowMatrixX2d& uv) const {
    const Eigen::Vector2d now = uv.row(v).transpose(), grow = Eigen::Vector2d::Constant(kClearance);
    for (int i : at_[v]) {
      const int w = segments_[i].from == v ? segments_[i].to : segments_[i].from;
      const Eigen::Vector2d q = uv.row(w).transpose();
      const Eigen::Vector2d lo = p.cwiseMin(q) - grow, hi = p.cwiseMax(q) + grow;
      const bool closer = grid_->any_near(lo, hi, [&](int j) {
        const Segment& t = segments_[j];
        if (t.from == v || t.to == v || t.from == w || t.to == w) return false;
        const Eigen::Vector2d r = uv.row(t.from).transpose(), s = uv.row(t.to).transpose();
        // Most edges in the cells lie clear of the grown box: no distance needed.
        if ((r.cwiseMax(s).array() < lo.array()).any() || (r.cwiseMin(s).array() > hi.array()).any()) return false;
        const double after = segment_distance(p, q, r, s);
        return after < kClearance && after < segment_distance(now, q, r, s);
      });
      if (closer) return false;
    }
    return true;
  }

  // The boundary vertices of v's faces, with v at p, stay kTurnClearance
  // short of a full turn, or no closer to it than they are.
  bool turns_stay_clear(int v, const Eigen::Vector2d& p, RowMatrixX2d& uv) const {
    std::vector<int> around;
    for (int s = topology_.vertex_offsets[v]; s < topology_.vertex_offsets[v + 1]; ++s)
      for (int k = 0; k < 3; ++k)
        if (const int u = triangles_(topology_.vertex_corners[s] / 3, k); !at_[u].empty()) around.push_back(u);
    std::sort(around.begin(), around.end());
    around.erase(std::unique(around.begin(), around.end()), around.end());
    std::vector<double> before;
    for (int u : around) before.push_back(turn(u, uv));
    const Eigen::Vector2d now = uv.row(v).transpose();
    uv.row(v) = p.transpose();
    bool clear = true;
    for (size_t i = 0; i < around.size() && clear; ++i) {
      const double after = turn(around[i], uv);
      clear = !(after > kFullTurn - kTurnClearance && after > before[i]);
    }
    uv.row(v) = now.transpose();
    return clear;
  }

  // The faces' angles at u, added up.
  double turn(int u, const RowMatrixX2d& uv) const {
    double sum = 0;
    for (int s = topology_.vertex_offsets[u]; s < topology_.vertex_offsets[u + 1]; ++s) {
      const int f = topology_.vertex_corners[s] / 3, k = topology_.vertex_corners[s] % 3;
      const Eigen::Vector2d a = (uv.row(triangles_(f, (k + 1) % 3)) - uv.row(u)).transpose();
      const Eigen::Vector2d b = (uv.row(triangles_(f, (k + 2) % 3)) - uv.row(u)).transpose();
      sum += std::atan2(a.x() * b.y() - a.y() * b.x(), a.dot(b));
    }
    return sum;
  }

  const MeshTopology& topology_;
  const RowMatrixX3i& triangles_;
  std::vector<Segment> segments_;
  std::vector<std::vector<int>> at_;  // per vertex: its boundary edges
  std::optional<BucketGrid> grid_;
  RowMatrixX2d start_;  // where the vertices were as the sweep began
  double margin_ = 0;
};

// The weighted energy of the faces at v with v at p (+inf if one degenerates).
double vertex_energy(const std::vector<ReferenceFace>& faces, const MeshTopology& topology,
                     const std::vector<double>& weight, int v, const Eigen::Vector2d& p, RowMatrixX2d& uv) {
  const Eigen::Vector2d kept = uv.row(v).transpose();
  uv.row(v) = p.transpose();
  double sum = 0;
  for (int s = topology.vertex_offsets[v]; s < topology.vertex_offsets[v + 1] && sum < kInfinity; ++s) {
    const int f = topology.vertex_corners[s] / 3;
    sum += weight[f] * faces[f].area * symmetric_dirichlet_density(jacobian(faces[f], uv));
  }
  uv.row(v) = kept.transpose();
  return sum;
}

// One step of vertex v: the minimum of its faces' SLIM proxies
//   sum_f w_f A_f |W_f (J_f + d g_f^T - R_f)|^2  (g_f: v's gradient in f),
// a 2x2 system, then a backtracking line search on the true energy that
// starts short of the first face to degenerate.
void relax_vertex(const std::vector<ReferenceFace>& faces, const MeshTopology& topology,
                  const std::vector<double>& weight, const BorderGuard* guard, int v, RowMatrixX2d& uv) {
  Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  double largest_step = kInfinity;
  std::vector<std::pair<Eigen::Matrix2d, Eigen::Vector2d>> jacobians;
  const int first = topology.vertex_offsets[v], last = topology.vertex_offsets[v + 1];
  for (int s = first; s < last; ++s) {
    const int f = topology.vertex_corners[s] / 3, k = topology.vertex_corners[s] % 3;
    const Eigen::Matrix2d j = jacobian(faces[f], uv);
    const Eigen::Vector2d& g = faces[f].gradient[k];
    const SlimProxyTarget target = slim_proxy_target(j);
    const double wa = weight[f] * faces[f].area;
    h += wa * g.squaredNorm() * target.weight;
    rhs -= wa * target.weight * (j - target.rotation) * g;
    jacobians.push_back({j, g});
  }
  if (!(h.determinant() > 0)) return;  // no face at v: nothing to move
  const Eigen::Vector2d d = h.inverse() * rhs;
  if (!d.allFinite() || d.isZero()) return;
  double slope = 0;  // dE/dt at t = 0 along d
  for (size_t i = 0; i < jacobians.size(); ++i) {
    const auto& [j, g] = jacobians[i];
    const int f = topology.vertex_corners[first + static_cast<int>(i)] / 3;
    const Eigen::Matrix2d dj = d * g.transpose();
    slope += weight[f] * faces[f].area * symmetric_dirichlet_rate(j, dj);
    // det(J + t dJ) is linear in t for a rank-one dJ.
    const double rate = determinant_rate(j, dj);
    if (rate < 0) largest_step = std::min(largest_step, -j.determinant() / rate);
  }
  if (!(slope < 0)) return;
  const Eigen::Vector2d p = uv.row(v).transpose();
  const double start = vertex_energy(faces, topology, weight, v, p, uv);
  double t = std::min(1.0, kToDegenerate * largest_step);
  for (int i = 0; i < kHalvings; ++i, t /= 2)
    if (vertex_energy(faces, topology, weight, v, p + t * d, uv) <= start + kArmijo * t * slope &&
        (!guard || guard->allows(v, p + t * d, uv))) {
      uv.row(v) = (p + t * d).transpose();
      return;
    }
}

// Each sweep, w_f *= floor / ratio for the faces below the floor: a face
// that stays squeezed weighs more and more, until it is lifted or its
// neighbours' energy rises past the bound.
void weigh_squeezed(const std::vector<ReferenceFace>& faces, const std::vector<int>& region, const RowMatrixX2d& uv,
                    double floor, std::vector<double>& weight) {
  for (int f : region) {
    const double ratio = jacobian(faces[f], uv).determinant();
    if (ratio < floor) weight[f] *= floor / ratio;
  }
}

// The faces at the vertices `at_vertices`, each once, ascending.
std::vector<int> faces_at(const MeshTopology& topology, const std::vector<int>& at_vertices) {
  std::vector<int> out;
  for (int v : at_vertices)
    for (int s = topology.vertex_offsets[v]; s < topology.vertex_offsets[v + 1]; ++s)
      out.push_back(topology.vertex_corners[s] / 3);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace

bool relax_squeezed_faces(const RowMatrixX3i& triangles, const RowMatrixX2d& reference, const RelaxOptions& options,
                          RowMatrixX2d& uv) {
  if (options.sweeps <= 0 || !(options.floor > 0)) return false;
  const std::vector<ReferenceFace> all = reference_faces(triangles, reference);
  std::vector<int> squeezed;
  for (size_t f = 0; f < all.size(); ++f)
    if (jacobian(all[f], uv).determinant() < kDensityFloor) squeezed.push_back(static_cast<int>(f));
  if (squeezed.empty()) return false;
  const MeshTopology topology = build_topology(triangles, static_cast<int>(uv.rows()));
  const std::vector<char> boundary = boundary_vertices(topology, static_cast<int>(uv.rows()));
  const std::vector<int> free = free_vertices(all, topology, boundary, squeezed, options.rings, options.free_border);
  if (free.empty()) return false;
  // Only the faces at free vertices change: the sums run over them.
  const std::vector<int> region = faces_at(topology, free);
  const double lost = area_below_half(all, region, uv);
  const double start_energy = energy(all, region, uv);
  const double rise = options.energy_rise * energy(all, {}, uv);
  RowMatrixX2d relaxed = uv;
  std::vector<double> weight(all.size(), 1.0);
  double now_lost = lost;
  std::optional<BorderGuard> guard;
  if (options.free_border) guard.emplace(topology, triangles);
  for (int sweep = 0; sweep < options.sweeps && now_lost > 0; ++sweep) {
    weigh_squeezed(all, region, relaxed, options.floor, weight);
    if (guard) guard->bucket(relaxed);
    for (int v : free) relax_vertex(all, topology, weight, guard ? &*guard : nullptr, v, relaxed);
    if (energy(all, region, relaxed) > start_energy + rise) return false;
    now_lost = area_below_half(all, region, relaxed);
  }
  if (!(now_lost < lost) || (guard && !guard->simple(relaxed))) return false;
  uv = std::move(relaxed);
  return true;
}

}  // namespace atlas
