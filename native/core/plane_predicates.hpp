// Exact-sign predicates on 2D points, for overlap tests of UV triangles.
#pragma once
#include <Eigen/Core>
#include <algorithm>

namespace atlas {

// Twice the signed area of (a, b, c): > 0 when c lies left of a -> b.
inline double orient(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

// c inside the box spanned by a and b (borders included).
inline bool within_box(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return c.x() >= std::min(a.x(), b.x()) && c.x() <= std::max(a.x(), b.x()) && c.y() >= std::min(a.y(), b.y()) &&
         c.y() <= std::max(a.y(), b.y());
}

// Segments pq and rs cross or touch.
inline bool segments_touch(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r,
                           const Eigen::Vector2d& s) {
  const double d1 = orient(p, q, r), d2 = orient(p, q, s), d3 = orient(r, s, p), d4 = orient(r, s, q);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  return (d1 == 0 && within_box(p, q, r)) || (d2 == 0 && within_box(p, q, s)) || (d3 == 0 && within_box(r, s, p)) ||
         (d4 == 0 && within_box(r, s, q));
}

// The point of segment ab closest to p.
inline Eigen::Vector2d closest_on_segment(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                          const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = b - a;
  const double length2 = d.squaredNorm();
  const double t = length2 > 0 ? std::clamp(d.dot(p - a) / length2, 0.0, 1.0) : 0.0;
  return a + t * d;
}

// Distance between segments pq and rs (0 when they cross or touch).
inline double segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r,
                               const Eigen::Vector2d& s) {
  if (segments_touch(p, q, r, s)) return 0;
  return std::min({(closest_on_segment(r, s, p) - p).norm(), (closest_on_segment(r, s, q) - q).norm(),
                   (closest_on_segment(p, q, r) - r).norm(), (closest_on_segment(p, q, s) - s).norm()});
}

// p inside triangle abc or on its edges, either winding.
inline bool in_or_on_triangle(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                              const Eigen::Vector2d& p) {
  const double d1 = orient(a, b, p), d2 = orient(b, c, p), d3 = orient(c, a, p);
  return (d1 >= 0 && d2 >= 0 && d3 >= 0) || (d1 <= 0 && d2 <= 0 && d3 <= 0);
}

}  // namespace atlas
