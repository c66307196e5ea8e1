#include <gtest/gtest.h>

#include <Eigen/LU>

#include <map>
#include <utility>
#include <vector>

#include "core/geometry.hpp"
#include "core/segment_crossing.hpp"
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


// Whether two boundary edges (edges one face uses) cross or touch.
bool boundary_crosses(const RowMatrixX3i& triangles, const RowMatrixX2d& uv) {
  std::map<std::pair<int, int>, int> uses;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = triangles(f, k), b = triangles(f, (k + 1) % 3);
      ++uses[{std::min(a, b), std::max(a, b)}];
    }
  std::vector<Segment> segments;
  for (const auto& [edge, count] : uses)
    if (count == 1) segments.push_back({edge.first, edge.second});
  std::vector<Eigen::Vector2d> points;
  for (Eigen::Index v = 0; v < uv.rows(); ++v) points.push_back(uv.row(v).transpose());
  return first_crossing(points, segments).has_value();
}

// Relaxes uv with the border free: every face ends above half its
// reference area, and the boundary crosses nowhere.
void expect_lifted_with_free_border(const Grid& g, const RowMatrixX2d& reference, RowMatrixX2d& uv) {
  RelaxOptions free;
  free.free_border = true;
  ASSERT_TRUE(relax_squeezed_faces(g.triangles, reference, free, uv));
  EXPECT_GT(smallest_ratio(g, reference, uv), 0.5);
  EXPECT_FALSE(boundary_crosses(g.triangles, uv));
}

TEST(RelaxSqueezedFaces, LiftsAFaceOnTheBorderWhenTheBorderMayMove) {
  // A face whose three corners are all on the boundary, squeezed by sliding
  // one of them along the border: held, nothing can lift it; free, it is.
  const int n = 6;
  const Grid g = grid(n);
  const RowMatrixX2d reference = corners(g, 10.0);
  RowMatrixX2d uv = 10.0 * g.points;
  auto on_boundary = [&](int v) {
    const Eigen::RowVector2d p = g.points.row(v);
    return p.x() == 0 || p.y() == 0 || p.x() == n || p.y() == n;
  };
  Eigen::Index corner_face = -1;
  for (Eigen::Index f = 0; f < g.triangles.rows() && corner_face < 0; ++f)
    if (on_boundary(g.triangles(f, 0)) && on_boundary(g.triangles(f, 1)) && on_boundary(g.triangles(f, 2)))
      corner_face = f;
  ASSERT_GE(corner_face, 0);
  // Its corner that is not a corner of the square slides towards the one that is.
  int slid = -1, towards = -1;
  for (int k = 0; k < 3; ++k) {
    const Eigen::RowVector2d p = g.points.row(g.triangles(corner_face, k));
    const bool square_corner = (p.x() == 0 || p.x() == n) && (p.y() == 0 || p.y() == n);
    if (square_corner) towards = g.triangles(corner_face, k);
  }
  for (int k = 0; k < 3 && slid < 0; ++k) {
    const int v = g.triangles(corner_face, k);
    const Eigen::RowVector2d d = g.points.row(v) - g.points.row(towards);
    if (v != towards && (d.x() == 0 || d.y() == 0)) slid = v;
  }
  ASSERT_GE(slid, 0);
  uv.row(slid) = 10.0 * (0.35 * g.points.row(slid) + 0.65 * g.points.row(towards));
  ASSERT_LT(smallest_ratio(g, reference, uv), 0.4);
  ASSERT_GT(smallest_ratio(g, reference, uv), 0.0);

  RowMatrixX2d held = uv;
  relax_squeezed_faces(g.triangles, reference, RelaxOptions(), held);
  EXPECT_LT(smallest_ratio(g, reference, held), 0.5);
  expect_lifted_with_free_border(g, reference, uv);
}

TEST(RelaxSqueezedFaces, AFreeBorderMovesBeyondTheSqueezedFacesOwnCorners) {
  // A cell on the bottom border whose references are 5 times as wide: to
  // lift it the border must stretch by more than the cells beside it can
  // give up, so boundary vertices beyond its own corners must move too (with
  // only its corners free it stays below half).
  const int n = 6;
  const Grid g = grid(n);
  RowMatrixX2d reference = corners(g, 10.0);
  for (Eigen::Index f = 0; f < g.triangles.rows(); ++f) {
    Eigen::RowVector2d centre = Eigen::RowVector2d::Zero();
    for (int k = 0; k < 3; ++k) centre += g.points.row(g.triangles(f, k)) / 3;
    if (centre.x() > 2 && centre.x() < 3 && centre.y() < 1)
      for (int k = 0; k < 3; ++k) reference(3 * f + k, 0) = 10.0 * (2.5 + 5.0 * (g.points(g.triangles(f, k), 0) - 2.5));
  }
  RowMatrixX2d uv = 10.0 * g.points;
  ASSERT_LT(smallest_ratio(g, reference, uv), 0.5);

  expect_lifted_with_free_border(g, reference, uv);
}

TEST(RelaxSqueezedFaces, AFreeBorderNeverCrossesItself) {
  // A slit from the left side to the middle, its two sides 0.05 apart. A
  // vertex of its lower side is pushed down, squeezing the faces under it,
  // whose references are taller than the gap leaves room for: lifting them
  // fully would push that side through the other.
  const int n = 6;
  Grid g = grid(n);
  std::vector<Eigen::RowVector2d> points;
  for (Eigen::Index v = 0; v < g.points.rows(); ++v) points.push_back(g.points.row(v));
  std::map<int, int> lower_copy;
  RowMatrixX2d reference = corners(g, 10.0);
  for (Eigen::Index f = 0; f < g.triangles.rows(); ++f) {
    double centre_y = 0;
    for (int k = 0; k < 3; ++k) centre_y += g.points(g.triangles(f, k), 1) / 3;
    if (centre_y > 3 || centre_y < 2) continue;
    for (int k = 0; k < 3; ++k) reference(3 * f + k, 1) = 10.0 * (2 + 1.3 * (g.points(g.triangles(f, k), 1) - 2));
    for (int k = 0; k < 3; ++k) {
      const int v = g.triangles(f, k);
      if (g.points(v, 1) != 3 || g.points(v, 0) >= 3) continue;
      if (!lower_copy.count(v)) {
        lower_copy[v] = static_cast<int>(points.size());
        points.push_back(g.points.row(v) - Eigen::RowVector2d(0, 0.05));
      }
      g.triangles(f, k) = lower_copy[v];
    }
  }
  g.points.resize(static_cast<Eigen::Index>(points.size()), 2);
  for (size_t v = 0; v < points.size(); ++v) g.points.row(static_cast<Eigen::Index>(v)) = points[v];
  RowMatrixX2d uv = 10.0 * g.points;
  const int pushed = lower_copy.at(1 * (n + 1) + 3);
  uv(pushed, 1) = 24.0;
  ASSERT_FALSE(boundary_crosses(g.triangles, uv));
  ASSERT_LT(smallest_ratio(g, reference, uv), 0.5);

  expect_lifted_with_free_border(g, reference, uv);
  EXPECT_LT(uv(pushed, 1), 30.0);
}

}  // namespace
}  // namespace atlas
