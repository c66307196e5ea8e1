// Seam refinement: faces moved between flattened charts shorten the seam and
// keep every chart a flip-free, non-overlapping disk that bakes the same.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "bake/bake.hpp"
#include "charts/chart_graph.hpp"
#include "charts/disk_merge.hpp"
#include "core/geometry.hpp"
#include "flatten/disk_boundary.hpp"
#include "flatten/flatten_without_overlap.hpp"
#include "flatten/refine_seams.hpp"
#include "flatten/straighten_borders.hpp"
#include "core/min_cut.hpp"
#include "test_meshes.hpp"

using namespace atlas;

namespace {

constexpr int kGrid = 8;

// The unit grid split down x = 1/2, except that in the odd rows the triangle
// of the left column that touches the border is given to the right chart: a
// zig-zag border of teeth (kGrid / 2 - 1 of them, none on the mesh border),
// each touching the left chart along two edges.
Mesh zigzag_charts(std::vector<int>& chart) {
  const Mesh grid = atlas::testing::grid_disk(kGrid);
  chart.assign(grid.face_count(), 0);
  for (int f = 0; f < grid.face_count(); ++f) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    int on_border = 0;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = grid.positions.row(grid.triangles(f, k));
      centre += p / 3;
      on_border += std::abs(p.x() - 0.5) < 1e-12;
    }
    const int row = static_cast<int>(centre.y() * kGrid);
    const bool tooth = centre.x() < 0.5 && on_border == 2 && row % 2 == 1 && row < kGrid - 1;
    chart[f] = centre.x() > 0.5 || tooth ? 1 : 0;
  }
  return atlas::testing::with_chart_uvs(grid.positions, grid.triangles, chart);
}

// Every chart keeps its input UVs, in texels.
std::vector<FlatChart> kept_charts(const Mesh& mesh, const std::vector<int>& chart, int count) {
  std::vector<FlatChart> out(count);
  for (int f = 0; f < mesh.face_count(); ++f) out[chart[f]].faces.push_back(f);
  for (FlatChart& c : out) {
    c.kept_original = true;
    c.corner_uv.resize(3 * static_cast<Eigen::Index>(c.faces.size()), 2);
    for (size_t i = 0; i < c.faces.size(); ++i)
      for (int k = 0; k < 3; ++k) c.corner_uv.row(3 * i + k) = mesh.uv_texels(c.faces[i], k).transpose();
  }
  return out;
}

// The unit grid split down x = 1/2, but the two columns left of it belong to
// the right chart in rows 2-5: a bump whose faces, one at a time, would each
// lengthen the border by leaving it.
Mesh bump_charts(std::vector<int>& chart) {
  const Mesh grid = atlas::testing::grid_disk(kGrid);
  chart.assign(grid.face_count(), 0);
  for (int f = 0; f < grid.face_count(); ++f) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) centre += grid.positions.row(grid.triangles(f, k)).transpose() / 3;
    const int row = static_cast<int>(centre.y() * kGrid);
    const bool bump = centre.x() > 0.25 && row >= 2 && row <= 5;
    chart[f] = centre.x() > 0.5 || bump ? 1 : 0;
  }
  return atlas::testing::with_chart_uvs(grid.positions, grid.triangles, chart);
}

std::vector<int> labels(const Mesh& mesh, const std::vector<FlatChart>& charts) {
  std::vector<int> label(mesh.face_count(), -1);
  for (size_t c = 0; c < charts.size(); ++c)
    for (int f : charts[c].faces) label[f] = static_cast<int>(c);
  return label;
}

// 3D length of the edges between faces of different charts.
double seam_length(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& label) {
  double length = 0;
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (topology.edge_valence(e) != 2) continue;
    const int f0 = topology.edge_corners[topology.edge_offsets[e]] / 3;
    const int f1 = topology.edge_corners[topology.edge_offsets[e] + 1] / 3;
    if (label[f0] != label[f1])
      length += edge_length(mesh, topology, e);
  }
  return length;
}

