// Cuts for packing: an L-shaped chart is cut where its arms meet, into two
// disks that keep their UVs and pack onto less page; the seam reported is
// the seam opened; budgets, convex charts and non-disks are respected.
#include <gtest/gtest.h>

#include <omp.h>

#include <algorithm>
#include <numeric>
#include <vector>

#include "core/topology.hpp"
#include "flatten/disk_boundary.hpp"
#include "flatten/packing_cuts.hpp"
#include "pack/pack.hpp"
#include "test_meshes.hpp"

using namespace atlas;

namespace {

constexpr int kSide = 40;         // cells of the L's long sides
constexpr int kArm = 8;           // cells across each arm
constexpr double kTexels = 4.0;   // texels per cell

// An L of unit cells (two triangles each) in the plane: a kSide x kArm bar
// along x and a kArm x kSide bar along y. One chart, UV = kTexels * xy.
struct LChart {
  Mesh mesh;
  MeshTopology topology;
  std::vector<FlatChart> charts;
};

LChart l_chart(bool kept_original) {
  const Mesh grid = atlas::testing::grid_disk(kSide);
  std::vector<int> faces;
  for (int f = 0; f < grid.face_count(); ++f) {
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) centre += grid.positions.row(grid.triangles(f, k)).transpose() / 3.0;
    if (std::min(centre.x(), centre.y()) * kSide < kArm) faces.push_back(f);
  }
  LChart l;
  l.mesh = grid;
  l.mesh.positions *= kSide;  // one unit of length per cell
  l.topology = build_topology(l.mesh.triangles, l.mesh.vertex_count());
  FlatChart chart;
  chart.faces = faces;
  chart.kept_original = kept_original;
  chart.corner_uv.resize(3 * static_cast<Eigen::Index>(faces.size()), 2);
  for (size_t i = 0; i < faces.size(); ++i)
    for (int k = 0; k < 3; ++k)
      chart.corner_uv.row(3 * i + k) = kTexels * l.mesh.positions.row(l.mesh.triangles(faces[i], k)).head<2>();
  l.charts.push_back(chart);
  return l;
}

PackingCutOptions options(double budget) {
  PackingCutOptions o;
  o.padding = 4;
  o.seam_budget = budget;
  return o;
}

long long packed_page_texels(const std::vector<FlatChart>& charts) {
  std::vector<RowMatrixX2d> uv;
  for (const FlatChart& c : charts) uv.push_back(c.corner_uv);
  PackOptions pack;
  pack.padding = 4;
  const PackResult result = pack_charts(uv, pack, RunControl{});
  long long texels = 0;
  for (const PageSize& page : result.pages) texels += static_cast<long long>(page.width) * page.height;
  return texels;
}

// The chart's faces with local vertices (corners at one mesh vertex joined),
// as disk_boundary_loop takes them: every face of an L piece is UV-continuous
// with its neighbours, so mesh vertices are the local ones.
bool is_disk(const Mesh& mesh, const FlatChart& chart) {
  std::vector<int> local(mesh.vertex_count(), -1);
  RowMatrixX3i triangles(chart.faces.size(), 3);
  int n = 0;
  for (size_t i = 0; i < chart.faces.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      int& v = local[mesh.triangles(chart.faces[i], k)];
      if (v < 0) v = n++;
      triangles(i, k) = v;
    }
  std::vector<int> loop;
  return disk_boundary_loop(triangles, n, loop).ok();
}

// 3D length of the mesh edges whose two faces lie in different charts.
double seam_between(const Mesh& mesh, const MeshTopology& topology, const std::vector<FlatChart>& charts) {
  std::vector<int> chart_of(mesh.face_count(), -1);
  for (size_t c = 0; c < charts.size(); ++c)
    for (int f : charts[c].faces) chart_of[f] = static_cast<int>(c);
  double seam = 0;
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (topology.edge_valence(e) != 2) continue;
    const int a = chart_of[topology.edge_corners[topology.edge_offsets[e]] / 3];
    const int b = chart_of[topology.edge_corners[topology.edge_offsets[e] + 1] / 3];
    if (a >= 0 && b >= 0 && a != b) seam += edge_length(mesh, topology, e);
  }
  return seam;
}

TEST(PackingCuts, LShapeIsCutOnceIntoTwoDisksThatPackSmaller) {
  LChart l = l_chart(true);
  const FlatChart whole = l.charts[0];
  const PackingCutStats stats = cut_for_packing(l.mesh, l.topology, options(100.0), l.charts, RunControl{});
  ASSERT_EQ(stats.cuts, 1);
  ASSERT_EQ(l.charts.size(), 2u);
  // The faces are shared out, each keeping its UVs (kept_original: not turned).
  std::vector<int> seen(l.mesh.face_count(), 0);
  for (const FlatChart& piece : l.charts) {
    EXPECT_TRUE(piece.kept_original);
    EXPECT_TRUE(is_disk(l.mesh, piece));
    for (size_t i = 0; i < piece.faces.size(); ++i) {
      ++seen[piece.faces[i]];
      const auto at = std::find(whole.faces.begin(), whole.faces.end(), piece.faces[i]) - whole.faces.begin();
      EXPECT_EQ(piece.corner_uv.middleRows(3 * i, 3), whole.corner_uv.middleRows(3 * at, 3));
    }
  }
  for (int f : whole.faces) EXPECT_EQ(seen[f], 1);
  // The seam reported is the seam opened, about an arm across (a cut along
  // the cells' diagonals is sqrt(2) longer).
  EXPECT_NEAR(stats.seam_added_3d, seam_between(l.mesh, l.topology, l.charts), 1e-9);
  EXPECT_GE(stats.seam_added_3d, kArm - 1e-9);
  EXPECT_LE(stats.seam_added_3d, 1.5 * kArm);
  EXPECT_LT(packed_page_texels(l.charts), 0.8 * packed_page_texels({whole}));
}

