#include "flatten/relax_squeezed_faces.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <limits>
#include <vector>

#include "flatten/symmetric_dirichlet.hpp"

namespace atlas {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
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

// sum_f w_f A_ref(f) psi(J_f) over the faces `which` (every face if empty),
// w_f 1 where `weight` is empty.
double weighted_energy(const std::vector<ReferenceFace>& faces, const std::vector<int>& which,
                       const std::vector<double>& weight, const RowMatrixX2d& uv) {
  double energy = 0;
  const size_t count = which.empty() ? faces.size() : which.size();
  for (size_t i = 0; i < count; ++i) {
    const size_t f = which.empty() ? i : static_cast<size_t>(which[i]);
    energy += (weight.empty() ? 1.0 : weight[f]) * faces[f].area * symmetric_dirichlet_density(jacobian(faces[f], uv));
  }
  return energy;
}

// Reference area of the faces `which` whose area ratio det J is below 1/2.
double area_below_half(const std::vector<ReferenceFace>& faces, const std::vector<int>& which, const RowMatrixX2d& uv) {
  double area = 0;
  for (int f : which)
    if (jacobian(faces[f], uv).determinant() < 0.5) area += faces[f].area;
  return area;
}

// Faces at each vertex, as (face, corner) pairs: those of v are
// at[start[v] .. start[v + 1]).
struct VertexFaces {
  std::vector<int> start;
  std::vector<std::pair<int, int>> at;
};

VertexFaces vertex_faces(const std::vector<ReferenceFace>& faces, int vertex_count) {
  VertexFaces out;
  out.start.assign(static_cast<size_t>(vertex_count) + 1, 0);
  for (const ReferenceFace& face : faces)
    for (int k = 0; k < 3; ++k) ++out.start[static_cast<size_t>(face.corners[k]) + 1];
  for (int v = 0; v < vertex_count; ++v) out.start[v + 1] += out.start[v];
  out.at.resize(3 * faces.size());
  std::vector<int> next(out.start.begin(), out.start.end() - 1);
  for (size_t f = 0; f < faces.size(); ++f)
    for (int k = 0; k < 3; ++k) out.at[static_cast<size_t>(next[faces[f].corners[k]]++)] = {static_cast<int>(f), k};
  return out;
}

// 1 for every vertex on an edge that only one face uses.
std::vector<char> boundary_vertices(const std::vector<ReferenceFace>& faces, int vertex_count) {
  std::vector<std::pair<int, int>> edges;
  edges.reserve(3 * faces.size());
  for (const ReferenceFace& face : faces)
    for (int k = 0; k < 3; ++k) {
      const int a = face.corners[k], b = face.corners[(k + 1) % 3];
      edges.push_back({std::min(a, b), std::max(a, b)});
    }
  std::sort(edges.begin(), edges.end());
  std::vector<char> out(static_cast<size_t>(vertex_count), 0);
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) out[edges[i].first] = out[edges[i].second] = 1;
    i = j;
  }
  return out;
}

// Interior vertices within `rings` vertex rings of a face below half its
// reference area, in the order they were reached.
std::vector<int> free_vertices(const std::vector<ReferenceFace>& faces, const VertexFaces& at,
                               const std::vector<char>& boundary, const RowMatrixX2d& uv, int rings) {
  std::vector<char> reached(boundary.size(), 0);
  std::vector<int> order;
  for (const ReferenceFace& face : faces)
    if (jacobian(face, uv).determinant() < 0.5)
      for (int k = 0; k < 3; ++k)
        if (!reached[face.corners[k]]) reached[face.corners[k]] = 1, order.push_back(face.corners[k]);
  for (size_t ring_start = 0, ring = 0; ring < static_cast<size_t>(rings); ++ring) {
    const size_t ring_end = order.size();
    for (size_t i = ring_start; i < ring_end; ++i)
      for (int s = at.start[order[i]]; s < at.start[order[i] + 1]; ++s)
        for (int k = 0; k < 3; ++k) {
          const int w = faces[at.at[s].first].corners[k];
          if (!reached[w]) reached[w] = 1, order.push_back(w);
        }
    ring_start = ring_end;
  }
  order.erase(std::remove_if(order.begin(), order.end(), [&](int v) { return boundary[v]; }), order.end());
  return order;
}

