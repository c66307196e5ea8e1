// Chart graph and aggregation on small constructed meshes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include <Eigen/Geometry>

#include "charts/aggregate.hpp"
#include "charts/chart_graph.hpp"
#include "charts/disk_merge.hpp"
#include "charts/mesh_holes.hpp"
#include "core/angle_defects.hpp"
#include "core/corners.hpp"
#include "core/geometry.hpp"
#include "flatten/fill_holes.hpp"
#include "test_meshes.hpp"

using namespace atlas;

namespace {

struct ChartRun {
  Mesh mesh;
  MeshTopology topology;
  ChartGraph graph;
  Aggregation aggregation;
};

ChartRun aggregate(Mesh mesh, AggregateOptions options = {}) {
  ChartRun r{std::move(mesh), {}, {}, {}};
  r.topology = build_topology(r.mesh.triangles, r.mesh.vertex_count());
  r.graph = build_chart_graph(r.mesh, r.topology, {});
  r.aggregation = aggregate_charts(r.mesh, r.topology, r.graph, options, RunControl());
  return r;
}

void expect_all_disks(const ChartRun& r) {
  DiskClusters check(r.mesh, r.topology, r.aggregation.face_chart, r.aggregation.chart_count(), r.aggregation.kept_seam);
  for (int c = 0; c < r.aggregation.chart_count(); ++c) EXPECT_TRUE(check.is_disk(c)) << "chart " << c;
}

// Edges that a partial merge left open: seams inside a chart between two of its original charts.
int open_edges(const ChartRun& r) {
  int n = 0;
  for (int e = 0; e < r.topology.edge_count(); ++e) n += r.aggregation.kept_seam[e] && !r.graph.self_seam[e];
  return n;
}

// Splits the n x n grid disk into cells x cells square charts.
Mesh checkered_grid(int n, int cells) {
  const Mesh disk = atlas::testing::grid_disk(n);
  std::vector<int> chart(disk.face_count());
  for (int f = 0; f < disk.face_count(); ++f) {
    const int i = f / 2 / n, j = f / 2 % n;
    chart[f] = i * cells / n * cells + j * cells / n;
  }
  return atlas::testing::with_chart_uvs(disk.positions, disk.triangles, chart);
}

// rows x columns quads on a cylinder of radius 1, wrapped `turn` radians
// round its axis; the first half of the columns is chart 0, the rest chart 1.
Mesh cylinder_sheet(int rows, int columns, double turn) {
  RowMatrixX3d positions((rows + 1) * (columns + 1), 3);
  for (int i = 0; i <= rows; ++i)
    for (int j = 0; j <= columns; ++j) {
      const double t = turn * j / columns;
      positions.row(i * (columns + 1) + j) << std::cos(t), std::sin(t), 3.0 * i / rows;
    }
  RowMatrixX3i triangles(2 * rows * columns, 3);
  std::vector<int> chart;
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < columns; ++j) {
      const int v = i * (columns + 1) + j, f = 2 * (i * columns + j);
      triangles.row(f) << v, v + columns + 1, v + 1;
      triangles.row(f + 1) << v + 1, v + columns + 1, v + columns + 2;
      chart.insert(chart.end(), 2, j < columns / 2 ? 0 : 1);
    }
  return atlas::testing::with_chart_uvs(positions, triangles, chart);
}

// The mesh with n loose triangles added, far from it and from each other,
// each a chart of its own: a scan's debris.
Mesh with_debris(Mesh mesh, int n) {
  const Eigen::Index v = mesh.positions.rows(), f = mesh.triangles.rows();
  mesh.positions.conservativeResize(v + 3 * n, 3);
  mesh.triangles.conservativeResize(f + n, 3);
  mesh.corner_uv.conservativeResize(3 * (f + n), 2);
  mesh.face_page.conservativeResize(f + n);
  for (int i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      mesh.positions.row(v + 3 * i + k) << 10.0 + i, k == 1, k == 2;
      mesh.corner_uv.row(3 * (f + i) + k) << (i + (k == 1)) / (n + 1.0), 0.01 * (k == 2);
    }
    mesh.triangles.row(f + i) << int(v) + 3 * i, int(v) + 3 * i + 1, int(v) + 3 * i + 2;
    mesh.face_page(f + i) = 0;
  }
  return mesh;
}

