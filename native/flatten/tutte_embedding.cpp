#include "flatten/tutte_embedding.hpp"

#include <Eigen/SparseCholesky>
#include <cmath>

#include "core/corners.hpp"
#include "core/geometry.hpp"

namespace atlas {
namespace {

Eigen::Vector2d corner(const RowMatrixX2d& reference, int f, int k) { return reference.row(3 * f + k % 3); }

// tan(alpha / 2) for the angle alpha at corner a of the positive triangle (a, b, c):
// sin / (1 + cos) with sin = 2A / (|ab| |ac|) and cos = ab.ac / (|ab| |ac|).
// Finite and positive because references have no angle near 0 or 180 degrees.
double tan_half_angle(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d ab = b - a, ac = c - a;
  return 2 * signed_area(a, b, c) / (ab.norm() * ac.norm() + ab.dot(ac));
}

// Boundary vertex after arc length s (of total L) goes to angle 2 pi s / L on
// the unit circle, counter-clockwise like the face winding: the circle is
// convex, which is what Floater's theorem asks of the boundary.
void place_boundary_on_circle(const RowMatrixX3i& triangles, const RowMatrixX2d& reference,
                              const std::vector<int>& boundary_corners, RowMatrixX2d& uv) {
  std::vector<double> arc_start(boundary_corners.size());
  double perimeter = 0;
  for (size_t i = 0; i < boundary_corners.size(); ++i) {
    const int f = boundary_corners[i] / 3, k = boundary_corners[i] % 3;
    arc_start[i] = perimeter;
    perimeter += (corner(reference, f, k + 1) - corner(reference, f, k)).norm();
  }
  for (size_t i = 0; i < boundary_corners.size(); ++i) {
    const double angle = 2 * kPi * arc_start[i] / perimeter;
    uv.row(corner_vertex(triangles, boundary_corners[i])) << std::cos(angle), std::sin(angle);
  }
}

double total_area(const RowMatrixX3i& triangles, const RowMatrixX2d& uv) {
  double area = 0;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    area += signed_area(uv.row(triangles(f, 0)), uv.row(triangles(f, 1)), uv.row(triangles(f, 2)));
  return area;
}

double total_reference_area(const RowMatrixX2d& reference) {
  double area = 0;
  for (Eigen::Index c = 0; c < reference.rows(); c += 3)
    area += signed_area(reference.row(c), reference.row(c + 1), reference.row(c + 2));
  return area;
}

}  // namespace

SolveStatus mean_value_embedding(const RowMatrixX3i& triangles, const RowMatrixX2d& reference,
                                 const std::vector<int>& boundary_corners, int vertex_count,
                                 RowMatrixX2d& uv) {
  uv.setZero(vertex_count, 2);
  place_boundary_on_circle(triangles, reference, boundary_corners, uv);

  // Interior vertices are the unknowns; boundary ones move to the right-hand side.
  std::vector<int> unknown(vertex_count, 0);
  for (int c : boundary_corners) unknown[corner_vertex(triangles, c)] = -1;
  int unknown_count = 0;
  for (int& u : unknown)
    if (u == 0) u = unknown_count++;

  if (unknown_count > 0) {
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(9 * triangles.rows());
    Eigen::MatrixX2d rhs = Eigen::MatrixX2d::Zero(unknown_count, 2);
    const auto couple = [&](int i, int j, double w) {
      if (unknown[i] < 0) return;
      entries.emplace_back(unknown[i], unknown[i], w);
      if (unknown[j] >= 0)
        entries.emplace_back(unknown[i], unknown[j], -w);
      else
        rhs.row(unknown[i]) += w * uv.row(j);
    };
    for (int f = 0; f < triangles.rows(); ++f)
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector2d ri = corner(reference, f, k), rj = corner(reference, f, k + 1),
                              rk = corner(reference, f, k + 2);
        const double w = 0.5 * (tan_half_angle(ri, rj, rk) + tan_half_angle(rj, rk, ri)) / (rj - ri).norm();
        couple(triangles(f, k), triangles(f, (k + 1) % 3), w);
        couple(triangles(f, (k + 1) % 3), triangles(f, k), w);
      }
    Eigen::SparseMatrix<double> laplacian(unknown_count, unknown_count);
    laplacian.setFromTriplets(entries.begin(), entries.end());
    const Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> solver(laplacian);
    if (solver.info() != Eigen::Success) return solve_failed(SolveFailure::embedding, "mean-value embedding: Laplacian factorization failed");
    const Eigen::MatrixX2d interior = solver.solve(rhs);
    for (int v = 0; v < vertex_count; ++v)
      if (unknown[v] >= 0) uv.row(v) = interior.row(unknown[v]);
  }

  const double area = total_area(triangles, uv);
  if (!(area > 0) || !uv.allFinite()) return solve_failed(SolveFailure::embedding, "mean-value embedding: degenerate result");
  uv *= std::sqrt(total_reference_area(reference) / area);
  return {};
}

}  // namespace atlas
