// Ear clipping of a simple polygon in the plane.
#pragma once
#include <Eigen/Core>
#include <vector>

namespace atlas {

// Triangulates a counter-clockwise polygon (indices into points, 2D) that
// may visit a point twice (a bridge to a hole), appending its triangles,
// counter-clockwise, to `triangles`. An ear is a strictly convex corner whose
// triangle holds no other remaining reflex corner. Returns false (triangles
// partly appended) when no ear is left: a polygon that crosses itself, is
// clockwise, or has a collinear corner it cannot clip last.
bool clip_ears(const std::vector<Eigen::Vector2d>& points, const std::vector<int>& polygon,
               std::vector<Eigen::Vector3i>& triangles);

}  // namespace atlas