// The mesh without the faces `drop`: holes where they were.
Mesh without_faces(const Mesh& mesh, std::vector<int> drop) {
  std::sort(drop.begin(), drop.end());
  Mesh out = mesh;
  const Eigen::Index kept = mesh.face_count() - static_cast<Eigen::Index>(drop.size());
  out.triangles.resize(kept, 3);
  out.corner_uv.resize(3 * kept, 2);
  out.face_page.resize(kept);
  Eigen::Index at = 0;
  for (int f = 0; f < mesh.face_count(); ++f) {
    if (std::binary_search(drop.begin(), drop.end(), f)) continue;
    out.triangles.row(at) = mesh.triangles.row(f);
    out.corner_uv.middleRows(3 * at, 3) = mesh.corner_uv.middleRows(3 * f, 3);
    out.face_page[at++] = mesh.face_page[f];
  }
  return out;
}

// The 12 x 12 grid in 3 x 3 charts of 4 x 4 quads, with quads (1, 1) and
// (10, 10) cut out: a hole inside each of the two corner charts 0 and 8.
Mesh grid_with_two_holes() {
  return without_faces(checkered_grid(12, 3), {2 * (1 * 12 + 1), 2 * (1 * 12 + 1) + 1,  //
                                               2 * (10 * 12 + 10), 2 * (10 * 12 + 10) + 1});
}

// chi = V - E + F of triangles over vertex_count vertices.
long long euler_characteristic(const RowMatrixX3i& triangles, int vertex_count) {
  long long edges = 0;
  for_each_edge_run(corners_by_edge(static_cast<int>(3 * triangles.rows()),
                                    [&](int c) { return corner_vertex(triangles, c); }),
                    [&](int, int) { ++edges; });
  return vertex_count - edges + triangles.rows();
}

double sum(const std::vector<double>& values) {
  double total = 0;
  for (double v : values) total += v;
  return total;
}

}  // namespace

// Gauss-Bonnet: a closed surface's defects sum to 2 pi times its Euler
// characteristic, and a cylinder's interior vertices are flat.
TEST(AngleDefects, SumToTwoPiTimesTheEulerCharacteristic) {
  EXPECT_NEAR(sum(angle_defects(atlas::testing::uv_sphere(12, 16, 2))), 4 * M_PI, 1e-9);
  EXPECT_NEAR(sum(angle_defects(atlas::testing::torus(24, 12, 4))), 0, 1e-9);
  const Mesh sheet = cylinder_sheet(4, 8, M_PI);
  const std::vector<double> defect = angle_defects(sheet);
  EXPECT_NEAR(defect[2 * 9 + 4], 0, 1e-12);  // row 2, column 4: inside
}

// A sheet wrapped three quarters round a cylinder has a mean normal of 0.3
// (below min_normal_coherence) but no curvature inside: it unrolls flat, so
// its two halves merge, unless developable_curvature is 0.
TEST(Aggregate, ChartsOfACylinderMergePastAHemisphere) {
  const Mesh sheet = cylinder_sheet(16, 40, 1.5 * M_PI);  // 1,280 faces: above coherence_free_faces
  ASSERT_GT(sheet.face_count(), AggregateOptions{}.coherence_free_faces);
  const ChartRun merged = aggregate(sheet);
  EXPECT_EQ(merged.graph.chart_count(), 2);
  EXPECT_EQ(merged.aggregation.chart_count(), 1);
  expect_all_disks(merged);
  AggregateOptions hemisphere_only;
  hemisphere_only.developable_curvature = 0;
  hemisphere_only.reference_chart_faces = 0;  // 640 faces per chart would scale the exemption past 1,280
  const ChartRun gated = aggregate(sheet, hemisphere_only);
  EXPECT_EQ(gated.aggregation.chart_count(), 2);
  EXPECT_EQ(gated.aggregation.stops.normal_coherence, 1);
}