// A flattened chart as a triangulation of its own: corners at one mesh
// vertex with the same UV share a vertex.
void welded(const Mesh& mesh, const FlatChart& chart, RowMatrixX3i& triangles, RowMatrixX2d& uv) {
  std::map<std::tuple<int, double, double>, int> index;
  std::vector<Eigen::Vector2d> points;
  triangles.resize(static_cast<Eigen::Index>(chart.faces.size()), 3);
  for (size_t i = 0; i < chart.faces.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2d p = chart.corner_uv.row(3 * i + k).transpose();
      const auto [it, fresh] =
          index.emplace(std::make_tuple(mesh.triangles(chart.faces[i], k), p.x(), p.y()),
                        static_cast<int>(points.size()));
      if (fresh) points.push_back(p);
      triangles(static_cast<Eigen::Index>(i), k) = it->second;
    }
  uv.resize(static_cast<Eigen::Index>(points.size()), 2);
  for (size_t v = 0; v < points.size(); ++v) uv.row(v) = points[v].transpose();
}

// Two charts built by `build` (zigzag_charts, bump_charts), kept at their
// input UVs, as the refinements take them: no seam kept, no face groups.
struct TwoCharts {
  std::vector<int> chart;  // per face, as built
  Mesh mesh;
  MeshTopology topology;
  std::vector<FlatChart> charts;
  std::vector<char> no_seams;
  std::vector<int> no_groups;
  RefineOptions options;

  explicit TwoCharts(Mesh (*build)(std::vector<int>&))
      : mesh(build(chart)), topology(build_topology(mesh.triangles, mesh.vertex_count())),
        charts(kept_charts(mesh, chart, 2)), no_seams(topology.edge_count(), 0) {}
  Polygons polygons{{}};
  RefineInput input() const { return {mesh, topology, no_seams, no_groups, options, polygons}; }
};

void expect_flip_free_disks(const Mesh& mesh, const MeshTopology& topology, const std::vector<FlatChart>& charts) {
  const std::vector<char> no_seams(topology.edge_count(), 0);
  DiskClusters disks(mesh, topology, labels(mesh, charts), static_cast<int>(charts.size()), no_seams);
  for (size_t c = 0; c < charts.size(); ++c) {
    EXPECT_TRUE(disks.is_disk(static_cast<int>(c))) << "chart " << c;
    RowMatrixX3i triangles;
    RowMatrixX2d uv;
    welded(mesh, charts[c], triangles, uv);
    std::vector<int> loop;
    const SolveStatus disk = disk_boundary_loop(triangles, static_cast<int>(uv.rows()), loop);
    EXPECT_TRUE(disk.ok()) << "chart " << c << ": " << disk.detail;
    EXPECT_FALSE(boundary_self_intersects(triangles, uv)) << "chart " << c;
    int positive = 0, negative = 0;
    for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
      const double a = signed_area(uv.row(triangles(f, 0)), uv.row(triangles(f, 1)), uv.row(triangles(f, 2)));
      positive += a > 0, negative += a < 0;
    }
    EXPECT_TRUE(positive == 0 || negative == 0) << "chart " << c << ": " << positive << " vs " << negative;
  }
}

}  // namespace

TEST(RefineSeams, ZigZagBorderGetsShorterAndChartsStayFlipFreeDisks) {
  TwoCharts t(zigzag_charts);
  const double before = seam_length(t.mesh, t.topology, t.chart);
  ASSERT_GT(before, 1.0 + 1e-9);  // longer than the straight border
  const RefineStats stats = refine_seams(t.input(), t.charts);
  const double after = seam_length(t.mesh, t.topology, labels(t.mesh, t.charts));
  EXPECT_EQ(stats.faces_moved, kGrid / 2 - 1);
  EXPECT_NEAR(after, 1.0, 1e-9);  // straight: every tooth went back
  EXPECT_NEAR(before - after, stats.seam_removed_3d, 1e-9);
  expect_flip_free_disks(t.mesh, t.topology, t.charts);
}

// Per face, a polygon id: each face of `moving` (by chart in t) paired with
// its neighbour across an edge that `partner` accepts, every other face alone.
template <class Partner>
std::vector<int> paired_polygons(const TwoCharts& t, const std::vector<int>& moving, Partner partner) {
  std::vector<int> polygon(t.mesh.face_count());
  for (int f = 0; f < t.mesh.face_count(); ++f) polygon[f] = f;
  for (int f : moving)
    for (int k = 0; k < 3; ++k) {
      const int e = t.topology.corner_edge[3 * f + k];
      if (t.topology.edge_valence(e) != 2) continue;
      const int g = face_across(t.topology, e, f);
      if (partner(g) && polygon[g] == g && polygon[f] == f) {
        polygon[g] = f;
        break;
      }
    }
  return polygon;
}

