// Atlas, map and colour metrics on small constructed layouts with known answers.
#include <gtest/gtest.h>
#include <omp.h>

#include <cmath>
#include <cstdint>
#include <random>

#include "core/geometry.hpp"
#include "core/rasterize_triangle.hpp"
#include "metrics.hpp"
#include "test_meshes.hpp"

using namespace atlas;

namespace {

AtlasMeasures measure(const Mesh& mesh) {
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  return measure_atlas(mesh, topology, layout_of(mesh));
}

// Corner UVs from one UV per vertex (keeps the layout continuous: one chart).
RowMatrixX2d corner_uv_from_vertices(const Mesh& mesh, const RowMatrixX2d& vertex_uv) {
  RowMatrixX2d uv(3 * mesh.face_count(), 2);
  for (int f = 0; f < mesh.face_count(); ++f)
    for (int k = 0; k < 3; ++k) uv.row(3 * f + k) = vertex_uv.row(mesh.triangles(f, k));
  return uv;
}

// Two unit quads far apart in 3D, UV squares [lo_a, lo_a + side] and [lo_b, lo_b + side].
Mesh two_squares(double lo_a, double lo_b, double side, int page_size) {
  RowMatrixX3d p(8, 3);
  p << 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 5, 0, 0, 6, 0, 0, 6, 1, 0, 5, 1, 0;
  RowMatrixX3i t(4, 3);
  t << 0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7;
  RowMatrixX2d uv(12, 2);
  for (int f = 0; f < 4; ++f)
    for (int k = 0; k < 3; ++k) {
      const int v = t(f, k);
      const double lo = v < 4 ? lo_a : lo_b;
      uv.row(3 * f + k) << lo + side * (p(v, 0) - (v < 4 ? 0 : 5)), lo + side * p(v, 1);
    }
  return make_mesh(p, t, uv, Eigen::VectorXi::Zero(4), {PageSize{page_size, page_size}});
}

template <class T>
std::vector<T> pattern_image(int w, int h, int channels, double scale) {
  std::vector<T> texels(static_cast<size_t>(w) * h * channels);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < channels; ++c)
        texels[(static_cast<size_t>(y) * w + x) * channels + c] =
            static_cast<T>(scale * ((x * 7 + y * 13 + c * 50) % 200));
  return texels;
}

template <class T>
ImageView<T> view_of(const std::vector<T>& texels, int w, int h, int channels) {
  return {texels.data(), w, h, channels, texels.size()};
}

}  // namespace

// ---- measure_atlas ---------------------------------------------------------

TEST(MeasureAtlas, GridDiskIsOneCleanChart) {
  const Mesh mesh = atlas::testing::grid_disk(16, 0.37, 256);
  const AtlasMeasures m = measure(mesh);
  const double side = 0.37 * 256;
  EXPECT_EQ(m.charts, 1);
  EXPECT_DOUBLE_EQ(m.seam_ratio, 0.0);
  EXPECT_NEAR(m.boundary_texels, 4 * side, 1e-9);
  EXPECT_EQ(m.page_texels, 256LL * 256);
  EXPECT_EQ(m.flipped_faces, 0);
  EXPECT_EQ(m.overlap_texels, 0);
  // Centres inside a square of side 94.72: 94 or 95 per axis.
  EXPECT_NEAR(static_cast<double>(m.covered_texels), side * side, 2 * side + 1);
  EXPECT_GE(m.covered_texels, 94 * 94);
  EXPECT_LE(m.covered_texels, 95 * 95);
  EXPECT_DOUBLE_EQ(m.occupancy, static_cast<double>(m.covered_texels) / m.page_texels);
}