// corners_by_edge's counting sort gives std::sort's order: on a fan whose
// centre starts more edges than the insertion sort takes, on scattered
// triangles, and with indices far above the corner count (std::sort there).
TEST(CornersByEdge, SameOrderAsSortingThePairs) {
  std::vector<std::vector<int>> cases(3);
  for (int i = 0; i < 40; ++i) cases[0].insert(cases[0].end(), {0, i + 2, i + 1});  // a fan of 40 faces
  for (int i = 0; i < 300; ++i) cases[1].push_back((i * 7919) % 97);                // triangles over 97 vertices
  cases[2] = {1000001, 1000000, 1000002, 1000002, 1000000, 1000003};
  for (const std::vector<int>& corner_vertices : cases) {
    const int n = static_cast<int>(corner_vertices.size());
    const auto vertex_of = [&](int c) { return corner_vertices[c]; };
    std::vector<std::pair<std::int64_t, int>> expected;
    for (int c = 0; c < n; ++c) expected.push_back({atlas::edge_key(vertex_of(c), vertex_of(atlas::next_corner(c))), c});
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(atlas::corners_by_edge(n, vertex_of), expected);
  }
}

TEST(ChartGraph, CountsChartsAndSharedBorders) {
  const ChartRun r = aggregate(checkered_grid(8, 4));
  EXPECT_EQ(r.graph.chart_count(), 16);
  // 4x4 grid of squares: 2 * 4 * 3 = 24 adjacent pairs, each sharing 2 grid edges.
  ASSERT_EQ(r.graph.adjacency.size(), 24u);
  for (const ChartAdjacency& adj : r.graph.adjacency) {
    EXPECT_EQ(adj.shared_edges, 2);
    EXPECT_NEAR(adj.length_3d, 0.25, 1e-12);
    EXPECT_TRUE(adj.mergeable);
  }
  for (const ChartStats& s : r.graph.charts) {
    EXPECT_NEAR(s.area_3d, 1.0 / 16, 1e-12);
    EXPECT_NEAR(s.perimeter_3d, 1.0, 1e-12);
  }
}

TEST(ChartGraph, SeamLengthCountsEachInteriorSeamOnce) {
  const ChartRun r = aggregate(checkered_grid(8, 4));
  // Interior seams: 3 vertical + 3 horizontal lines of length 1 on a unit square.
  EXPECT_NEAR(seam_length_ratio(r.mesh, r.topology, r.mesh.corner_uv, r.mesh.face_page), 6.0, 1e-12);
}

TEST(Aggregate, DiskBecomesOneChart) {
  for (Weighting w : {Weighting::UV, Weighting::Surface}) {
    const ChartRun r = aggregate(checkered_grid(12, 6), {w});
    EXPECT_EQ(r.aggregation.chart_count(), 1);
    expect_all_disks(r);
  }
}

TEST(Aggregate, TargetStopsEarly) {
  AggregateOptions options;
  options.target_charts = 5;
  const ChartRun r = aggregate(checkered_grid(12, 6), options);
  EXPECT_EQ(r.aggregation.chart_count(), 5);
  expect_all_disks(r);
}

TEST(Aggregate, AnnulusRefusesToCloseTheRingWithoutPartialMerges) {
  AggregateOptions whole_borders;
  whole_borders.partial_merges = false;
  const ChartRun r = aggregate(atlas::testing::annulus(3, 24, 4), whole_borders);
  EXPECT_EQ(r.graph.chart_count(), 6);
  EXPECT_EQ(r.aggregation.chart_count(), 2);
  EXPECT_EQ(open_edges(r), 0);
  expect_all_disks(r);
}

TEST(Aggregate, TwoChartsSharingTwoArcsMergeLeavingOneArcOpen) {
  // Two half rings of an annulus touch along two radial arcs of 3 edges each.
  const ChartRun r = aggregate(atlas::testing::annulus(3, 24, 12));
  ASSERT_EQ(r.graph.chart_count(), 2);
  ASSERT_EQ(r.graph.adjacency.size(), 1u);
  EXPECT_EQ(r.graph.adjacency[0].shared_edges, 6);
  EXPECT_EQ(r.aggregation.chart_count(), 1);
  EXPECT_EQ(open_edges(r), 3);
  expect_all_disks(r);
  const AggregationStops& s = r.aggregation.stops;
  EXPECT_EQ(s.non_manifold + s.not_disk + s.normal_coherence + s.max_chart_faces + s.min_chart_fraction + s.feasible, 0);
}

