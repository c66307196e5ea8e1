#include "flatten/scaffold_triangulation.hpp"

#include <algorithm>

#include "core/bucket_grid.hpp"
#include "core/corners.hpp"
#include "core/ear_clipping.hpp"
#include "core/geometry.hpp"

namespace atlas {
namespace {

using Points = std::vector<Eigen::Vector2d>;

// The box and the hole as one polygon: box corners counter-clockwise, and at
// the corner below-right a detour along the bridge to the chart's rightmost
// boundary vertex, round the boundary clockwise, and back. Every point of the
// bridge but its chart end lies right of the whole chart, so it crosses nothing.
std::vector<int> bridged_polygon(const Points& points, const std::vector<int>& loop, int box) {
  const auto rightmost = std::max_element(loop.begin(), loop.end(), [&](int a, int b) {
    return points[a].x() < points[b].x() || (points[a].x() == points[b].x() && points[a].y() < points[b].y());
  });
  const size_t start = static_cast<size_t>(rightmost - loop.begin());
  std::vector<int> polygon = {box, box + 1};
  for (size_t i = 0; i <= loop.size(); ++i) polygon.push_back(loop[(start + loop.size() - i) % loop.size()]);
  polygon.insert(polygon.end(), {box + 1, box + 2, box + 3});
  return polygon;
}

// d strictly inside the circumcircle of counter-clockwise (a, b, c).
bool in_circumcircle(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                     const Eigen::Vector2d& d) {
  const Eigen::Vector2d p = a - d, q = b - d, r = c - d;
  return p.squaredNorm() * (q.x() * r.y() - r.x() * q.y()) - q.squaredNorm() * (p.x() * r.y() - r.x() * p.y()) +
             r.squaredNorm() * (p.x() * q.y() - q.x() * p.y()) >
         0;
}

// Half-edge h = 3t + k runs from corner k of triangle t to corner k + 1;
// twin[h] is the opposite half-edge, -1 on the chart's boundary or the box.
std::vector<int> twin_half_edges(const std::vector<Eigen::Vector3i>& triangles) {
  // Only an edge of exactly two triangles has a twin; a repeated point could
  // make more share a key, and those edges are left alone.
  return opposite_corners(corners_by_edge(3 * static_cast<int>(triangles.size()),
                                          [&](int h) { return triangles[h / 3][h % 3]; }));
}

// Lawson flips: the edge between scaffold triangles (a, b, c) and (b, a, d)
// becomes (c, d) when d lies in the circumcircle of (a, b, c) and both new
// triangles stay positive. Boundary and box edges have no twin, so they stay:
// the result tends to the constrained Delaunay triangulation. Capped, because
// round-off could otherwise flip an edge back and forth.
void delaunay_flips(const Points& points, std::vector<Eigen::Vector3i>& triangles) {
  std::vector<int> twin = twin_half_edges(triangles);
  std::vector<int> stack(twin.size());
  for (size_t h = 0; h < twin.size(); ++h) stack[h] = static_cast<int>(h);
  auto link = [&](int h, int g) {
    twin[h] = g;
    if (g >= 0) twin[g] = h;
  };
  for (size_t budget = 8 * twin.size(); !stack.empty() && budget > 0; --budget) {
    const int h = stack.back();
    stack.pop_back();
    const int g = twin[h];
    if (g < 0) continue;
    const int t = h / 3, k = h % 3, u = g / 3, j = g % 3;
    const int a = triangles[t][k], b = triangles[t][(k + 1) % 3], c = triangles[t][(k + 2) % 3];
    const int d = triangles[u][(j + 2) % 3];
    if (!in_circumcircle(points[a], points[b], points[c], points[d])) continue;
    if (signed_area(points[a], points[d], points[c]) <= 0 || signed_area(points[d], points[b], points[c]) <= 0) continue;
    // Outer half-edges b->c, c->a of t and a->d, d->b of u keep their twins.
    const int bc = twin[3 * t + (k + 1) % 3], ca = twin[3 * t + (k + 2) % 3];
    const int ad = twin[3 * u + (j + 1) % 3], db = twin[3 * u + (j + 2) % 3];
    triangles[t] = {a, d, c};  // a->d, d->c, c->a
    triangles[u] = {d, b, c};  // d->b, b->c, c->d
    link(3 * t, ad), link(3 * t + 2, ca), link(3 * u, db), link(3 * u + 1, bc);
    link(3 * t + 1, 3 * u + 2);
    stack.insert(stack.end(), {3 * t, 3 * t + 2, 3 * u, 3 * u + 1});
  }
}

}  // namespace

bool triangulate_scaffold(const RowMatrixX2d& uv, const std::vector<int>& loop, double margin, Scaffold& scaffold) {
  const int n = static_cast<int>(uv.rows());
  const Eigen::Vector2d lo = uv.colwise().minCoeff().transpose(), hi = uv.colwise().maxCoeff().transpose();
  const double pad = margin * std::max((hi - lo).maxCoeff(), 1e-9);
  scaffold.box_corners.resize(4, 2);
  scaffold.box_corners << lo.x() - pad, lo.y() - pad, hi.x() + pad, lo.y() - pad, hi.x() + pad, hi.y() + pad,
      lo.x() - pad, hi.y() + pad;
  Points points(n + 4);
  for (int v = 0; v < n; ++v) points[v] = uv.row(v).transpose();
  for (int k = 0; k < 4; ++k) points[n + k] = scaffold.box_corners.row(k).transpose();

  std::vector<Eigen::Vector3i> triangles;
  if (!clip_ears(points, bridged_polygon(points, loop, n), triangles)) return false;
  delaunay_flips(points, triangles);
  scaffold.triangles.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (size_t t = 0; t < triangles.size(); ++t) scaffold.triangles.row(t) = triangles[t].transpose();
  return true;
}

}  // namespace atlas