TEST(MeasureAtlas, CentresOnEdgesAndVerticesCountOnce) {
  // Vertices on texel corners: every diagonal runs through texel centres.
  const Mesh on_corners = atlas::testing::grid_disk(8, 1.0, 8);
  AtlasMeasures m = measure(on_corners);
  EXPECT_EQ(m.covered_texels, 64);
  EXPECT_EQ(m.overlap_texels, 0);
  EXPECT_DOUBLE_EQ(m.occupancy, 1.0);

  // Vertices on texel centres: every grid line runs through centres, every vertex is one.
  Mesh on_centres = atlas::testing::grid_disk(8, 0.5, 16);
  on_centres.corner_uv.array() += 0.5 / 16;
  m = measure(on_centres);
  EXPECT_EQ(m.covered_texels, 64);
  EXPECT_EQ(m.overlap_texels, 0);

  // Mirrored (clockwise) triangles follow the same rule.
  on_centres.corner_uv.col(0) = (0.75 - on_centres.corner_uv.col(0).array()).matrix();
  m = measure(on_centres);
  EXPECT_EQ(m.covered_texels, 64);
  EXPECT_EQ(m.overlap_texels, 0);
  EXPECT_EQ(m.flipped_faces, 0);  // the whole chart is mirrored, consistently
}

TEST(MeasureAtlas, JitteredMeshCoversEveryTexelExactlyOnce) {
  // A 24x24 grid stretched past a 40x40 page, interior vertices jittered, some
  // snapped to texel centres or corners: a watertight, fold-free tiling of the page.
  const int n = 24, page = 40;
  const Mesh disk = atlas::testing::grid_disk(n, 1.0, page);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  RowMatrixX2d vertex_uv(disk.vertex_count(), 2);
  for (int v = 0; v < disk.vertex_count(); ++v) {
    Eigen::Vector2d g = disk.positions.row(v).head<2>().transpose() * n;  // grid coordinates
    const bool interior = g.x() > 0.5 && g.x() < n - 0.5 && g.y() > 0.5 && g.y() < n - 0.5;
    if (interior) g += Eigen::Vector2d(jitter(rng), jitter(rng));
    Eigen::Vector2d texel = (g / n) * (page + 4.0) - Eigen::Vector2d::Constant(2.0);
    if (interior && v % 3 == 0) texel = (texel * 2).array().round().matrix() / 2;  // on a centre or corner grid
    vertex_uv.row(v) = texel.transpose() / page;
  }
  Mesh mesh = disk;
  mesh.corner_uv = corner_uv_from_vertices(disk, vertex_uv);
  const AtlasMeasures m = measure(mesh);
  EXPECT_EQ(m.charts, 1);
  EXPECT_EQ(m.flipped_faces, 0);
  EXPECT_EQ(m.covered_texels, page * page);
  EXPECT_EQ(m.overlap_texels, 0);
}

// A 4 x 4 grid on a 256-texel page with its interior vertex (1,1) moved to
// (x, y) in grid units. Its one-ring is the hexagon (+-1,0), (0,+-1), (1,1),
// (-1,-1) around it: past the ring edge x = 2, exactly one triangle folds.
Mesh grid_with_vertex_moved(double x, double y) {
  const int n = 4;
  Mesh mesh = atlas::testing::grid_disk(n, 1.0, 256);
  RowMatrixX2d vertex_uv = mesh.positions.leftCols<2>();
  for (int i = 0; i < mesh.vertex_count(); ++i)
    if ((mesh.positions.row(i).head<2>() - Eigen::RowVector2d(0.25, 0.25)).norm() < 1e-12)
      vertex_uv.row(i) << x / n, y / n;
  mesh.corner_uv = corner_uv_from_vertices(mesh, vertex_uv);
  return mesh;
}

TEST(MeasureAtlas, OneFoldedTriangleIsFlipped) {
  const AtlasMeasures m = measure(grid_with_vertex_moved(2.1, 1.5));
  EXPECT_EQ(m.charts, 1);
  EXPECT_EQ(m.flipped_faces, 1);
  EXPECT_GT(m.overlap_texels, 0);  // the fold lies over its neighbours
}