// A chart curled round to touch itself at the hub of a fan (two fans there),
// and a triangle of that fan filling the notch between them: welding both
// shared edges would close a ring round the hub, leaving a hole. The arc is
// split at the hub, so one edge welds and the union is a disk.
TEST(Aggregate, ArcsSplitWhereAChartTouchesItself) {
  RowMatrixX3d positions(17, 3);
  positions.row(0) << 0, 0, 0;
  for (int i = 0; i < 8; ++i)
    for (int ring = 1; ring <= 2; ++ring)
      positions.row(ring == 1 ? 1 + i : 9 + i) << ring * std::cos(kPi * i / 4), ring * std::sin(kPi * i / 4), 0;
  std::vector<Eigen::Vector3i> tris;
  std::vector<int> cluster;
  auto w = [](int i) { return 1 + (i % 8); };
  auto u = [](int i) { return 9 + (i % 8); };
  for (int i = 0; i < 8; ++i) {  // the fan round the hub: 3 joins the notch, 7 is the hole
    tris.emplace_back(0, w(i), w(i + 1));
    cluster.push_back(i == 3 ? 1 : i == 7 ? -1 : 0);
  }
  for (int i : {6, 7, 0}) {  // the outer band that joins the fan's two sides
    tris.emplace_back(w(i), u(i), u(i + 1));
    tris.emplace_back(w(i), u(i + 1), w(i + 1));
    cluster.push_back(0), cluster.push_back(0);
  }
  RowMatrixX3i triangles(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f) triangles.row(f) = tris[f].transpose();
  const Mesh mesh = atlas::testing::with_chart_uvs(positions, triangles, std::vector<int>(tris.size(), 0));
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const std::vector<char> no_seams(topology.edge_count(), 0);
  DiskClusters whole(mesh, topology, cluster, 2, no_seams, false);
  ASSERT_TRUE(whole.is_disk(0));
  EXPECT_FALSE(whole.check_merge(0, 1));
  DiskClusters partial(mesh, topology, cluster, 2, no_seams, true);
  const MergeCheck check = partial.check_merge(0, 1);
  ASSERT_TRUE(check);
  EXPECT_EQ(check.left_open.size(), 1u);
  EXPECT_TRUE(partial.is_disk(partial.merge(0, 1, check)));
}

// The two hemispheres of a closed surface share their whole border, one loop:
// welded whole they would close a sphere, so half the loop is welded and the
// other half stays a seam inside the union, which is a disk.
TEST(DiskClusters, HalvesOfAClosedSurfaceMergeWithHalfTheirLoopOpen) {
  const Mesh mesh = atlas::testing::uv_sphere(12, 16, 2);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  std::vector<int> cluster(mesh.face_count());
  for (int f = 0; f < mesh.face_count(); ++f) {
    const double z = (mesh.positions.row(mesh.triangles(f, 0)) + mesh.positions.row(mesh.triangles(f, 1)) +
                      mesh.positions.row(mesh.triangles(f, 2)))(2);
    cluster[f] = z > 0 ? 0 : 1;
  }
  const std::vector<char> no_seams(topology.edge_count(), 0);
  DiskClusters whole(mesh, topology, cluster, 2, no_seams, false);
  ASSERT_TRUE(whole.is_disk(0) && whole.is_disk(1));
  EXPECT_FALSE(whole.check_merge(0, 1));
  DiskClusters partial(mesh, topology, cluster, 2, no_seams, true);
  const MergeCheck check = partial.check_merge(0, 1);
  ASSERT_TRUE(check);
  double loop = 0;
  for (int e = 0; e < topology.edge_count(); ++e) {
    const int f0 = topology.edge_corners[topology.edge_offsets[e]] / 3;
    const int f1 = topology.edge_corners[topology.edge_offsets[e] + 1] / 3;
    if (cluster[f0] != cluster[f1]) loop += edge_length(mesh, topology, e);
  }
  EXPECT_NEAR(check.open_length, loop / 2, loop / 16 + 1e-9);  // the equator's 16 edges, halved
  EXPECT_TRUE(partial.is_disk(partial.merge(0, 1, check)));
}