TEST(RefineSeams, ATriangleGoesBackToItsQuadButDoesNotLeaveIt) {
  TwoCharts t(zigzag_charts);
  std::vector<int> teeth;
  for (int f = 0; f < t.mesh.face_count(); ++f)
    if (t.chart[f] == 1 && t.mesh.positions.row(t.mesh.triangles(f, 0)).x() < 0.5 + 1e-12 &&
        t.mesh.positions.row(t.mesh.triangles(f, 1)).x() < 0.5 + 1e-12 &&
        t.mesh.positions.row(t.mesh.triangles(f, 2)).x() < 0.5 + 1e-12)
      teeth.push_back(f);
  ASSERT_EQ(teeth.size(), static_cast<size_t>(kGrid / 2 - 1));
  // Each tooth a quad with a triangle of the left chart: moving back joins it.
  t.polygons = Polygons(paired_polygons(t, teeth, [&](int g) { return t.chart[g] == 0; }));
  EXPECT_EQ(refine_seams(t.input(), t.charts).faces_moved, kGrid / 2 - 1);
  // Each tooth a quad with a triangle of its own chart: moving would part it.
  TwoCharts u(zigzag_charts);
  u.polygons = Polygons(paired_polygons(u, teeth, [&](int g) { return u.chart[g] == 1; }));
  EXPECT_EQ(refine_seams(u.input(), u.charts).faces_moved, 0);
}

TEST(RefineSeams, DisabledByZeroAreaRatio) {
  TwoCharts t(zigzag_charts);
  t.options.min_area_ratio = 0;
  EXPECT_EQ(refine_seams(t.input(), t.charts).faces_moved, 0);
}

TEST(RefineSeams, FaceMovedToAnotherChartBakesToTheSameColours) {
  TwoCharts t(zigzag_charts);
  refine_seams(t.input(), t.charts);
  const Mesh& mesh = t.mesh;
  const std::vector<int>& chart = t.chart;
  const std::vector<FlatChart>& charts = t.charts;
  // A smooth old page, so bilinear sampling at the same surface point agrees.
  const int size = mesh.pages[0].width;
  std::vector<std::uint8_t> old_texels(static_cast<size_t>(size) * size * 3);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      std::uint8_t* t = &old_texels[(static_cast<size_t>(y) * size + x) * 3];
      t[0] = static_cast<std::uint8_t>(x / 4), t[1] = static_cast<std::uint8_t>(y / 4);
      t[2] = static_cast<std::uint8_t>((x + y) / 8);
    }
  // The refined charts on the old page (they keep its texel coordinates).
  RowMatrixX2d new_uv(3 * mesh.face_count(), 2);
  std::vector<int> moved;
  for (size_t c = 0; c < charts.size(); ++c)
    for (size_t i = 0; i < charts[c].faces.size(); ++i) {
      const int f = charts[c].faces[i];
      new_uv.middleRows(3 * f, 3) = charts[c].corner_uv.middleRows(3 * i, 3) / size;
      if (chart[f] != static_cast<int>(c)) moved.push_back(f);
    }
  ASSERT_FALSE(moved.empty());
  const Eigen::VectorXi page = Eigen::VectorXi::Zero(mesh.face_count());
  const UvLayout old_layout = layout_of(mesh), new_layout{&new_uv, &page, &mesh.pages};
  const ImageView<std::uint8_t> view{old_texels.data(), size, size, 3, old_texels.size()};
  const auto baked = bake_map<std::uint8_t>(old_layout, {view}, new_layout, {}, RunControl());
  auto texel = [&](const std::vector<std::uint8_t>& texels, const Eigen::Vector2d& uv, int channel) {
    const int x = static_cast<int>(uv.x() * size), y = static_cast<int>(uv.y() * size);
    return static_cast<int>(texels[(static_cast<size_t>(y) * size + x) * 3 + channel]);
  };
  for (int f : moved) {
    const Eigen::Vector2d old_centre = (mesh.corner_uv.middleRows(3 * f, 3).colwise().sum() / 3).transpose();
    const Eigen::Vector2d new_centre = (new_uv.middleRows(3 * f, 3).colwise().sum() / 3).transpose();
    EXPECT_GT((old_centre - new_centre).norm() * size, 10.0);  // it really moved on the page
    for (int channel = 0; channel < 3; ++channel)
      EXPECT_NEAR(texel(baked[0].texels, new_centre, channel), texel(old_texels, old_centre, channel), 1)
          << "face " << f;
  }
}