TEST(MeasureAtlas, SliverFoldedByAThousandthOfATexelIsFlipped) {
  // The same fold, a thousandth of a texel past the ring edge (a grid unit is
  // 64 texels): it covers no texel, yet its stored winding disagrees, and
  // every such face counts.
  EXPECT_EQ(measure(grid_with_vertex_moved(2 + 1e-3 / 64, 1.5)).flipped_faces, 1);
}

TEST(MeasureAtlas, OverlappingChartsCountTheOverlapArea) {
  const int page = 256;
  const Mesh mesh = two_squares(0.1, 0.3, 0.4, page);
  const AtlasMeasures m = measure(mesh);
  EXPECT_EQ(m.charts, 2);
  EXPECT_DOUBLE_EQ(m.seam_ratio, 0.0);  // no shared edges, so no seam
  EXPECT_EQ(m.flipped_faces, 0);
  const double overlap_side = 0.2 * page, side = 0.4 * page;
  EXPECT_NEAR(static_cast<double>(m.overlap_texels), overlap_side * overlap_side, 2 * overlap_side + 1);
  const double union_area = 2 * side * side - overlap_side * overlap_side;
  EXPECT_NEAR(static_cast<double>(m.covered_texels), union_area, 4 * side + 1);
  EXPECT_NEAR(m.boundary_texels, 8 * side, 1e-9);

  const AtlasMeasures apart = measure(two_squares(0.05, 0.55, 0.4, page));
  EXPECT_EQ(apart.overlap_texels, 0);
}

TEST(MeasureAtlas, UntexturedFacesAndClippingAreIgnored) {
  // 2x2-texel quads offset by (0.3, 0.1) texels: of each quad's 4 centres, 1 lies
  // below the diagonal (triangle a,b,c) and 3 above it (triangle a,c,d).
  Mesh mesh = atlas::testing::grid_disk(8, 1.0, 16);
  mesh.corner_uv.col(0).array() += 0.3 / 16;
  mesh.corner_uv.col(1).array() += 0.1 / 16;
  AtlasMeasures m = measure(mesh);
  EXPECT_EQ(m.covered_texels, 256);
  for (int f = 0; f < mesh.face_count(); f += 2) mesh.face_page[f] = -1;
  m = measure(mesh);
  EXPECT_EQ(m.covered_texels, 3 * 64);
  EXPECT_EQ(m.overlap_texels, 0);
  mesh.face_page.setConstant(-1);
  m = measure(mesh);
  EXPECT_EQ(m.charts, 0);
  EXPECT_EQ(m.covered_texels, 0);
  EXPECT_EQ(m.flipped_faces, 0);
  EXPECT_DOUBLE_EQ(m.occupancy, 0.0);

  // UVs far outside [0,1] are clipped to the page.
  Mesh outside = atlas::testing::grid_disk(4, 1.0, 16);
  outside.corner_uv = (outside.corner_uv.array() * 3 - 1).matrix();
  m = measure(outside);
  EXPECT_EQ(m.covered_texels, 256);
  EXPECT_EQ(m.overlap_texels, 0);
}

TEST(MeasureAtlas, RejectsMismatchedLayouts) {
  const Mesh mesh = atlas::testing::grid_disk(2);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const RowMatrixX2d short_uv = mesh.corner_uv.topRows(3);
  EXPECT_THROW(measure_atlas(mesh, topology, {&short_uv, &mesh.face_page, &mesh.pages}), InputError);
  const Eigen::VectorXi bad_page = Eigen::VectorXi::Constant(mesh.face_count(), 1);
  EXPECT_THROW(measure_atlas(mesh, topology, {&mesh.corner_uv, &bad_page, &mesh.pages}), InputError);
  RowMatrixX2d nan_uv = mesh.corner_uv;
  nan_uv(4, 1) = std::nan("");
  EXPECT_THROW(measure_atlas(mesh, topology, {&nan_uv, &mesh.face_page, &mesh.pages}), InputError);
}

