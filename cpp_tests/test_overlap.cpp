// Overlap detection and the backtracking that splits overlapping charts.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numeric>

#include "charts/aggregate.hpp"
#include "charts/chart_graph.hpp"
#include "charts/mesh_holes.hpp"
#include "core/bucket_grid.hpp"
#include "core/corners.hpp"
#include "core/geometry.hpp"
#include "flatten/cut_to_disk.hpp"
#include "flatten/fill_holes.hpp"
#include "flatten/flatten_without_overlap.hpp"
#include "core/union_find.hpp"
#include "test_meshes.hpp"

using namespace atlas;

namespace {

// A strip winding 3 turns up a helix, width along the radius: each short
// piece is nearly flat, but flattening the whole strip without distortion
// curls it like an annulus, so it must cross itself.
Mesh helical_strip(int segments, int segments_per_chart) {
  RowMatrixX3d positions(2 * (segments + 1), 3);
  for (int i = 0; i <= segments; ++i) {
    const double t = 6.0 * 3.14159265358979 * i / segments;
    for (int side = 0; side < 2; ++side) {
      const double r = 1.0 + 0.5 * side;
      positions.row(2 * i + side) << r * std::cos(t), r * std::sin(t), 0.05 * t;
    }
  }
  RowMatrixX3i triangles(2 * segments, 3);
  std::vector<int> chart(2 * segments);
  for (int i = 0; i < segments; ++i) {
    const int a = 2 * i, b = 2 * i + 1, c = 2 * i + 3, d = 2 * i + 2;
    triangles.row(2 * i) << a, b, c;
    triangles.row(2 * i + 1) << a, c, d;
    chart[2 * i] = chart[2 * i + 1] = i / segments_per_chart;
  }
  return atlas::testing::with_chart_uvs(positions, triangles, chart);
}

// Whether a flattened piece's boundary crosses itself. Its corner UVs come per
// face; the mesh's vertex indices give them back their sharing, which holds
// for the pieces here (disks with no vertex split by a cut or a pinch).
bool piece_crosses_itself(const Mesh& mesh, const FlatChart& piece) {
  RowMatrixX3i t(static_cast<Eigen::Index>(piece.faces.size()), 3);
  RowMatrixX2d uv = RowMatrixX2d::Zero(mesh.vertex_count(), 2);
  for (size_t i = 0; i < piece.faces.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      t(i, k) = mesh.triangles(piece.faces[i], k);
      uv.row(t(i, k)) = piece.corner_uv.row(3 * i + k);
    }
  return boundary_self_intersects(t, uv);
}

std::vector<int> identity(int n) {
  std::vector<int> v(n);
  for (int i = 0; i < n; ++i) v[i] = i;
  return v;
}

}  // namespace

TEST(Overlap, DetectsCrossingBoundary) {
  // An open fan around vertex 0; moving its last vertex across the fan makes
  // the boundary edge 3-4 cross the boundary edge 1-2.
  RowMatrixX3i t(3, 3);
  t << 0, 1, 2, 0, 2, 3, 0, 3, 4;
  RowMatrixX2d uv(5, 2);
  uv << 0, 0, 1, 0, 0, 1, -1, 0, 0, -1;
  EXPECT_FALSE(boundary_self_intersects(t, uv));
  uv.row(4) << 1.5, 0.5;
  EXPECT_TRUE(boundary_self_intersects(t, uv));
}

// SLIM may unroll the strip (energy ~4.15) or curl it (energy 4, overlapping,
// then split): either way no piece may overlap and every face must be placed.
TEST(Overlap, HelicalStripEndsWithoutOverlap) {
  const Mesh mesh = helical_strip(480, 8);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const ChartGraph graph = build_chart_graph(mesh, topology, {});
  ASSERT_EQ(graph.chart_count(), 60);
  const Aggregation merged = aggregate_charts(mesh, topology, graph, {}, RunControl());
  ASSERT_EQ(merged.chart_count(), 1);

  std::vector<std::vector<int>> chart_faces(graph.chart_count());
  for (int f = 0; f < mesh.face_count(); ++f) chart_faces[graph.face_chart[f]].push_back(f);
  FlattenStats stats;
  const auto pieces =
      flatten_without_overlap(mesh, topology, graph, chart_faces, merged.members[0], merged.merges, {}, RunControl(), stats);
  size_t faces = 0;
  for (const FlatChart& piece : pieces) {
    faces += piece.faces.size();
    EXPECT_FALSE(piece_crosses_itself(mesh, piece));
    EXPECT_TRUE(piece.corner_uv.allFinite());
  }
  EXPECT_EQ(faces, static_cast<size_t>(mesh.face_count()));
}

