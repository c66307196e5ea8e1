#include "core/segment_crossing.hpp"

#include "core/bucket_grid.hpp"
#include "core/plane_predicates.hpp"

namespace atlas {

// Touching boundaries count as overlap, hence segments_touch (collinear
// contact included).
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
        if (segments_touch(points[e.from], points[e.to], points[g.from], points[g.to]))
          return std::make_pair(bucket[i], bucket[j]);
      }
  return std::nullopt;
}

}  // namespace atlas