TEST(TexelTriangle, SharedEdgeThroughCentresIsClaimedOnce) {
  // Random triangles fanned around a centre that sits on a texel centre; the fan
  // covers a convex polygon, every centre inside it must be claimed exactly once.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> radius(3.0, 9.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Vector2d c(10.5, 10.5);
    const int k = 5 + trial % 7;
    std::vector<Eigen::Vector2d> ring;
    for (int i = 0; i < k; ++i) {
      const double a = 2 * kPi * i / k;
      const double r = trial % 2 ? 6.0 : radius(rng);
      ring.push_back(c + r * Eigen::Vector2d(std::cos(a), std::sin(a)));
      if (trial % 3 == 0) ring.back() = (ring.back() * 2).array().round().matrix() / 2;
    }
    int counts[24][24] = {};
    for (int i = 0; i < k; ++i) {
      TexelTriangle t;
      if (!t.setup(c, ring[i], ring[(i + 1) % k])) continue;
      for (int y = t.row_begin; y < t.row_end; ++y) {
        int x0, x1;
        t.row_span(y, x0, x1);
        for (int x = x0; x < x1; ++x) ++counts[y][x];
      }
    }
    for (int y = 0; y < 24; ++y)
      for (int x = 0; x < 24; ++x) ASSERT_LE(counts[y][x], 1) << "trial " << trial;
    EXPECT_EQ(counts[10][10], 1) << "trial " << trial;  // the shared apex itself
  }
}

// ---- measure_map -------------------------------------------------------------

TEST(MeasureMap, IdentityIsPerfect) {
  const Mesh mesh = atlas::testing::grid_disk(8, 0.6, 512);
  const MapMeasures m = measure_map(mesh, layout_of(mesh), layout_of(mesh));
  EXPECT_DOUBLE_EQ(m.density_loss_area_share, 0.0);
  EXPECT_NEAR(m.density_ratio_p5, 1.0, 1e-12);
  EXPECT_NEAR(m.density_ratio_p50, 1.0, 1e-12);
  EXPECT_NEAR(m.density_ratio_p95, 1.0, 1e-12);
  EXPECT_NEAR(m.angle_error_p50, 0.0, 1e-9);
  EXPECT_NEAR(m.angle_error_p90, 0.0, 1e-9);
  EXPECT_NEAR(m.angle_error_p99, 0.0, 1e-9);
}

TEST(MeasureMap, HalfScaleLosesAllDensity) {
  const Mesh mesh = atlas::testing::grid_disk(8, 0.6, 512);
  const RowMatrixX2d half = mesh.corner_uv * 0.5;
  const MapMeasures m = measure_map(mesh, layout_of(mesh), {&half, &mesh.face_page, &mesh.pages});
  EXPECT_DOUBLE_EQ(m.density_loss_area_share, 1.0);
  EXPECT_NEAR(m.density_ratio_p5, 0.25, 1e-12);
  EXPECT_NEAR(m.density_ratio_p50, 0.25, 1e-12);
  EXPECT_NEAR(m.density_ratio_p95, 0.25, 1e-12);
  EXPECT_NEAR(m.angle_error_p99, 0.0, 1e-9);
}

TEST(MeasureMap, WiderPageStretchesInTexels) {
  // Same page UVs, new page twice as wide: texel density x2 and the right
  // isoceles triangles shear to 26.57 / 63.43 / 90 degrees.
  const Mesh mesh = atlas::testing::grid_disk(4, 1.0, 256);
  const std::vector<PageSize> wide = {PageSize{512, 256}};
  const MapMeasures m = measure_map(mesh, layout_of(mesh), {&mesh.corner_uv, &mesh.face_page, &wide});
  EXPECT_DOUBLE_EQ(m.density_loss_area_share, 0.0);
  EXPECT_NEAR(m.density_ratio_p5, 2.0, 1e-12);
  EXPECT_NEAR(m.density_ratio_p95, 2.0, 1e-12);
  const double shear = 45.0 - std::atan(0.5) * 180 / kPi;  // 18.43 degrees on 2 of 3 corners, 0 on the right angle
  EXPECT_NEAR(m.angle_error_p50, shear, 1e-9);
  EXPECT_NEAR(m.angle_error_p90, shear, 1e-9);
  EXPECT_NEAR(m.angle_error_p99, shear, 1e-9);
}