// Two triangles touching at a vertex, together one hole in a grid chart:
// welding either alone leaves the hole (chi stays 0), the second closes it.
// Scanners leave such pairs inside their charts; each must be allowed to
// merge even though the first merge alone makes no disk.
TEST(Aggregate, IslandsThatFillOneHoleTogetherMerge) {
  const Mesh mesh = atlas::testing::grid_disk(6);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  auto shares = [&](int f, int g) {
    int n = 0;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) n += mesh.triangles(f, i) == mesh.triangles(g, j);
    return n;
  };
  auto interior = [&](int f) {
    for (int k = 0; k < 3; ++k)
      if (topology.edge_valence(topology.corner_edge[3 * f + k]) != 2) return false;
    return true;
  };
  const int first = 2 * (2 * 6 + 2);  // a triangle of quad (2, 2)
  int second = -1;
  for (int g = 0; g < mesh.face_count() && second < 0; ++g)
    if (shares(first, g) == 1 && interior(g)) {
      bool apart = true;  // no third triangle touches both across edges
      for (int h = 0; h < mesh.face_count(); ++h) apart = apart && !(h != g && h != first && shares(first, h) == 3);
      if (apart) second = g;
    }
  ASSERT_TRUE(interior(first));
  ASSERT_GE(second, 0);
  std::vector<int> cluster(mesh.face_count(), 0);
  cluster[first] = 1, cluster[second] = 2;
  DiskClusters disks(mesh, topology, cluster, 3, std::vector<char>(topology.edge_count(), 0));
  ASSERT_FALSE(disks.is_disk(0));
  const MergeCheck one = disks.check_merge(0, 1);
  ASSERT_TRUE(one);
  const int grown = disks.merge(0, 1, one);
  EXPECT_FALSE(disks.is_disk(grown));
  const MergeCheck two = disks.check_merge(grown, 2);
  ASSERT_TRUE(two);
  EXPECT_TRUE(disks.is_disk(disks.merge(grown, 2, two)));
}

TEST(MeshHoles, EveryBorderLoopButThePiecesLongestIsAHole) {
  const Mesh mesh = grid_with_two_holes();
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const MeshHoles holes = mesh_holes(mesh, topology);
  ASSERT_EQ(holes.edges, (std::vector<int>{4, 4}));
  int border = 0, on_holes = 0;
  for (int e = 0; e < topology.edge_count(); ++e)
    border += topology.edge_valence(e) == 1, on_holes += holes.edge_hole[e] >= 0;
  EXPECT_EQ(border, 48 + 8);  // the grid's outline is no hole
  EXPECT_EQ(on_holes, 8);
  // A loop with an edge that may not be a hole is none.
  std::vector<char> may_be_hole(topology.edge_count(), 1);
  for (int e = 0; e < topology.edge_count(); ++e)
    if (holes.edge_hole[e] == 0) may_be_hole[e] = 0;
  EXPECT_EQ(mesh_holes(mesh, topology, may_be_hole).edges, (std::vector<int>{4}));
}

// A vertex the weld missed (two copies at one point, the faces left of it
// on one, those right of it on the other) leaves a crack of four border
// edges and no area: no hole, which filled would force the crack open.
TEST(MeshHoles, ACrackIsNoHole) {
  const int n = 6, middle = 3 * (n + 1) + 3;
  Mesh mesh = atlas::testing::grid_disk(n);
  mesh.positions.conservativeResize(mesh.vertex_count() + 1, 3);
  mesh.positions.row(mesh.vertex_count() - 1) = mesh.positions.row(middle);
  for (int f = 0; f < mesh.face_count(); ++f) {
    double x = 0;
    for (int k = 0; k < 3; ++k) x += mesh.positions(mesh.triangles(f, k), 0) / 3;
    for (int k = 0; k < 3; ++k)
      if (mesh.triangles(f, k) == middle && x < 0.5) mesh.triangles(f, k) = mesh.vertex_count() - 1;
  }
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  int border = 0;
  for (int e = 0; e < topology.edge_count(); ++e) border += topology.edge_valence(e) == 1;
  ASSERT_EQ(border, 4 * n + 4);
  EXPECT_TRUE(mesh_holes(mesh, topology).edges.empty());
}

TEST(Aggregate, ChartsAroundHolesOfTheMeshMergeIntoOne) {
  ChartRun r{grid_with_two_holes(), {}, {}, {}};
  r.topology = build_topology(r.mesh.triangles, r.mesh.vertex_count());
  r.graph = build_chart_graph(r.mesh, r.topology, {});
  ASSERT_EQ(r.graph.chart_count(), 9);
  // Counting every hole, no chart can hold both: two charts are left.
  EXPECT_EQ(aggregate_charts(r.mesh, r.topology, r.graph, {}, RunControl()).chart_count(), 2);
  r.graph.holes = mesh_holes(r.mesh, r.topology);
  r.aggregation = aggregate_charts(r.mesh, r.topology, r.graph, {}, RunControl());
  EXPECT_EQ(r.aggregation.chart_count(), 1);
  EXPECT_EQ(open_edges(r), 0);
  EXPECT_EQ(r.aggregation.stops.not_disk, 0);
}