TEST(PackingCuts, PolygonsAcrossTheCutGoWholeToOnePiece) {
  // The L's triangles paired across the grid's lines, not across the cells'
  // diagonals: across the lines x = const, or y = const. Cell (i, j) holds
  // faces 2q = (a, b, c) and 2q + 1 = (a, c, d), q = i kSide + j. A cut along
  // the grid's lines parts such pairs unless they move whole to one side.
  for (const bool across_x : {true, false}) {
    LChart l = l_chart(true);
    std::vector<int> polygon(l.mesh.face_count());
    std::iota(polygon.begin(), polygon.end(), 0);
    for (int q = 0; q < kSide * kSide; ++q) {
      if (across_x && q + kSide < kSide * kSide) polygon[2 * (q + kSide) + 1] = 2 * q;
      if (!across_x && (q + 1) % kSide != 0) polygon[2 * (q + 1)] = 2 * q + 1;
    }
    l.topology = build_topology(l.mesh.triangles, l.mesh.vertex_count(), polygon);
    ASSERT_EQ(cut_for_packing(l.mesh, l.topology, options(100.0), l.charts, RunControl{}).cuts, 1);
    std::vector<int> piece_of(l.mesh.face_count(), -1);
    for (size_t p = 0; p < l.charts.size(); ++p)
      for (int f : l.charts[p].faces) piece_of[f] = static_cast<int>(p);
    for (int f = 0; f < l.mesh.face_count(); ++f) {
      const int g = polygon[f];
      if (g != f && piece_of[f] >= 0 && piece_of[g] >= 0) {
        EXPECT_EQ(piece_of[f], piece_of[g]) << f << " " << g;
      }
    }
    for (const FlatChart& piece : l.charts) EXPECT_TRUE(is_disk(l.mesh, piece));
  }
}

TEST(PackingCuts, SolvedPiecesAreTurnedToTheirSmallestBoxAndStayDisks) {
  LChart l = l_chart(false);
  const PackingCutStats stats = cut_for_packing(l.mesh, l.topology, options(100.0), l.charts, RunControl{});
  ASSERT_EQ(stats.cuts, 1);
  for (const FlatChart& piece : l.charts) {
    EXPECT_TRUE(is_disk(l.mesh, piece));
    // A bar about kArm cells across (the cut may leave a cell of the
    // corner on either side), whichever way it was turned.
    const Eigen::RowVector2d extent = piece.corner_uv.colwise().maxCoeff() - piece.corner_uv.colwise().minCoeff();
    EXPECT_LE(extent.minCoeff(), kTexels * (kArm + 2) + 1e-6);
  }
}

TEST(PackingCuts, NoCutBeyondTheBudget) {
  LChart l = l_chart(true);
  const PackingCutStats stats = cut_for_packing(l.mesh, l.topology, options(0.5 * kArm), l.charts, RunControl{});
  EXPECT_EQ(stats.cuts, 0);
  EXPECT_EQ(stats.seam_added_3d, 0.0);
  EXPECT_EQ(l.charts.size(), 1u);
}

TEST(PackingCuts, ConvexChartIsLeftWhole) {
  const Mesh grid = atlas::testing::grid_disk(16);
  const MeshTopology topology = build_topology(grid.triangles, grid.vertex_count());
  std::vector<FlatChart> charts(1);
  for (int f = 0; f < grid.face_count(); ++f) charts[0].faces.push_back(f);
  charts[0].corner_uv = 64.0 * grid.corner_uv;  // a 64 x 64 texel square
  EXPECT_EQ(cut_for_packing(grid, topology, options(100.0), charts, RunControl{}).cuts, 0);
  EXPECT_EQ(charts.size(), 1u);
}

TEST(PackingCuts, AnnulusIsNotCutIntoNonDisks) {
  // One chart around a hole: no chord across its ring parts it.
  const Mesh ring = atlas::testing::annulus(4, 48, 48);
  const MeshTopology topology = build_topology(ring.triangles, ring.vertex_count());
  std::vector<FlatChart> charts(1);
  charts[0].kept_original = true;
  for (int f = 0; f < ring.face_count(); ++f) charts[0].faces.push_back(f);
  charts[0].corner_uv.resize(3 * ring.face_count(), 2);
  for (int f = 0; f < ring.face_count(); ++f)
    for (int k = 0; k < 3; ++k) charts[0].corner_uv.row(3 * f + k) = ring.uv_texels(f, k).transpose();
  cut_for_packing(ring, topology, options(1e6), charts, RunControl{});
  EXPECT_EQ(charts.size(), 1u);
}

TEST(PackingCuts, SameCutsOnOneThreadAsOnMany) {
  auto run = [](int threads) {
    const int before = omp_get_max_threads();
    omp_set_num_threads(threads);
    LChart l = l_chart(false);
    cut_for_packing(l.mesh, l.topology, options(100.0), l.charts, RunControl{});
    omp_set_num_threads(before);
    return l.charts;
  };
  const std::vector<FlatChart> one = run(1), two = run(2);
  ASSERT_EQ(one.size(), two.size());
  for (size_t c = 0; c < one.size(); ++c) {
    EXPECT_EQ(one[c].faces, two[c].faces);
    EXPECT_EQ(one[c].corner_uv, two[c].corner_uv);
  }
}

}  // namespace
