// Tiny triangle formulas shared by the stages.
#pragma once
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace atlas {

constexpr double kPi = 3.14159265358979323846;

// A face loses density when its texel area falls below this share of its
// original one: it then keeps under half its texels, the unit of the
// output's density guarantee (under 1% of the surface may lose density).
constexpr double kDensityFloor = 0.5;

// Signed area of a 2D triangle: ((b-a) x (c-a)) / 2, positive counter-clockwise.
inline double signed_area(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return 0.5 * ((b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x()));
}

// Area of a 3D triangle: |(b-a) x (c-a)| / 2.
inline double triangle_area(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return 0.5 * (b - a).cross(c - a).norm();
}

}  // namespace atlas