// A cluster round a hole of the mesh that touches the hole's border at a
// vertex from two sides (a quad of another cluster fills the corner there)
// does not enclose it: the hole and that quad's notch are one gap of its
// border. Once the quad joins, the hole is a loop of its own, and counts.
TEST(DiskClusters, AHoleCountsOnceItsBorderIsALoopOfItsOwn) {
  const int n = 6, hole = 2 * (2 * n + 2), wedge = 2 * (3 * n + 3) - 2;  // quad (3, 3), after the hole's 2 faces
  const Mesh mesh = without_faces(atlas::testing::grid_disk(n), {hole, hole + 1});
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  std::vector<int> cluster(mesh.face_count(), 0);
  cluster[wedge] = cluster[wedge + 1] = 1;
  DiskClusters disks(mesh, topology, cluster, 2, std::vector<char>(topology.edge_count(), 0), false,
                     mesh_holes(mesh, topology));
  EXPECT_FALSE(disks.is_disk(0));
  EXPECT_TRUE(disks.is_disk(1));
  const MergeCheck check = disks.check_merge(0, 1);
  ASSERT_TRUE(check);
  EXPECT_TRUE(disks.is_disk(disks.merge(0, 1, check)));
}

TEST(FillHoles, AWholeHoleGetsACentreAndFacesWoundLikeTheChart) {
  const Mesh mesh = grid_with_two_holes();
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const MeshHoles holes = mesh_holes(mesh, topology);
  std::vector<int> faces(mesh.face_count());
  std::iota(faces.begin(), faces.end(), 0);
  RowMatrixX3i triangles = mesh.triangles;
  std::vector<int> vertices(mesh.vertex_count());
  std::iota(vertices.begin(), vertices.end(), 0);
  ASSERT_EQ(euler_characteristic(triangles, mesh.vertex_count()), -1);  // a disk with two holes
  const RowMatrixX3d centres = fill_holes(mesh, topology, holes, faces, triangles, vertices);
  ASSERT_EQ(centres.rows(), 2);
  EXPECT_EQ(triangles.rows(), mesh.face_count() + 8);
  EXPECT_EQ(vertices.back(), mesh.vertex_count() + 1);
  EXPECT_EQ(euler_characteristic(triangles, static_cast<int>(vertices.size())), 1);
  // Wound like the chart: every edge runs once each way between its two faces.
  const auto keyed = corners_by_edge(static_cast<int>(3 * triangles.rows()),
                                     [&](int c) { return corner_vertex(triangles, c); });
  for_each_edge_run(keyed, [&](int first, int count) {
    if (count != 2) return;
    const int a = keyed[first].second, b = keyed[first + 1].second;
    EXPECT_EQ(corner_vertex(triangles, a), corner_vertex(triangles, next_corner(b)));
  });
  // The centre of the hole in quad (1, 1) of the unit square's 12 x 12 grid.
  const Eigen::RowVector3d middle(1.5 / 12, 1.5 / 12, 0);
  EXPECT_LT(std::min((centres.row(0) - middle).norm(), (centres.row(1) - middle).norm()), 1e-12);
}

TEST(FillHoles, AHoleThatTheChartHoldsInPartStaysOpen) {
  const Mesh mesh = grid_with_two_holes();
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  std::vector<int> faces;
  for (int f = 0; f < mesh.face_count(); ++f)
    if (mesh.positions(mesh.triangles(f, 0), 1) > 0.5) faces.push_back(f);  // the upper half only
  RowMatrixX3i triangles(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t i = 0; i < faces.size(); ++i) triangles.row(i) = mesh.triangles.row(faces[i]);
  std::vector<int> vertices(mesh.vertex_count());
  std::iota(vertices.begin(), vertices.end(), 0);
  const RowMatrixX3d centres = fill_holes(mesh, topology, mesh_holes(mesh, topology), faces, triangles, vertices);
  EXPECT_EQ(centres.rows(), 1);  // the hole at (10, 10); the one at (1, 1) has no face here
  EXPECT_EQ(triangles.rows(), static_cast<Eigen::Index>(faces.size()) + 4);
}

