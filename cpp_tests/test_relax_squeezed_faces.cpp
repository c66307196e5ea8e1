#include <gtest/gtest.h>

#include <Eigen/LU>

#include "core/geometry.hpp"
#include "flatten/relax_squeezed_faces.hpp"
#include "test_meshes.hpp"

namespace atlas {
namespace {

// An n x n grid of unit cells (test_meshes' grid_disk, scaled by n).
struct Grid {
  RowMatrixX3i triangles;
  RowMatrixX2d points;
};

Grid grid(int n) {
  const Mesh mesh = testing::grid_disk(n);
  return {mesh.triangles, n * mesh.positions.leftCols<2>()};
}

// Each face's corners, 3 rows a face, scaled: the references of the tests.
RowMatrixX2d corners(const Grid& g, double scale) {
  RowMatrixX2d out(3 * g.triangles.rows(), 2);
  for (Eigen::Index f = 0; f < g.triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) out.row(3 * f + k) = scale * g.points.row(g.triangles(f, k));
  return out;
}

// Smallest new area over reference area of any face.
double smallest_ratio(const Grid& g, const RowMatrixX2d& reference, const RowMatrixX2d& uv) {
  double smallest = 1e300;
  for (Eigen::Index f = 0; f < g.triangles.rows(); ++f) {
    const auto& t = g.triangles;
    const double after = signed_area(uv.row(t(f, 0)), uv.row(t(f, 1)), uv.row(t(f, 2)));
    const double before = signed_area(reference.row(3 * f), reference.row(3 * f + 1), reference.row(3 * f + 2));
    smallest = std::min(smallest, after / before);
  }
  return smallest;
}

TEST(RelaxSqueezedFaces, LiftsFacesSqueezedByOneVertexAndKeepsTheBoundary) {
  const int n = 6;
  const Grid g = grid(n);
  const RowMatrixX2d reference = corners(g, 10.0);
  RowMatrixX2d uv = 10.0 * g.points;
  const int moved = 3 * (n + 1) + 3;
  uv.row(moved) += Eigen::RowVector2d(7.0, 7.0);  // towards (4, 4): two faces there keep 0.3 of their area
  ASSERT_LT(smallest_ratio(g, reference, uv), 0.35);
  ASSERT_GT(smallest_ratio(g, reference, uv), 0.0);
  const RowMatrixX2d before = uv;

  ASSERT_TRUE(relax_squeezed_faces(g.triangles, reference, RelaxOptions(), uv));
  EXPECT_GT(smallest_ratio(g, reference, uv), 0.5);
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const int v = j * (n + 1) + i;
      const bool on_boundary = i == 0 || j == 0 || i == n || j == n;
      EXPECT_TRUE(!on_boundary || uv.row(v) == before.row(v)) << "boundary vertex " << v << " moved";
    }
  }
}

TEST(RelaxSqueezedFaces, LeavesAChartSqueezedAllOverAsItWas) {
  // Every face keeps about a quarter of its reference area (references of
  // uneven size, so the vertices do move) and the boundary is held: no face
  // can reach half, so nothing is gained and the map must stay as it was.
  const Grid g = grid(5);
  RowMatrixX2d reference = corners(g, 10.0);
  for (Eigen::Index f = 0; f < g.triangles.rows(); ++f)
    reference.middleRows(3 * f, 3) *= 1.9 + 0.05 * static_cast<double>((7 * f) % 5);
  RowMatrixX2d uv = 10.0 * g.points;
  const RowMatrixX2d before = uv;
  EXPECT_FALSE(relax_squeezed_faces(g.triangles, reference, RelaxOptions(), uv));
  EXPECT_EQ(uv, before);
  RelaxOptions none;
  none.sweeps = 0;
  uv.row(8) += Eigen::RowVector2d(3.0, 3.0);
  const RowMatrixX2d squeezed = uv;
  EXPECT_FALSE(relax_squeezed_faces(g.triangles, corners(g, 10.0), none, uv));
  EXPECT_EQ(uv, squeezed);
}

}  // namespace
}  // namespace atlas
