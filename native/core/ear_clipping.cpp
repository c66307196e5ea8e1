#include "core/ear_clipping.hpp"

#include "core/bucket_grid.hpp"
#include "core/geometry.hpp"

namespace atlas {
namespace {

// p inside or on triangle (a, b, c), counter-clockwise.
bool in_triangle(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                 const Eigen::Vector2d& c) {
  return signed_area(a, b, p) >= 0 && signed_area(b, c, p) >= 0 && signed_area(c, a, p) >= 0;
}

}  // namespace

bool clip_ears(const std::vector<Eigen::Vector2d>& points, const std::vector<int>& polygon,
               std::vector<Eigen::Vector3i>& triangles) {
  const int m = static_cast<int>(polygon.size());
  std::vector<int> prev(m), next(m);
  std::vector<char> clipped(m, 0);
  for (int i = 0; i < m; ++i) prev[i] = (i + m - 1) % m, next[i] = (i + 1) % m;
  auto at = [&](int i) -> const Eigen::Vector2d& { return points[polygon[i]]; };
  auto convex = [&](int i) { return signed_area(at(prev[i]), at(i), at(next[i])) > 0; };
  // Only reflex corners can lie inside an ear, and corners never turn reflex
  // while ears are clipped: the grid holds the first ones, and entries that
  // were clipped or turned convex are skipped.
  Eigen::Vector2d bottom_left = at(0), top_right = at(0);
  for (int i = 0; i < m; ++i) bottom_left = bottom_left.cwiseMin(at(i)), top_right = top_right.cwiseMax(at(i));
  std::vector<int> reflex;
  for (int i = 0; i < m; ++i)
    if (!convex(i)) reflex.push_back(i);
  BucketGrid grid(bottom_left, top_right, reflex.size());
  for (int i : reflex) grid.insert(i, at(i), at(i));
  auto is_ear = [&](int i) {
    if (!convex(i)) return false;
    const int a = polygon[prev[i]], b = polygon[i], c = polygon[next[i]];
    const Eigen::Vector2d lo = points[a].cwiseMin(points[b]).cwiseMin(points[c]);
    const Eigen::Vector2d hi = points[a].cwiseMax(points[b]).cwiseMax(points[c]);
    return !grid.any_near(lo, hi, [&](int j) {
      const int p = polygon[j];
      if (clipped[j] || p == a || p == b || p == c || convex(j)) return false;
      return in_triangle(points[p], points[a], points[b], points[c]);
    });
  };
  int i = 0, misses = 0;
  for (int remaining = m; remaining > 3;) {
    if (is_ear(i)) {
      triangles.emplace_back(polygon[prev[i]], polygon[i], polygon[next[i]]);
      clipped[i] = 1;
      next[prev[i]] = next[i];
      prev[next[i]] = prev[i];
      i = prev[i];
      --remaining;
      misses = 0;
    } else if (++misses > remaining) {
      return false;
    } else {
      i = next[i];
    }
  }
  if (!convex(i)) return false;
  triangles.emplace_back(polygon[prev[i]], polygon[i], polygon[next[i]]);
  return true;
}

}  // namespace atlas