TEST(StraightenBorders, BumpGoesBackWholeAndChartsStayFlipFreeDisks) {
  TwoCharts t(bump_charts);
  for (FlatChart& c : t.charts) c.kept_original = false;  // solved charts, at their input UVs
  const double before = seam_length(t.mesh, t.topology, t.chart);
  ASSERT_NEAR(before, 1.5, 1e-9);  // the straight border and the bump's two sides
  const RefineStats stats = straighten_borders(t.input(), t.charts);
  EXPECT_EQ(stats.faces_moved, 2 * 2 * 4);  // two columns, four rows, two triangles a cell
  EXPECT_NEAR(seam_length(t.mesh, t.topology, labels(t.mesh, t.charts)), 1.0, 1e-9);
  EXPECT_NEAR(stats.seam_removed_3d, 0.5, 1e-9);
  expect_flip_free_disks(t.mesh, t.topology, t.charts);
  // The moved faces keep their shape: the charts are flat, so nearly exactly.
  const FlatChart& left = t.charts[0];
  for (size_t j = 0; j < left.faces.size(); ++j) {
    const double area =
        signed_area(left.corner_uv.row(3 * j), left.corner_uv.row(3 * j + 1), left.corner_uv.row(3 * j + 2));
    const double input = std::abs(t.mesh.signed_area_uv(left.faces[j]));
    EXPECT_NEAR(std::abs(area), input, 1e-6 * input) << "face " << left.faces[j];
  }
}

TEST(StraightenBorders, QuadsMoveWholeOrNotAtAll) {
  TwoCharts t(bump_charts);
  for (FlatChart& c : t.charts) c.kept_original = false;
  auto centre_x = [&](int f) {
    return (t.mesh.positions(t.mesh.triangles(f, 0), 0) + t.mesh.positions(t.mesh.triangles(f, 1), 0) +
            t.mesh.positions(t.mesh.triangles(f, 2), 0)) / 3;
  };
  std::vector<int> bump, inner;  // inner: the bump's column away from the border
  for (int f = 0; f < t.mesh.face_count(); ++f)
    if (t.chart[f] == 1 && centre_x(f) < 0.5) {
      bump.push_back(f);
      if (centre_x(f) < 0.375) inner.push_back(f);
    }
  ASSERT_EQ(bump.size(), 16u);
  auto in = [](const std::vector<int>& faces, int g) { return std::find(faces.begin(), faces.end(), g) != faces.end(); };
  // The bump's cells as quads: the strips move them whole, the border ends straight.
  t.polygons = Polygons(paired_polygons(t, bump, [&](int g) { return in(bump, g); }));
  EXPECT_EQ(straighten_borders(t.input(), t.charts).faces_moved, 16);
  EXPECT_NEAR(seam_length(t.mesh, t.topology, labels(t.mesh, t.charts)), 1.0, 1e-9);
  // Quads across the bump's two columns: no strip may part them.
  TwoCharts u(bump_charts);
  for (FlatChart& c : u.charts) c.kept_original = false;
  const std::vector<int> pairs =
      paired_polygons(u, inner, [&](int g) { return in(bump, g) && !in(inner, g); });
  u.polygons = Polygons(pairs);
  straighten_borders(u.input(), u.charts);
  const std::vector<int> after = labels(u.mesh, u.charts);
  int quads = 0;
  for (int f = 0; f < u.mesh.face_count(); ++f)
    if (pairs[f] != f) {
      ++quads;
      EXPECT_EQ(after[f], after[pairs[f]]) << "faces " << f << " and " << pairs[f];
    }
  EXPECT_EQ(quads, 4);
  expect_flip_free_disks(u.mesh, u.topology, u.charts);
}

TEST(StraightenBorders, ChartsKeepingTheirOriginalUVsTakeNoPart) {
  TwoCharts t(bump_charts);
  EXPECT_EQ(straighten_borders(t.input(), t.charts).faces_moved, 0);
}

// s - a - b - t with capacities 3, 1, 2 and a bypass s - b of 0.5: the cut
// takes a - b and s - b (1.5), leaving s and a on the source's side.
TEST(MinCut, TakesTheCheapestEdgesBetweenSourceAndSink) {
  const int s = 0, a = 1, b = 2, t = 3;
  const std::vector<char> side = min_cut_source_side(4, {{s, a, 3}, {a, b, 1}, {b, t, 2}, {s, b, 0.5}}, s, t);
  EXPECT_EQ(side, (std::vector<char>{1, 1, 0, 0}));
}