TEST(MeasureMap, DegenerateAndUntexturedFacesAreSkipped) {
  Mesh mesh = atlas::testing::grid_disk(4, 1.0, 256);
  RowMatrixX2d old_uv = mesh.corner_uv;
  old_uv.middleRows(0, 3).rowwise() = old_uv.row(0);  // face 0: zero old UV area
  mesh.face_page[1] = -1;                              // face 1: untextured
  RowMatrixX2d new_uv = mesh.corner_uv;
  new_uv.middleRows(6, 3).rowwise() = new_uv.row(6);  // face 2: collapsed in the new layout
  const MapMeasures m =
      measure_map(mesh, {&old_uv, &mesh.face_page, &mesh.pages}, {&new_uv, &mesh.face_page, &mesh.pages});
  // Face 2 is one of 30 counted faces of equal area; it loses all density.
  EXPECT_NEAR(m.density_loss_area_share, 1.0 / 30, 1e-12);
  EXPECT_NEAR(m.density_ratio_p50, 1.0, 1e-12);
  for (double v : {m.density_ratio_p5, m.density_ratio_p95, m.angle_error_p50, m.angle_error_p90, m.angle_error_p99})
    EXPECT_TRUE(std::isfinite(v));

  Mesh none = mesh;
  none.face_page.setConstant(-1);
  const MapMeasures empty = measure_map(none, layout_of(none), layout_of(none));
  EXPECT_EQ(empty.density_loss_area_share, 0.0);
  EXPECT_EQ(empty.density_ratio_p50, 0.0);
}

// ---- compare_colors ----------------------------------------------------------

TEST(CompareColors, IdenticalImagesAndLayouts) {
  const Mesh mesh = atlas::testing::grid_disk(8, 0.9, 64);
  const std::vector<std::uint8_t> texels = pattern_image<std::uint8_t>(64, 64, 4, 1.0);
  const std::vector<ImageView<std::uint8_t>> images = {view_of(texels, 64, 64, 4)};
  const ColorFidelity c = compare_colors(mesh, layout_of(mesh), images, layout_of(mesh), images, 20000, 1);
  EXPECT_EQ(c.samples, 20000);
  EXPECT_DOUBLE_EQ(c.psnr_db, kMaxPsnrDb);
  EXPECT_DOUBLE_EQ(c.share_off_32, 0.0);

  // A whole-page shift wraps onto the same texels.
  const RowMatrixX2d shifted = (mesh.corner_uv.array() + 1.0).matrix();
  const ColorFidelity w =
      compare_colors(mesh, layout_of(mesh), images, {&shifted, &mesh.face_page, &mesh.pages}, images, 20000, 1);
  EXPECT_GT(w.psnr_db, 90.0);
  EXPECT_DOUBLE_EQ(w.share_off_32, 0.0);
}