TEST(Aggregate, ClosedSurfacesEndAsDisks) {
  AggregateOptions topology_only;
  topology_only.min_normal_coherence = 0;
  // A sphere closes up when its last two charts meet along a whole loop:
  // half the loop is welded and half left open, so one disk covers it.
  const ChartRun sphere = aggregate(atlas::testing::uv_sphere(12, 16, 2), topology_only);
  EXPECT_GT(sphere.graph.chart_count(), 1);
  EXPECT_EQ(sphere.aggregation.chart_count(), 1);
  EXPECT_GT(open_edges(sphere), 0);
  expect_all_disks(sphere);
  // A torus has genus one: a single disk covers it only with arcs left open
  // inside it, which partial merges do.
  const ChartRun torus = aggregate(atlas::testing::torus(24, 12, 4), topology_only);
  EXPECT_EQ(torus.graph.chart_count(), 24);
  EXPECT_EQ(torus.aggregation.chart_count(), 1);
  EXPECT_GT(open_edges(torus), 0);
  expect_all_disks(torus);
}

namespace {

// Per aggregated chart: |sum_f A_f n_f| / sum_f A_f.
std::vector<double> normal_coherence(const ChartRun& r) {
  std::vector<Eigen::Vector3d> normal(r.aggregation.chart_count(), Eigen::Vector3d::Zero());
  std::vector<double> area(r.aggregation.chart_count(), 0);
  for (int f = 0; f < r.mesh.face_count(); ++f) {
    const Eigen::Vector3d a = r.mesh.positions.row(r.mesh.triangles(f, 0));
    const Eigen::Vector3d b = r.mesh.positions.row(r.mesh.triangles(f, 1));
    const Eigen::Vector3d c = r.mesh.positions.row(r.mesh.triangles(f, 2));
    const Eigen::Vector3d n = 0.5 * (b - a).cross(c - a);
    normal[r.aggregation.face_chart[f]] += n;
    area[r.aggregation.face_chart[f]] += n.norm();
  }
  std::vector<double> out;
  for (size_t c = 0; c < normal.size(); ++c) out.push_back(normal[c].norm() / area[c]);
  return out;
}

}  // namespace

// A sphere is curved everywhere: developable_curvature lets no chart past a
// hemisphere either.
TEST(Aggregate, NoChartWiderThanAHemisphere) {
  AggregateOptions gate_all;
  gate_all.coherence_free_faces = 0;
  const ChartRun sphere = aggregate(atlas::testing::uv_sphere(24, 32, 1), gate_all);
  EXPECT_GE(sphere.aggregation.chart_count(), 2);  // a closed sphere needs two hemispheres at least
  const std::vector<double> coherence = normal_coherence(sphere);
  for (size_t c = 0; c < coherence.size(); ++c) EXPECT_GE(coherence[c], 0.5) << c;
  expect_all_disks(sphere);
}

// Below coherence_free_faces the gate does not apply: on a small sphere some
// chart grows past a hemisphere.
TEST(Aggregate, SmallChartsMergePastAHemisphere) {
  const Mesh mesh = atlas::testing::uv_sphere(24, 32, 1);
  AggregateOptions gate_large;
  gate_large.coherence_free_faces = mesh.face_count();
  const ChartRun sphere = aggregate(mesh, gate_large);
  const std::vector<double> coherence = normal_coherence(sphere);
  EXPECT_LT(*std::min_element(coherence.begin(), coherence.end()), 0.5);
  expect_all_disks(sphere);
}