TEST(Overlap, ClosedSurfaceIsSplitIntoDisks) {
  const Mesh torus = atlas::testing::torus(24, 12, 4);
  const MeshTopology topology = build_topology(torus.triangles, torus.vertex_count());
  const ChartGraph graph = build_chart_graph(torus, topology, {});
  std::vector<std::vector<int>> chart_faces(graph.chart_count());
  for (int f = 0; f < torus.face_count(); ++f) chart_faces[graph.face_chart[f]].push_back(f);
  std::vector<int> all(graph.chart_count());
  for (int c = 0; c < graph.chart_count(); ++c) all[c] = c;
  FlattenStats stats;
  const auto pieces = flatten_without_overlap(torus, topology, graph, chart_faces, all, {}, {}, RunControl(), stats);
  EXPECT_GE(stats.not_disk, 1);
  EXPECT_GE(pieces.size(), 2u);
  size_t faces = 0;
  for (const FlatChart& piece : pieces) faces += piece.faces.size();
  EXPECT_EQ(faces, static_cast<size_t>(torus.face_count()));
}

TEST(Overlap, HalvingAFoldedChartKeepsItsQuadsWhole) {
  // A torus of quads (two triangles each) mapped as one chart seen from
  // above: its top and bottom fold onto each other, and a torus cannot be cut
  // into a disk, so the chart is halved until its pieces flatten.
  const Mesh shape = atlas::testing::torus(24, 12, 24);
  RowMatrixX2d uv(3 * static_cast<Eigen::Index>(shape.face_count()), 2);
  for (int f = 0; f < shape.face_count(); ++f)
    for (int k = 0; k < 3; ++k)
      uv.row(3 * f + k) = (shape.positions.row(shape.triangles(f, k)).head<2>() / 6).array() + 0.5;
  const Mesh mesh = make_mesh(shape.positions, shape.triangles, uv, Eigen::VectorXi::Zero(shape.face_count()),
                              {PageSize{1024, 1024}});
  std::vector<int> quad(mesh.face_count());
  for (int f = 0; f < mesh.face_count(); ++f) quad[f] = f / 2;
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count(), quad);
  const ChartGraph graph = build_chart_graph(mesh, topology, {});
  ASSERT_EQ(graph.chart_count(), 1);
  std::vector<std::vector<int>> chart_faces(1);
  for (int f = 0; f < mesh.face_count(); ++f) chart_faces[0].push_back(f);
  FlattenStats stats;
  const auto pieces = flatten_without_overlap(mesh, topology, graph, chart_faces, {0}, {}, {}, RunControl(), stats);
  EXPECT_GE(stats.overlap_halved, 1);
  std::vector<int> piece_of(mesh.face_count(), -1);
  for (size_t p = 0; p < pieces.size(); ++p)
    for (int f : pieces[p].faces) piece_of[f] = static_cast<int>(p);
  for (int f = 0; f < mesh.face_count(); f += 2) EXPECT_EQ(piece_of[f], piece_of[f + 1]) << "quad " << f / 2;
}

TEST(CutToDisk, AnnulusOpensIntoADisk) {
  const Mesh ring = atlas::testing::annulus(3, 24, 24);
  RowMatrixX3i t = ring.triangles;
  std::vector<int> source = identity(ring.vertex_count());
  EXPECT_TRUE(cut_to_disk(t, source));
  EXPECT_GT(static_cast<int>(source.size()), ring.vertex_count());  // the cut doubled a path
}

TEST(CutToDisk, TorusIsNotADisk) {
  const Mesh torus = atlas::testing::torus(12, 8, 12);
  RowMatrixX3i t = torus.triangles;
  std::vector<int> source = identity(torus.vertex_count());
  EXPECT_FALSE(cut_to_disk(t, source));
}