// The weighted energy of the faces at v with v at p (+inf if one degenerates).
double vertex_energy(const std::vector<ReferenceFace>& faces, const VertexFaces& at, const std::vector<double>& weight,
                     int v, const Eigen::Vector2d& p, RowMatrixX2d& uv) {
  const Eigen::Vector2d kept = uv.row(v).transpose();
  uv.row(v) = p.transpose();
  double energy = 0;
  for (int s = at.start[v]; s < at.start[v + 1] && energy < kInfinity; ++s) {
    const int f = at.at[s].first;
    energy += weight[f] * faces[f].area * symmetric_dirichlet_density(jacobian(faces[f], uv));
  }
  uv.row(v) = kept.transpose();
  return energy;
}

// One step of vertex v: the minimum of its faces' SLIM proxies
//   sum_f w_f A_f |W_f (J_f + d g_f^T - R_f)|^2  (g_f: v's gradient in f),
// a 2x2 system, then a backtracking line search on the true energy that
// starts short of the first face to degenerate.
void relax_vertex(const std::vector<ReferenceFace>& faces, const VertexFaces& at, const std::vector<double>& weight,
                  int v, RowMatrixX2d& uv) {
  Eigen::Matrix2d h = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  double largest_step = kInfinity;
  std::vector<std::pair<Eigen::Matrix2d, Eigen::Vector2d>> jacobians;
  for (int s = at.start[v]; s < at.start[v + 1]; ++s) {
    const auto [f, k] = at.at[s];
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
    const int f = at.at[at.start[v] + i].first;
    const Eigen::Matrix2d dj = d * g.transpose();
    slope += weight[f] * faces[f].area * symmetric_dirichlet_rate(j, dj);
    // det(J + t dJ) is linear in t for a rank-one dJ.
    const double rate = determinant_rate(j, dj);
    if (rate < 0) largest_step = std::min(largest_step, -j.determinant() / rate);
  }
  if (!(slope < 0)) return;
  const Eigen::Vector2d p = uv.row(v).transpose();
  const double start = vertex_energy(faces, at, weight, v, p, uv);
  double t = std::min(1.0, kToDegenerate * largest_step);
  for (int i = 0; i < kHalvings; ++i, t /= 2)
    if (vertex_energy(faces, at, weight, v, p + t * d, uv) <= start + kArmijo * t * slope) {
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
std::vector<int> faces_at(const VertexFaces& at, const std::vector<int>& at_vertices) {
  std::vector<int> out;
  for (int v : at_vertices)
    for (int s = at.start[v]; s < at.start[v + 1]; ++s) out.push_back(at.at[s].first);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace

bool relax_squeezed_faces(const RowMatrixX3i& triangles, const RowMatrixX2d& reference, const RelaxOptions& options,
                          RowMatrixX2d& uv) {
  if (options.sweeps <= 0 || !(options.floor > 0)) return false;
  const std::vector<ReferenceFace> all = reference_faces(triangles, reference);
  if (std::none_of(all.begin(), all.end(), [&](const ReferenceFace& f) { return jacobian(f, uv).determinant() < 0.5; }))
    return false;
  const int vertex_count = static_cast<int>(uv.rows());
  const VertexFaces at = vertex_faces(all, vertex_count);
  const std::vector<int> free = free_vertices(all, at, boundary_vertices(all, vertex_count), uv, options.rings);
  if (free.empty()) return false;
  // Only the faces at free vertices change: the sums run over them.
  const std::vector<int> region = faces_at(at, free);
  const double lost = area_below_half(all, region, uv);
  const double energy = weighted_energy(all, region, {}, uv);
  const double rise = options.energy_rise * weighted_energy(all, {}, {}, uv);
  RowMatrixX2d relaxed = uv;
  std::vector<double> weight(all.size(), 1.0);
  double now_lost = lost;
  for (int sweep = 0; sweep < options.sweeps && now_lost > 0; ++sweep) {
    weigh_squeezed(all, region, relaxed, options.floor, weight);
    for (int v : free) relax_vertex(all, at, weight, v, relaxed);
    if (weighted_energy(all, region, {}, relaxed) > energy + rise) return false;
    now_lost = area_below_half(all, region, relaxed);
  }
  if (!(now_lost < lost)) return false;
  uv = std::move(relaxed);
  return true;
}

}  // namespace atlas
