// Whether any two of a set of 2D segments cross or touch, on a uniform grid.
// The overlap check runs it on a chart's boundary edges, and SLIM on its
// boundary loop after every step, to hand a crossing chart over to SCAF.
#pragma once
#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace atlas {

struct Segment {
  int from, to;  // point indices; segments sharing an end point are not tested
};

// The first pair of segments (indices into segments) found crossing or
// touching other than at a shared end point; nothing if there is none.
// About one segment per grid cell keeps the pair tests near linear.
std::optional<std::pair<int, int>> first_crossing(const std::vector<Eigen::Vector2d>& points,
                                                  const std::vector<Segment>& segments);

}  // namespace atlas