namespace {

// Quads (a, b, c, d) as triangles (a, b, c) and (a, c, d): the corners
// whose edge is the diagonal a-c are set in *uncut.
RowMatrixX3i split_quads(const std::vector<std::array<int, 4>>& quads, std::vector<char>* uncut) {
  RowMatrixX3i t(2 * static_cast<Eigen::Index>(quads.size()), 3);
  uncut->assign(3 * t.rows(), 0);
  for (size_t q = 0; q < quads.size(); ++q) {
    const auto [a, b, c, d] = quads[q];
    t.row(2 * q) << a, b, c;
    t.row(2 * q + 1) << a, c, d;
    (*uncut)[6 * q + 2] = (*uncut)[6 * q + 3] = 1;
  }
  return t;
}

// Corners set in uncut whose edge the cut made boundary (one corner left on it).
int diagonals_cut(const RowMatrixX3i& t, const std::vector<char>& uncut) {
  const auto keyed = corners_by_edge(static_cast<int>(3 * t.rows()), [&](int c) { return corner_vertex(t, c); });
  int cut = 0;
  for_each_edge_run(keyed, [&](int first, int count) { cut += count == 1 && uncut[keyed[first].second]; });
  return cut;
}

}  // namespace

TEST(CutToDisk, CutsGoAroundTheDiagonalsOfQuads) {
  std::vector<char> uncut;
  // A tube of four quads, one ring high: the first path from the bottom loop
  // to the top one that the search meets is a diagonal.
  std::vector<std::array<int, 4>> tube;
  for (int i = 0; i < 4; ++i) tube.push_back({i, (i + 1) % 4, 4 + (i + 1) % 4, 4 + i});
  RowMatrixX3i t = split_quads(tube, &uncut);
  std::vector<int> source = identity(8);
  ASSERT_TRUE(cut_to_disk(t, source, uncut));
  EXPECT_EQ(diagonals_cut(t, uncut), 0);
  // A closed cube of six quads: the slit that opens it takes no diagonal either.
  const std::vector<std::array<int, 4>> cube = {{0, 1, 2, 3}, {7, 6, 5, 4}, {0, 4, 5, 1},
                                                {1, 5, 6, 2}, {2, 6, 7, 3}, {3, 7, 4, 0}};
  t = split_quads(cube, &uncut);
  source = identity(8);
  ASSERT_TRUE(cut_to_disk(t, source, uncut));
  EXPECT_EQ(diagonals_cut(t, uncut), 0);
}

TEST(CutToDisk, ClosedSurfaceIsSlitOpen) {
  const Mesh sphere = atlas::testing::uv_sphere(8, 12, 8);
  RowMatrixX3i t = sphere.triangles;
  std::vector<int> source = identity(sphere.vertex_count());
  EXPECT_TRUE(cut_to_disk(t, source));
  EXPECT_EQ(static_cast<int>(source.size()), sphere.vertex_count() + 1);  // one vertex split by the slit
}

namespace {

// Every piece must wind one way only: no face flipped against the others.
void expect_no_flips(const std::vector<FlatChart>& pieces) {
  for (const FlatChart& piece : pieces) {
    int positive = 0, negative = 0;
    for (size_t i = 0; i < piece.faces.size(); ++i) {
      const double a = signed_area(piece.corner_uv.row(3 * i), piece.corner_uv.row(3 * i + 1),
                                   piece.corner_uv.row(3 * i + 2));
      positive += a > 0, negative += a < 0;
    }
    EXPECT_TRUE(positive == 0 || negative == 0) << positive << " faces one way, " << negative << " the other";
  }
}

std::vector<FlatChart> flatten_single_chart(const Mesh& mesh, FlattenStats& stats) {
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const ChartGraph graph = build_chart_graph(mesh, topology, {});
  EXPECT_EQ(graph.chart_count(), 1);
  std::vector<std::vector<int>> chart_faces(1, identity(mesh.face_count()));
  auto pieces = flatten_without_overlap(mesh, topology, graph, chart_faces, {0}, {}, {}, RunControl(), stats);
  size_t faces = 0;
  for (const FlatChart& piece : pieces) {
    faces += piece.faces.size();
    EXPECT_TRUE(piece.corner_uv.allFinite());
  }
  EXPECT_EQ(faces, static_cast<size_t>(mesh.face_count()));
  return pieces;
}

}  // namespace

