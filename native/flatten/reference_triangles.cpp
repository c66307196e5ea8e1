#include "flatten/reference_triangles.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/geometry.hpp"

namespace atlas {
namespace {

// A reference smaller than this fraction of the area the face should cover
// makes the symmetric Dirichlet energy explode (it grows like 1/area).
constexpr double kMinAreaRatio = 1e-3;
// sin(1 degree): below it a triangle is a sliver whose Jacobian is ill-conditioned.
constexpr double kSinMinAngle = 0.017452406437283512;

// All angles of a triangle with these edge lengths are at least 1 degree.
// The smallest sine, sin(angle) = 2A / (l_j l_k), is the one between the two
// longest edges, so one comparison covers both tiny and near-180 degree angles.
// Written so that NaN and zero-length edges fail the test.
bool well_shaped(double area, double l0, double l1, double l2) {
  const double longest = std::max({l0, l1, l2});
  const double middle = l0 + l1 + l2 - longest - std::min({l0, l1, l2});
  return 2 * area > kSinMinAngle * longest * middle;
}

bool well_shaped_2d(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return well_shaped(std::abs(signed_area(a, b, c)), (b - a).norm(), (c - b).norm(), (a - c).norm());
}

bool well_shaped_3d(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  return well_shaped(triangle_area(a, b, c), (b - a).norm(), (c - b).norm(), (a - c).norm());
}

// Equilateral triangle of the given area: side s with area sqrt(3)/4 s^2.
void write_equilateral(double area, Eigen::Ref<RowMatrixX2d> out) {
  const double side = std::sqrt(4 * area / std::sqrt(3.0));
  out.row(0) << 0, 0;
  out.row(1) << side, 0;
  out.row(2) << side / 2, side * std::sqrt(3.0) / 2;
}

}  // namespace

// Corners (0, 0), (|b - a|, 0) and ((c - a).(b - a) / |b - a|, |(b - a) x (c - a)| / |b - a|),
// times sqrt(density).
void write_flattened(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                     double density, Eigen::Ref<RowMatrixX2d> out) {
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const double length = e1.norm(), scale = std::sqrt(density);
  out.row(0) << 0, 0;
  out.row(1) << scale * length, 0;
  out.row(2) << scale * e1.dot(e2) / length, scale * e1.cross(e2).norm() / length;
}

ReferenceTriangles repaired_reference_triangles(const RowMatrixX3i& triangles,
                                                const RowMatrixX3d& positions,
                                                const RowMatrixX2d& reference_uv,
                                                const Eigen::VectorXi& mirrored) {
  const Eigen::Index face_count = triangles.rows();
  ReferenceTriangles out;
  out.corners = reference_uv;
  std::vector<char> reference_ok(face_count), solid_ok(face_count), was_folded(face_count);
  std::vector<double> reference_area(face_count), solid_area(face_count);
  double good_reference_area = 0, good_solid_area = 0, shaped_reference_area = 0;
  int shaped_reference_count = 0;

  for (Eigen::Index f = 0; f < face_count; ++f) {
    auto corners = out.corners.middleRows<3>(3 * f);
    if (mirrored[f]) corners.col(0) *= -1;
    if (signed_area(corners.row(0), corners.row(1), corners.row(2)) < 0) {
      corners.col(0) *= -1;
      was_folded[f] = 1;
    }
    const Eigen::Vector3d a = positions.row(triangles(f, 0)), b = positions.row(triangles(f, 1)),
                          c = positions.row(triangles(f, 2));
    reference_area[f] = signed_area(corners.row(0), corners.row(1), corners.row(2));
    solid_area[f] = triangle_area(a, b, c);
    reference_ok[f] = well_shaped_2d(corners.row(0), corners.row(1), corners.row(2));
    solid_ok[f] = well_shaped_3d(a, b, c);
    if (reference_ok[f]) {
      shaped_reference_area += reference_area[f];
      ++shaped_reference_count;
    }
    if (reference_ok[f] && solid_ok[f]) {
      good_reference_area += reference_area[f];
      good_solid_area += solid_area[f];
    }
  }

  // Without any usable face the scale is arbitrary: one texel per 3D unit.
  const double density = good_solid_area > 0 ? good_reference_area / good_solid_area : 1.0;
  const double mean_area = shaped_reference_count > 0 ? shaped_reference_area / shaped_reference_count : 1.0;

  for (Eigen::Index f = 0; f < face_count; ++f) {
    const double expected_area = solid_ok[f] ? density * solid_area[f] : mean_area;
    if (reference_ok[f] && reference_area[f] >= kMinAreaRatio * expected_area) {
      out.folded += was_folded[f];
      continue;
    }
    auto corners = out.corners.middleRows<3>(3 * f);
    if (solid_ok[f])
      write_flattened(positions.row(triangles(f, 0)), positions.row(triangles(f, 1)),
                      positions.row(triangles(f, 2)), density, corners);
    else
      write_equilateral(mean_area, corners);
    ++out.repaired;
  }
  return out;
}

}  // namespace atlas
