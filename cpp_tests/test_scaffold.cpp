// The scaffold that SCAF solves a chart in: a triangulation of the box around
// the chart minus the chart.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

#include "core/geometry.hpp"
#include "flatten/scaffold_triangulation.hpp"

using namespace atlas;

namespace {

// A comb: a polygon with deep slots, the shape of chart boundaries that
// nearly touch themselves. Counter-clockwise.
RowMatrixX2d comb(int teeth, std::vector<int>& loop) {
  std::vector<Eigen::Vector2d> p = {{0, 0}};
  for (int i = 0; i < teeth; ++i) {
    const double x = 2.0 * i;
    p.push_back({x + 1.0, 0.0});
    p.push_back({x + 1.0, 5.0});
    p.push_back({x + 1.9, 5.0});
    p.push_back({x + 1.9, 0.0});
  }
  p.push_back({2.0 * teeth + 1, 0});
  p.push_back({2.0 * teeth + 1, 6});
  p.push_back({0, 6});
  RowMatrixX2d uv(static_cast<Eigen::Index>(p.size()), 2);
  for (size_t i = 0; i < p.size(); ++i) uv.row(i) = p[i].transpose(), loop.push_back(static_cast<int>(i));
  return uv;
}

double polygon_area(const RowMatrixX2d& uv, const std::vector<int>& loop) {
  double area = 0;
  for (size_t i = 0; i < loop.size(); ++i) {
    const Eigen::Vector2d a = uv.row(loop[i]), b = uv.row(loop[(i + 1) % loop.size()]);
    area += 0.5 * (a.x() * b.y() - b.x() * a.y());
  }
  return area;
}

void expect_fills_box(const RowMatrixX2d& uv, const std::vector<int>& loop, const Scaffold& s) {
  const int n = static_cast<int>(uv.rows());
  auto point = [&](int i) -> Eigen::Vector2d {
    return i < n ? Eigen::Vector2d(uv.row(i)) : Eigen::Vector2d(s.box_corners.row(i - n));
  };
  double area = 0;
  std::map<std::pair<int, int>, int> directed;
  for (Eigen::Index t = 0; t < s.triangles.rows(); ++t) {
    const double a = signed_area(point(s.triangles(t, 0)), point(s.triangles(t, 1)), point(s.triangles(t, 2)));
    EXPECT_GT(a, 0) << "scaffold triangle " << t;
    area += a;
    for (int k = 0; k < 3; ++k) ++directed[{s.triangles(t, k), s.triangles(t, (k + 1) % 3)}];
  }
  const Eigen::Vector2d box = s.box_corners.row(2) - s.box_corners.row(0);
  EXPECT_NEAR(area + polygon_area(uv, loop), box.x() * box.y(), 1e-9 * box.x() * box.y());
  // Each chart boundary edge borders exactly one scaffold triangle, running the other way.
  for (size_t i = 0; i < loop.size(); ++i) {
    const int a = loop[i], b = loop[(i + 1) % loop.size()];
    EXPECT_EQ(directed[std::make_pair(b, a)], 1) << "boundary edge " << a << "-" << b;
    EXPECT_EQ(directed.count({a, b}), 0u) << "boundary edge " << a << "-" << b;
  }
  for (const auto& [edge, count] : directed) EXPECT_EQ(count, 1) << edge.first << "-" << edge.second;
}

}  // namespace

TEST(Scaffold, SquareChartIsSurroundedExactly) {
  RowMatrixX2d uv(4, 2);
  uv << 0, 0, 1, 0, 1, 1, 0, 1;
  const std::vector<int> loop = {0, 1, 2, 3};
  Scaffold s;
  ASSERT_TRUE(triangulate_scaffold(uv, loop, 1.0, s));
  EXPECT_EQ(s.triangles.rows(), 8);  // a polygon with one hole: as many triangles as corners
  expect_fills_box(uv, loop, s);
  EXPECT_NEAR(s.box_corners(0, 0), -1.0, 1e-12);
  EXPECT_NEAR(s.box_corners(2, 1), 2.0, 1e-12);
}

TEST(Scaffold, DeepSlotsAreFilledWithoutCrossing) {
  std::vector<int> loop;
  const RowMatrixX2d uv = comb(12, loop);
  ASSERT_GT(polygon_area(uv, loop), 0);
  Scaffold s;
  ASSERT_TRUE(triangulate_scaffold(uv, loop, 0.5, s));
  expect_fills_box(uv, loop, s);
}