// The cylinder sheet below at four times the faces (twice the rows and
// columns, the same two charts) merges alike past the hemisphere and the
// cap: the gates' face counts scale with the faces per input chart.
TEST(Aggregate, FinerTessellationMergesAlike) {
  AggregateOptions options;
  options.developable_curvature = 0;  // the face counts alone decide
  options.coherence_free_faces = 1280;
  options.reference_chart_faces = 640;  // the coarse sheet's
  const ChartRun coarse = aggregate(cylinder_sheet(16, 40, 1.5 * M_PI), options);
  const ChartRun fine = aggregate(cylinder_sheet(32, 80, 1.5 * M_PI), options);
  ASSERT_EQ(fine.graph.chart_count(), 2);
  EXPECT_EQ(coarse.aggregation.chart_count(), 1);
  EXPECT_EQ(fine.aggregation.chart_count(), 1);
  expect_all_disks(fine);
  // Loose triangles do not count as the surface's tessellation.
  EXPECT_EQ(aggregate(with_debris(cylinder_sheet(32, 80, 1.5 * M_PI), 200), options).aggregation.chart_count(), 201);
  options.reference_chart_faces = 0;
  EXPECT_EQ(aggregate(cylinder_sheet(32, 80, 1.5 * M_PI), options).aggregation.chart_count(), 2);
  AggregateOptions capped;  // so does the cap
  capped.max_chart_faces = 1280;
  capped.reference_chart_faces = 640;
  EXPECT_EQ(aggregate(cylinder_sheet(32, 80, 1.5 * M_PI), capped).aggregation.chart_count(), 1);
  capped.reference_chart_faces = 0;
  EXPECT_EQ(aggregate(cylinder_sheet(32, 80, 1.5 * M_PI), capped).aggregation.chart_count(), 2);
  // Nine times finer, the cap stops at four times: two charts of 5,760 faces
  // merge under a cap of 2,880, not 2,879.
  capped.reference_chart_faces = 640;
  const Mesh finest = cylinder_sheet(48, 120, 1.5 * M_PI);
  capped.max_chart_faces = 2880;
  EXPECT_EQ(aggregate(finest, capped).aggregation.chart_count(), 1);
  capped.max_chart_faces = 2879;
  EXPECT_EQ(aggregate(finest, capped).aggregation.chart_count(), 2);
}

TEST(Aggregate, NeverMergesAcrossNonManifoldEdge) {
  const ChartRun r = aggregate(atlas::testing::nonmanifold_fin());
  EXPECT_EQ(r.graph.chart_count(), 3);
  for (const ChartAdjacency& adj : r.graph.adjacency) EXPECT_FALSE(adj.mergeable);
  EXPECT_EQ(r.aggregation.chart_count(), 3);
}

TEST(Aggregate, CancelStopsTheRun) {
  const Mesh mesh = checkered_grid(64, 32);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const ChartGraph graph = build_chart_graph(mesh, topology, {});
  RunControl control;
  control.cancel();
  EXPECT_THROW(aggregate_charts(mesh, topology, graph, {}, control), Cancelled);
}

TEST(Aggregate, ChartsUnrolledFromATubeAreDisksAndMerge) {
  // Two strips, each closing round the tube in 3D but cut at its own UV seam.
  AggregateOptions topology_only;
  topology_only.min_normal_coherence = 0;  // a whole tube has no mean normal
  const ChartRun tube = aggregate(atlas::testing::unrolled_tube(6, 12, 3), topology_only);
  ASSERT_EQ(tube.graph.chart_count(), 2);
  EXPECT_EQ(tube.aggregation.chart_count(), 1);
  EXPECT_EQ(tube.aggregation.stops.not_disk, 0);
  expect_all_disks(tube);
  // Glued at its seam, each strip would be an annulus that could never merge.
  DiskClusters glued(tube.mesh, tube.topology, tube.graph.face_chart, 2,
                     std::vector<char>(tube.topology.edge_count(), 0));
  EXPECT_FALSE(glued.is_disk(0));
  EXPECT_FALSE(glued.check_merge(0, 1));
}

TEST(Aggregate, StopsNameWhatRefusedTheLastMerges) {
  // An annulus of 8 charts ends as at least two: the last merge would close
  // the ring, and nothing but topology refuses it.
  AggregateOptions topology_only;
  topology_only.min_normal_coherence = 0;
  topology_only.partial_merges = false;
  const ChartRun ring = aggregate(atlas::testing::annulus(2, 16, 2), topology_only);
  EXPECT_GE(ring.aggregation.chart_count(), 2);
  const AggregationStops& s = ring.aggregation.stops;
  EXPECT_GT(s.not_disk, 0);
  EXPECT_EQ(s.non_manifold + s.normal_coherence + s.max_chart_faces + s.min_chart_fraction + s.feasible, 0);
  // A target stops it early, with feasible merges left.
  AggregateOptions target = topology_only;
  target.target_charts = 6;
  EXPECT_GT(aggregate(atlas::testing::annulus(2, 16, 2), target).aggregation.stops.feasible, 0);
}