TEST(Overlap, LoneChartFoldedInUvIsUnfolded) {
  // One chart whose right half is mirrored over onto its left half in UV.
  Mesh mesh = atlas::testing::grid_disk(8, 100.0 / 256);
  for (Eigen::Index c = 0; c < mesh.corner_uv.rows(); ++c)
    mesh.corner_uv(c, 0) = 50.0 / 256 - std::abs(mesh.corner_uv(c, 0) - 50.0 / 256);
  FlattenStats stats;
  const auto pieces = flatten_single_chart(mesh, stats);
  expect_no_flips(pieces);
  EXPECT_EQ(pieces.size(), 1u);  // a flat disk: flattened whole
}

TEST(Overlap, LoneClosedChartIsUnfolded) {
  // A closed surface under one continuous UV map always covers part of its
  // image twice, with opposite windings.
  Mesh sphere = atlas::testing::uv_sphere(6, 8, 6);
  for (Eigen::Index f = 0; f < sphere.face_count(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = sphere.positions.row(sphere.triangles(f, k));
      sphere.corner_uv.row(3 * f + k) << 0.5 + 0.2 * p.x(), 0.5 + 0.2 * p.y();
    }
  FlattenStats stats;
  const auto pieces = flatten_single_chart(sphere, stats);
  expect_no_flips(pieces);
}

TEST(Overlap, LoneChartCrossingItselfInUvIsUncrossed) {
  // One chart whose UVs wind 1.2 turns round an annulus: no face flipped, but
  // the end of the strip lies over its start.
  Mesh mesh = atlas::testing::grid_disk(12, 1.0, 1024);
  for (Eigen::Index f = 0; f < mesh.face_count(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.positions.row(mesh.triangles(f, k));
      const double angle = 2.4 * 3.14159265358979 * p.x(), radius = 0.4 - 0.2 * p.y();
      mesh.corner_uv.row(3 * f + k) << 0.5 + radius * std::cos(angle), 0.5 + radius * std::sin(angle);
    }
  FlattenStats stats;
  const auto pieces = flatten_single_chart(mesh, stats);
  expect_no_flips(pieces);
  for (const FlatChart& piece : pieces) {
    EXPECT_FALSE(piece_crosses_itself(mesh, piece));
    EXPECT_FALSE(piece.kept_original);
  }
}

namespace {

// A spherical cap reaching polar angle `extent` (radians): rings x 6 sectors
// cells of quads around the pole, each cell of 3 rings by 6 quads its own
// nearly flat chart. Merged, they bend too far to flatten without squeezing.
Mesh sector_cap(int rings, int sectors, double extent) {
  const int around = 6 * sectors;
  RowMatrixX3d positions(1 + rings * around, 3);
  positions.row(0) << 0, 0, 1;
  for (int r = 1; r <= rings; ++r)
    for (int s = 0; s < around; ++s) {
      const double phi = extent * r / rings, theta = 2 * kPi * s / around;
      positions.row(1 + (r - 1) * around + s) << std::sin(phi) * std::cos(theta), std::sin(phi) * std::sin(theta),
          std::cos(phi);
    }
  auto at = [&](int r, int s) { return r == 0 ? 0 : 1 + (r - 1) * around + (s % around); };
  std::vector<Eigen::Vector3i> tris;
  std::vector<int> chart;
  for (int s = 0; s < around; ++s) {
    tris.emplace_back(at(0, 0), at(1, s), at(1, s + 1));
    chart.push_back(s / 6);
    for (int r = 1; r < rings; ++r) {
      tris.emplace_back(at(r, s), at(r + 1, s), at(r + 1, s + 1));
      tris.emplace_back(at(r, s), at(r + 1, s + 1), at(r, s + 1));
      const int cell = r / 3 * sectors + s / 6;
      chart.push_back(cell), chart.push_back(cell);
    }
  }
  RowMatrixX3i triangles(static_cast<Eigen::Index>(tris.size()), 3);
  for (size_t f = 0; f < tris.size(); ++f) triangles.row(f) = tris[f].transpose();
  return atlas::testing::with_chart_uvs(positions, triangles, chart);
}

struct CapRun {
  std::vector<FlatChart> pieces;
  FlattenStats stats;
  std::vector<int> face_chart;  // original chart of each face
  std::vector<std::pair<int, int>> merges;
};

CapRun flatten_cap(const Mesh& mesh, int relief_cuts) {
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const ChartGraph graph = build_chart_graph(mesh, topology, {});
  AggregateOptions merge_all;
  merge_all.min_normal_coherence = 0;
  const Aggregation merged = aggregate_charts(mesh, topology, graph, merge_all, RunControl());
  EXPECT_EQ(merged.chart_count(), 1);
  std::vector<std::vector<int>> chart_faces(graph.chart_count());
  for (int f = 0; f < mesh.face_count(); ++f) chart_faces[graph.face_chart[f]].push_back(f);
  FlattenOptions options;
  options.relief_cuts = relief_cuts;
  options.slim.relax.sweeps = 0;  // the cap's squeeze is what the cuts and splits here answer
  CapRun run;
  run.face_chart = graph.face_chart;
  run.merges = merged.merges;
  run.pieces = flatten_without_overlap(mesh, topology, graph, chart_faces, merged.members[0], merged.merges, options,
                                       RunControl(), run.stats);
  return run;
}

// Faces of the flattened pieces with less than half their original texel area, by 3D area share.
double density_lost_share(const Mesh& mesh, const std::vector<FlatChart>& pieces) {
  double lost = 0, total = 0;
  for (const FlatChart& piece : pieces)
    for (size_t i = 0; i < piece.faces.size(); ++i) {
      const int f = piece.faces[i];
      const double after = std::abs(signed_area(piece.corner_uv.row(3 * i), piece.corner_uv.row(3 * i + 1),
                                                piece.corner_uv.row(3 * i + 2)));
      total += mesh.area_3d(f);
      if (after < 0.5 * std::abs(mesh.signed_area_uv(f))) lost += mesh.area_3d(f);
    }
  return lost / total;
}

}  // namespace

// Without relief cuts the cap is split back into pieces; with them it stays
// one chart, slit open, within the density rule and without flips or crossings.
TEST(ReliefCut, KeepsABentChartWhole) {
  const Mesh cap = sector_cap(12, 6, 2.8);
  const CapRun split = flatten_cap(cap, 0);
  EXPECT_GE(split.stats.density_lost, 1);
  EXPECT_GE(split.pieces.size(), 2u);

  const CapRun slit = flatten_cap(cap, 2);
  ASSERT_EQ(slit.pieces.size(), 1u);
  EXPECT_GE(slit.stats.relief_cuts, 1);
  EXPECT_EQ(slit.stats.density_lost, 0);
  EXPECT_LE(density_lost_share(cap, slit.pieces), FlattenOptions().max_density_loss);
  const FlatChart& chart = slit.pieces[0];
  EXPECT_EQ(chart.faces.size(), static_cast<size_t>(cap.face_count()));
  double winding = 0;
  for (size_t i = 0; i < chart.faces.size(); ++i) {
    const double a = signed_area(chart.corner_uv.row(3 * i), chart.corner_uv.row(3 * i + 1), chart.corner_uv.row(3 * i + 2));
    if (i == 0) winding = a;
    EXPECT_GT(a * winding, 0) << "face " << i;
  }
}

// A split undoes the aggregation's last merge: two pieces, the two clusters
// that merge joined, rather than groups regrown from seeds.
TEST(ReliefCut, SplitUndoesTheLastMerge) {
  const Mesh cap = sector_cap(12, 6, 2.8);
  const CapRun split = flatten_cap(cap, 0);
  ASSERT_EQ(split.stats.density_lost, 1);
  ASSERT_EQ(split.pieces.size(), 2u);
  const auto [survivor, absorbed] = split.merges.back();
  UnionFind before(24);
  for (size_t i = 0; i + 1 < split.merges.size(); ++i) before.unite(split.merges[i].first, split.merges[i].second);
  for (const FlatChart& piece : split.pieces) {
    const int side = before.find(split.face_chart[piece.faces.front()]);
    EXPECT_TRUE(side == before.find(survivor) || side == before.find(absorbed));
    for (int f : piece.faces) EXPECT_EQ(before.find(split.face_chart[f]), side);
  }
  EXPECT_NE(before.find(split.face_chart[split.pieces[0].faces.front()]),
            before.find(split.face_chart[split.pieces[1].faces.front()]));
}

// A query box far larger than the cells (a clearance of fixed texels around
// a chart a hundred-billionth of a texel across) reaches every cell: the cell
// indices are clamped before they become ints, which they would overflow.
TEST(BucketGrid, AQueryBoxFarLargerThanTheGridVisitsEveryItem) {
  const double side = 1e-11;
  BucketGrid grid(Eigen::Vector2d::Zero(), Eigen::Vector2d::Constant(side), 100);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Vector2d at((i % 10 + 0.5) * side / 10, (i / 10 + 0.5) * side / 10);
    grid.insert(i, at, at);
  }
  std::vector<int> seen(100, 0);
  grid.any_near(Eigen::Vector2d::Constant(-0.05), Eigen::Vector2d::Constant(0.05), [&](int i) {
    seen[i] = 1;
    return false;
  });
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), 100);
}

