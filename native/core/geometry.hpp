// Tiny triangle formulas shared by the stages.
#pragma once
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <Eigen/Geometry>

namespace atlas {

// Signed area of a 2D triangle: ((b-a) x (c-a)) / 2, positive counter-clockwise.
inline double signed_area(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return 0.5 * ((b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x()));
}

// Winding of a UV triangle in texels: +1 counter-clockwise, -1 clockwise, 0
// when its height over its longest edge is under a hundredth of a texel. Such
// slivers cover no texel, and storing UVs as float32 (Blender, glTF) moves
// their corners by up to 1/2000 texel on an 8192 page: enough to turn them
// over, so they have no winding worth counting.
inline int uv_winding(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  constexpr double kMinHeight = 1e-2;
  const double doubled_area = 2 * signed_area(a, b, c);
  const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  if (std::abs(doubled_area) <= kMinHeight * longest) return 0;
  return doubled_area > 0 ? 1 : -1;
}

// Area of a 3D triangle: |(b-a) x (c-a)| / 2.
inline double triangle_area(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return 0.5 * (b - a).cross(c - a).norm();
}

}  // namespace atlas