TEST(CompareColors, ConstantOffsetGivesKnownPsnr) {
  const Mesh mesh = atlas::testing::grid_disk(8, 0.9, 64);
  const std::vector<std::uint8_t> a = pattern_image<std::uint8_t>(64, 64, 3, 1.0);
  std::vector<std::uint8_t> b = a, far = a;
  for (auto& v : b) v = static_cast<std::uint8_t>(v + 16);
  for (auto& v : far) v = static_cast<std::uint8_t>(v + 40);
  const std::vector<ImageView<std::uint8_t>> old_images = {view_of(a, 64, 64, 3)};
  const ColorFidelity c =
      compare_colors(mesh, layout_of(mesh), old_images, layout_of(mesh), {view_of(b, 64, 64, 3)}, 20000, 5);
  EXPECT_NEAR(c.psnr_db, 20 * std::log10(255.0 / 16), 0.1);
  EXPECT_DOUBLE_EQ(c.share_off_32, 0.0);
  const ColorFidelity f =
      compare_colors(mesh, layout_of(mesh), old_images, layout_of(mesh), {view_of(far, 64, 64, 3)}, 20000, 5);
  EXPECT_NEAR(f.psnr_db, 20 * std::log10(255.0 / 40), 0.1);
  EXPECT_DOUBLE_EQ(f.share_off_32, 1.0);

  // Float texels are used as they are.
  const std::vector<float> fa = pattern_image<float>(64, 64, 3, 1.0 / 255);
  std::vector<float> fb = fa;
  for (auto& v : fb) v += 16.0f / 255;
  const ColorFidelity g = compare_colors<float>(mesh, layout_of(mesh), {view_of(fa, 64, 64, 3)}, layout_of(mesh),
                                                {view_of(fb, 64, 64, 3)}, 20000, 5);
  EXPECT_NEAR(g.psnr_db, 20 * std::log10(255.0 / 16), 0.1);

  // Deterministic for a seed.
  const ColorFidelity again =
      compare_colors(mesh, layout_of(mesh), old_images, layout_of(mesh), {view_of(b, 64, 64, 3)}, 20000, 5);
  EXPECT_EQ(again.psnr_db, c.psnr_db);
}

TEST(CompareColors, BorderPointsAreThoseReadingGutterTexels) {
  // One chart over [0, 0.9]^2 of a 64^2 page: texels from column or row 58 on
  // are gutter. The new image changes only those.
  const Mesh mesh = atlas::testing::grid_disk(8, 0.9, 64);
  const std::vector<std::uint8_t> a = pattern_image<std::uint8_t>(64, 64, 3, 1.0);
  std::vector<std::uint8_t> b = a;
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 64; ++x)
      if (x >= 58 || y >= 58)
        for (int k = 0; k < 3; ++k) b[(static_cast<size_t>(y) * 64 + x) * 3 + k] ^= 0x80;
  const ColorFidelity c = compare_colors<std::uint8_t>(mesh, layout_of(mesh), {view_of(a, 64, 64, 3)}, layout_of(mesh),
                                         {view_of(b, 64, 64, 3)}, 20000, 3);
  EXPECT_DOUBLE_EQ(c.psnr_clean_db, kMaxPsnrDb);
  EXPECT_LT(c.psnr_border_db, 30.0);
  EXPECT_LT(c.psnr_db, kMaxPsnrDb);
  // Border points lie within about a texel of the chart's outer edges:
  // 2 of its 57.6-texel sides (the other two wrap onto gutter too).
  const double border_share = 1.0 - static_cast<double>(c.clean_samples) / c.samples;
  EXPECT_GT(border_share, 0.01);
  EXPECT_LT(border_share, 0.1);
}

TEST(CompareColors, SamplesUniformlyBy3DArea) {
  // UVs stay on the regular grid but x is squared in 3D: u < 0.5 holds 1/4 of the
  // surface. Old image black for u < 0.5, white above; new image all black.
  Mesh mesh = atlas::testing::grid_disk(16, 1.0, 64);
  mesh.positions.col(0) = mesh.positions.col(0).array().square().matrix();
  std::vector<std::uint8_t> half(64 * 64, 0), black(64 * 64, 0);
  for (int y = 0; y < 64; ++y)
    for (int x = 32; x < 64; ++x) half[y * 64 + x] = 255;
  const ColorFidelity c = compare_colors<std::uint8_t>(mesh, layout_of(mesh), {view_of(half, 64, 64, 1)}, layout_of(mesh),
                                         {view_of(black, 64, 64, 1)}, 40000, 9);
  // Bilinear blends within half a texel of u = 0.5 and of the wrap at u = 0 / 1 (3D shares ~0.008, ~0.0001 and ~0.016).
  EXPECT_NEAR(c.share_off_32, 0.75, 0.03);
}