// A 12 x 12 grid with a hole of the mesh (three quads at x = 1 / n) between
// the side x = 0 and an island (quad (3, 6), faces left out of the chart):
// the hole filled, the cut that opens the island's hole into the border
// goes round the hole's border when told to avoid it. Every path of three
// edges from x = 0 to the island passes that border, so left free the
// shortest cut runs through it.
TEST(CutToDisk, GoesRoundTheVerticesToAvoid) {
  const int n = 12;
  const Mesh grid = atlas::testing::grid_disk(n);
  std::vector<int> kept, faces;  // kept: the mesh; faces: the chart (rows of the mesh)
  for (int f = 0; f < grid.face_count(); ++f) {
    const int i = f / 2 / n, j = f / 2 % n;
    if (i == 1 && j >= 5 && j <= 7) continue;
    if (!(i == 3 && j == 6)) faces.push_back(static_cast<int>(kept.size()));
    kept.push_back(f);
  }
  Mesh mesh = grid;
  mesh.triangles.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (size_t r = 0; r < kept.size(); ++r) mesh.triangles.row(r) = grid.triangles.row(kept[r]);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const MeshHoles holes = mesh_holes(mesh, topology);
  ASSERT_EQ(holes.edges, (std::vector<int>{8}));
  std::vector<char> border(mesh.vertex_count(), 0);
  for (int e = 0; e < topology.edge_count(); ++e)
    if (holes.edge_hole[e] >= 0) border[topology.edge_vertices(e, 0)] = border[topology.edge_vertices(e, 1)] = 1;
  for (const bool avoiding : {false, true}) {
    RowMatrixX3i triangles(static_cast<Eigen::Index>(faces.size()), 3);
    for (size_t r = 0; r < faces.size(); ++r) triangles.row(r) = mesh.triangles.row(faces[r]);
    std::vector<int> source(mesh.vertex_count());
    std::iota(source.begin(), source.end(), 0);
    ASSERT_EQ(fill_holes(mesh, topology, holes, faces, triangles, source).rows(), 1);
    std::vector<char> uncut(3 * triangles.rows(), 0);
    std::fill(uncut.begin() + 3 * static_cast<std::ptrdiff_t>(faces.size()), uncut.end(), 1);
    ASSERT_TRUE(cut_to_disk(triangles, source, uncut, avoiding ? border : std::vector<char>()));
    std::vector<int> copies(mesh.vertex_count() + 1, 0);
    for (int s : source) ++copies[s];
    int border_copies = 0;
    for (int v = 0; v < mesh.vertex_count(); ++v) border_copies += border[v] ? copies[v] - 1 : 0;
    if (avoiding) {
      EXPECT_EQ(border_copies, 0);
    } else {
      EXPECT_GT(border_copies, 0);  // else the test shows nothing
    }
  }
}
