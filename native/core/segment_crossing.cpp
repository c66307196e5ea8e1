#include "core/segment_crossing.hpp"

#include <algorithm>

#include "core/bucket_grid.hpp"
#include "core/geometry.hpp"

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

}  // namespace

std::optional<std::pair<int, int>> first_crossing(const std::vector<Eigen::Vector2d>& points,
                                                  const std::vector<Segment>& segments) {
  if (segments.size() < 3) return std::nullopt;
  Eigen::Vector2d lo = points[segments[0].from], hi = lo;
  for (const Segment& s : segments)
    for (int p : {s.from, s.to}) lo = lo.cwiseMin(points[p]), hi = hi.cwiseMax(points[p]);
  BucketGrid grid(lo, hi, segments.size());
  for (size_t i = 0; i < segments.size(); ++i) {
    const Eigen::Vector2d& a = points[segments[i].from];
    const Eigen::Vector2d& b = points[segments[i].to];
    grid.insert(static_cast<int>(i), a.cwiseMin(b), a.cwiseMax(b));
  }
  for (const auto& bucket : grid.buckets())
    for (size_t i = 0; i < bucket.size(); ++i)
      for (size_t j = i + 1; j < bucket.size(); ++j) {
        const Segment& e = segments[bucket[i]];
        const Segment& g = segments[bucket[j]];
        if (e.from == g.from || e.from == g.to || e.to == g.from || e.to == g.to) continue;
        if (segments_meet(points[e.from], points[e.to], points[g.from], points[g.to]))
          return std::make_pair(bucket[i], bucket[j]);
      }
  return std::nullopt;
}

}  // namespace atlas