TEST(CompareColors, RejectsMissingImages) {
  const Mesh mesh = atlas::testing::grid_disk(2);
  const std::vector<std::uint8_t> texels(16 * 16 * 3, 0);
  const std::vector<ImageView<std::uint8_t>> none;
  const std::vector<ImageView<std::uint8_t>> small = {{texels.data(), 16, 16, 3, 100}};
  EXPECT_THROW(compare_colors(mesh, layout_of(mesh), none, layout_of(mesh), none, 10, 0), InputError);
  EXPECT_THROW(compare_colors(mesh, layout_of(mesh), small, layout_of(mesh), small, 10, 0), InputError);
}

// A grid atlas and the same atlas moved, each with an image of its own pattern.
struct MovedAtlas {
  Mesh mesh = atlas::testing::grid_disk(12, 0.8, 64);
  std::vector<std::uint8_t> a = pattern_image<std::uint8_t>(64, 64, 3, 1.0);
  std::vector<std::uint8_t> b = pattern_image<std::uint8_t>(64, 64, 3, 0.9);
  RowMatrixX2d moved = (mesh.corner_uv.array() * 0.9 + 0.03).matrix();
  std::vector<ImageView<std::uint8_t>> old_images = {view_of(a, 64, 64, 3)};
  std::vector<ImageView<std::uint8_t>> new_images = {view_of(b, 64, 64, 3)};

  ColorFidelity compare(unsigned seed, bool borders = true) const {
    return compare_colors(mesh, layout_of(mesh), old_images, {&moved, &mesh.face_page, &mesh.pages}, new_images,
                          30000, seed, borders);
  }
};

TEST(CompareColors, SameResultOnAnyThreadCount) {
  const MovedAtlas atlas;
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const ColorFidelity one = atlas.compare(11);
  omp_set_num_threads(3);
  const ColorFidelity three = atlas.compare(11);
  omp_set_num_threads(threads);
  EXPECT_EQ(one.psnr_db, three.psnr_db);
  EXPECT_EQ(one.share_off_32, three.share_off_32);
  EXPECT_LT(one.psnr_db, 40.0);  // the images really differ
  EXPECT_NE(atlas.compare(12).psnr_db, one.psnr_db);
}

// Two triangles along one edge, its two vertices given twice (as glTF writes a seam).
TEST(MakeMesh, WeldsExactCopiesUnlessToldNotTo) {
  RowMatrixX3d p(6, 3);
  p << 0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0;
  RowMatrixX3i t(2, 3);
  t << 0, 1, 2, 3, 4, 5;
  const RowMatrixX2d uv = RowMatrixX2d::Zero(6, 2);
  const Eigen::VectorXi page = Eigen::VectorXi::Zero(2);
  const Mesh welded = make_mesh(p, t, uv, page, {PageSize{8, 8}});
  EXPECT_EQ(welded.vertex_count(), 4);
  EXPECT_EQ(welded.triangles(1, 0), welded.triangles(0, 1));
  const Mesh as_given = make_mesh(p, t, uv, page, {PageSize{8, 8}}, /*weld=*/false);
  EXPECT_EQ(as_given.vertex_count(), 6);
  EXPECT_EQ(as_given.triangles, t);
}

// Without the clean / border split every point still counts: the same PSNR, no split figures.
TEST(CompareColors, WithoutBordersTheSamePsnr) {
  const MovedAtlas atlas;
  const ColorFidelity split = atlas.compare(11);
  const ColorFidelity whole = atlas.compare(11, /*borders=*/false);
  EXPECT_GT(split.clean_samples, 0);
  EXPECT_LT(split.clean_samples, split.samples);
  EXPECT_NEAR(whole.psnr_db, split.psnr_db, 1e-9);
  EXPECT_EQ(whole.share_off_32, split.share_off_32);
  EXPECT_EQ(whole.clean_samples, 0);
  EXPECT_TRUE(std::isnan(whole.psnr_clean_db) && std::isnan(whole.psnr_border_db));
}
