#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <type_traits>

#include "bake/bake.hpp"
#include "bake/sample_texture.hpp"

namespace atlas {
namespace {

using Colour = std::array<double, 4>;

// The unit square cut into charts_per_side^2 square charts of quads_per_chart^2 quads,
// two triangles each.
struct ChartedSquare {
  int charts_per_side = 1;
  std::vector<Eigen::Vector2d> corner_xy;  // 3 surface points per face
  std::vector<int> face_chart;

  double chart_size() const { return 1.0 / charts_per_side; }
  int chart_count() const { return charts_per_side * charts_per_side; }
  int face_count() const { return static_cast<int>(face_chart.size()); }
  Eigen::Vector2d chart_origin(int c) const {
    return chart_size() * Eigen::Vector2d(c % charts_per_side, c / charts_per_side);
  }
};

ChartedSquare charted_square(int charts_per_side, int quads_per_chart) {
  ChartedSquare s;
  s.charts_per_side = charts_per_side;
  const int n = charts_per_side * quads_per_chart;
  const double h = 1.0 / n;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Eigen::Vector2d a(i * h, j * h), b((i + 1) * h, j * h), c((i + 1) * h, (j + 1) * h),
          d(i * h, (j + 1) * h);
      const int chart = (j / quads_per_chart) * charts_per_side + i / quads_per_chart;
      using Tri = std::array<Eigen::Vector2d, 3>;
      for (const Tri& tri : {Tri{a, b, c}, Tri{a, c, d}}) {
        s.corner_xy.insert(s.corner_xy.end(), tri.begin(), tri.end());
        s.face_chart.push_back(chart);
      }
    }
  return s;
}

// Chart placement: uv = offset + linear * (xy - chart origin), on page `page`.
struct Placement {
  Eigen::Matrix2d linear;
  Eigen::Vector2d offset;
  int page = 0;

  Eigen::Vector2d local_of(const Eigen::Vector2d& uv) const { return linear.inverse() * (uv - offset); }
};

Eigen::Matrix2d turn(double scale, double a, double b, double c, double d) {
  Eigen::Matrix2d m;
  m << a, b, c, d;
  return scale * m;
}

struct Layout {
  RowMatrixX2d uv;
  Eigen::VectorXi face_page;
  UvLayout view(const std::vector<PageSize>& pages) const { return {&uv, &face_page, &pages}; }
};

// The page sizes of the old images, as the old layout must give them.
template <class T>
std::vector<PageSize> sizes_of(const std::vector<ImageView<T>>& views) {
  std::vector<PageSize> sizes;
  for (const ImageView<T>& v : views) sizes.push_back({v.width, v.height});
  return sizes;
}

Layout place(const ChartedSquare& s, const std::vector<Placement>& placements) {
  Layout layout;
  layout.uv.resize(3 * s.face_count(), 2);
  layout.face_page.resize(s.face_count());
  for (int f = 0; f < s.face_count(); ++f) {
    const int c = s.face_chart[f];
    const Placement& pl = placements[c];
    layout.face_page[f] = pl.page;
    for (int k = 0; k < 3; ++k)
      layout.uv.row(3 * f + k) =
          (pl.offset + pl.linear * (s.corner_xy[3 * f + k] - s.chart_origin(c))).transpose();
  }
  return layout;
}

template <class T>
Image<T> blank(int w, int h, int channels) {
  Image<T> img{w, h, channels, {}};
  img.texels.assign(static_cast<std::size_t>(w) * h * channels, T(0));
  return img;
}

template <class T>
ImageView<T> view_of(const Image<T>& img) {
  return {img.texels.data(), img.width, img.height, img.channels, img.texels.size()};
}

template <class T>
T stored(double v) {
  if constexpr (std::is_same_v<T, float>) return static_cast<float>(v);
  else return static_cast<T>(std::lround(std::clamp(v * 255.0, 0.0, 255.0)));
}

template <class T>
double unit(T v) {
  if constexpr (std::is_same_v<T, float>) return v;
  else return v / 255.0;
}

template <class T>
void set_texel(Image<T>& img, int x, int y, const Colour& colour) {
  for (int k = 0; k < img.channels; ++k)
    img.texels[(static_cast<std::size_t>(y) * img.width + x) * img.channels + k] = stored<T>(colour[k]);
}

template <class T>
Colour texel(const Image<T>& img, int x, int y) {
  Colour c{};
  for (int k = 0; k < img.channels; ++k)
    c[k] = unit(img.texels[(static_cast<std::size_t>(y) * img.width + x) * img.channels + k]);
  return c;
}

// Smallest texel-space stretch of a placement on a w x h page: local distance d is at
// least d * this many texels.
double min_texel_scale(const Placement& pl, int w, int h) {
  const Eigen::Matrix2d m = Eigen::Vector2d(w, h).asDiagonal() * pl.linear;
  // Smaller singular value of a 2x2 matrix: sigma^2 = (|m|^2 - sqrt(|m|^4 - 4 det^2)) / 2.
  const double f = m.squaredNorm(), d = m.determinant();
  return std::sqrt(std::max(0.0, (f - std::sqrt(std::max(0.0, f * f - 4 * d * d))) / 2));
}

// Chart of texel centre (x, y) of page `page` when it lies at least `inset` texels inside
// a chart (negative inset: up to about -inset texels outside), and its local surface point.
int chart_at(const ChartedSquare& s, const std::vector<Placement>& placements, int page, int w, int h,
             int x, int y, double inset, Eigen::Vector2d& local) {
  const Eigen::Vector2d uv((x + 0.5) / w, (y + 0.5) / h);
  for (int c = 0; c < s.chart_count(); ++c) {
    if (placements[c].page != page) continue;
    const double d = inset / min_texel_scale(placements[c], w, h);
    local = placements[c].local_of(uv);
    if (local.minCoeff() >= d && local.maxCoeff() <= s.chart_size() - d) return c;
  }
  return -1;
}

using ColourFn = std::function<Colour(int chart, const Eigen::Vector2d& xy)>;

// Old page whose texels within `margin` texels of a chart take colour(chart, surface
// point), the surface point extrapolated linearly past the chart; background elsewhere.
template <class T>
Image<T> paint(const ChartedSquare& s, const std::vector<Placement>& placements, int page, int w, int h,
               int channels, double margin, const ColourFn& colour, const Colour& background) {
  Image<T> img = blank<T>(w, h, channels);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Eigen::Vector2d local;
      const int c = chart_at(s, placements, page, w, h, x, y, -margin, local);
      set_texel(img, x, y, c < 0 ? background : colour(c, s.chart_origin(c) + local));
    }
  return img;
}

// Old layout shared by several tests: 4 charts of 40 x 40 texels on two 128 x 128 pages.
std::vector<Placement> old_placements() {
  const Eigen::Matrix2d s = 0.625 * Eigen::Matrix2d::Identity();  // 0.5 surface -> 40 texels
  return {{s, Eigen::Vector2d(10, 10) / 128, 0},
          {s, Eigen::Vector2d(70, 40) / 128, 0},
          {s, Eigen::Vector2d(10, 70) / 128, 1},
          {s, Eigen::Vector2d(60, 20) / 128, 1}};
}

// New layout: the same charts turned 90 degrees and shrunk onto one 160 x 100 page.
std::vector<Placement> turned_placements() {
  std::vector<Placement> out;
  for (int c = 0; c < 4; ++c)
    out.push_back({turn(0.35, 0, -1, 1, 0), Eigen::Vector2d(0.2 + 0.25 * c, 0.3 + 0.1 * (c % 2)), 0});
  return out;
}

Colour linear_colour(const Eigen::Vector2d& p) {
  return {0.1 + 0.6 * p.x() + 0.2 * p.y(), 0.9 - 0.5 * p.y() + 0.1 * p.x(), 0.2 + 0.3 * p.x() + 0.3 * p.y(),
          1.0};
}

template <class T>
struct Scene {
  ChartedSquare surface;
  std::vector<Placement> old_place, new_place;
  Layout old_layout, new_layout;
  std::vector<Image<T>> old_images;
  std::vector<PageSize> new_pages;

  std::vector<ImageView<T>> old_views() const {
    std::vector<ImageView<T>> v;
    for (const Image<T>& img : old_images) v.push_back(view_of(img));
    return v;
  }
  std::vector<Image<T>> bake(const BakeOptions& options = {}, BakeStats* stats = nullptr) const {
    const std::vector<ImageView<T>> views = old_views();
    const std::vector<PageSize> old_pages = sizes_of(views);
    return bake_map<T>(old_layout.view(old_pages), views, new_layout.view(new_pages), options, RunControl(), stats);
  }
};

template <class T>
Scene<T> scene(const std::vector<Placement>& old_place, const std::vector<Placement>& new_place,
               int old_size, const std::vector<PageSize>& new_pages, int channels, double margin,
               const ColourFn& colour, const Colour& background, int charts_per_side = 2, int quads = 4) {
  Scene<T> sc;
  sc.surface = charted_square(charts_per_side, quads);
  sc.old_place = old_place;
  sc.new_place = new_place;
  sc.old_layout = place(sc.surface, old_place);
  sc.new_layout = place(sc.surface, new_place);
  int old_page_count = 0;
  for (const Placement& p : old_place) old_page_count = std::max(old_page_count, p.page + 1);
  for (int p = 0; p < old_page_count; ++p)
    sc.old_images.push_back(
        paint<T>(sc.surface, old_place, p, old_size, old_size, channels, margin, colour, background));
  sc.new_pages = new_pages;
  return sc;
}

template <class T>
Scene<T> turned_scene(const ColourFn& colour, const Colour& background, int channels = 4) {
  return scene<T>(old_placements(), turned_placements(), 128, {{160, 100}}, channels, 3.0, colour,
                  background);
}

template <class T>
void expect_constant_everywhere() {
  const Colour c{0.3, 0.7, 0.123, 0.5};
  auto constant = [&](int, const Eigen::Vector2d&) { return c; };
  const Scene<T> sc = turned_scene<T>(constant, c);
  const Image<T> out = sc.bake()[0];
  ASSERT_EQ(out.channels, 4);
  const T expected[4] = {stored<T>(c[0]), stored<T>(c[1]), stored<T>(c[2]), stored<T>(c[3])};
  int wrong = 0;
  for (std::size_t i = 0; i < out.texels.size(); ++i) wrong += out.texels[i] != expected[i % 4];
  EXPECT_EQ(wrong, 0);
}

TEST(Bake, ConstantTextureStaysExactlyConstant8Bit) { expect_constant_everywhere<std::uint8_t>(); }
TEST(Bake, ConstantTextureStaysExactlyConstantFloat) { expect_constant_everywhere<float>(); }

// padding 0: a texel centre that the rasteriser dropped inside a chart would be filled
// by pull-push and break linearity instead of being patched by the padding pass.
template <class T>
void expect_linear_reproduced(double tolerance, int padding) {
  const Colour background{1.0, 0.0, 1.0, 1.0};
  auto colour = [](int, const Eigen::Vector2d& xy) { return linear_colour(xy); };
  const Scene<T> sc = turned_scene<T>(colour, background);
  BakeOptions options;
  options.padding = padding;
  const Image<T> out = sc.bake(options)[0];
  int checked = 0;
  double worst = 0;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      Eigen::Vector2d local;
      const int c = chart_at(sc.surface, sc.new_place, 0, out.width, out.height, x, y, 2.0, local);
      if (c < 0) continue;
      const Colour want = linear_colour(sc.surface.chart_origin(c) + local), got = texel(out, x, y);
      for (int k = 0; k < 4; ++k) worst = std::max(worst, std::abs(got[k] - want[k]));
      ++checked;
    }
  EXPECT_GT(checked, 4 * 100);
  EXPECT_LE(worst, tolerance);
}

TEST(Bake, LinearTextureReproducedAcrossTurnedScaledCharts8Bit) {
  expect_linear_reproduced<std::uint8_t>(1.0 / 255 + 1e-9, 4);
}
TEST(Bake, LinearTextureReproducedAcrossTurnedScaledChartsFloat) {
  expect_linear_reproduced<float>(1e-4, 4);
  expect_linear_reproduced<float>(1e-4, 0);
}

TEST(Bake, OldUvsOutsideThePageWrap) {
  auto colour = [](int, const Eigen::Vector2d& xy) { return linear_colour(xy); };
  Scene<float> sc = turned_scene<float>(colour, Colour{1.0, 0.0, 1.0, 1.0});
  const Image<float> inside = sc.bake()[0];
  sc.old_layout.uv.col(0).array() += 1.0;
  sc.old_layout.uv.col(1).array() -= 2.0;
  const Image<float> wrapped = sc.bake()[0];
  ASSERT_EQ(inside.texels.size(), wrapped.texels.size());
  for (std::size_t i = 0; i < inside.texels.size(); ++i) ASSERT_NEAR(inside.texels[i], wrapped.texels[i], 1e-5);
}

TEST(Bake, ChartsMovedByWholeTexelsAreCopiedExactly) {
  // Noise texture: any resampling blur or half-texel shift would change texels.
  auto none = [](int, const Eigen::Vector2d&) { return Colour{}; };
  const Eigen::Matrix2d scale = 0.5 * Eigen::Matrix2d::Identity();  // 32 texels on a 64 page
  Scene<std::uint8_t> sc = scene<std::uint8_t>({{scale, Eigen::Vector2d(8, 8) / 64, 0}},
                                               {{scale, Eigen::Vector2d(20, 13) / 64, 0}}, 64, {{64, 64}}, 3,
                                               0.0, none, Colour{}, 1, 4);
  std::uint32_t state = 12345;
  for (std::uint8_t& v : sc.old_images[0].texels) v = (state = state * 1664525u + 1013904223u) >> 24;
  const Image<std::uint8_t> out = sc.bake()[0];
  const Image<std::uint8_t>& old_page = sc.old_images[0];
  for (int y = 13; y < 13 + 32; ++y)
    for (int x = 20; x < 20 + 32; ++x)
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(out.texels[(y * 64 + x) * 3 + k], old_page.texels[((y - 5) * 64 + x - 12) * 3 + k])
            << x << "," << y;
}

TEST(Bake, FittedTexelsReadBilinearlyCloserToTheOldPage) {
  // Fine waves (periods of 3 to 4 texels) moved by a fraction of a texel: read
  // bilinearly at the same surface points, the fitted page must match the old
  // one better than centre samples.
  auto none = [](int, const Eigen::Vector2d&) { return Colour{}; };
  const Eigen::Matrix2d scale = 0.5 * Eigen::Matrix2d::Identity();  // 32 texels on a 64 page
  const Eigen::Vector2d shift(12.37, 5.61);                           // new texel - old texel
  Scene<float> sc = scene<float>({{scale, Eigen::Vector2d(8, 8) / 64, 0}},
                                 {{scale, (Eigen::Vector2d(8, 8) + shift) / 64, 0}}, 64, {{64, 64}}, 1, 0.0, none,
                                 Colour{}, 1, 4);
  Image<float>& old_page = sc.old_images[0];
  for (int y = 0; y < old_page.height; ++y)
    for (int x = 0; x < old_page.width; ++x)
      old_page.texels[y * old_page.width + x] =
          static_cast<float>(0.5 + 0.2 * std::sin(2 * M_PI * x / 3.3) + 0.2 * std::sin(2 * M_PI * y / 4.1));
  BakeOptions fit;
  fit.fit_texels = true;
  const Image<float> fitted = sc.bake(fit)[0], centres = sc.bake()[0];
  // Footprint{}: one bilinear tap.
  auto read = [](const Image<float>& img, double x, double y) {
    double value;
    sample_texture(view_of(img), Eigen::Vector2d(x, y), Footprint{}, &value);
    return value;
  };
  double fitted_error = 0, centre_error = 0;
  for (double y = 8 + shift.y() + 2; y < 8 + shift.y() + 30; y += 0.1)
    for (double x = 8 + shift.x() + 2; x < 8 + shift.x() + 30; x += 0.1) {
      const double want = read(sc.old_images[0], x - shift.x(), y - shift.y());
      fitted_error += std::pow(read(fitted, x, y) - want, 2);
      centre_error += std::pow(read(centres, x, y) - want, 2);
    }
  EXPECT_LT(fitted_error, 0.9 * centre_error);
}

TEST(SampleTexture, CubicNearOneToOneIsSharperThanBilinearAndNeverRings) {
  // A sine of period 5 texels along x, sampled between texel centres.
  constexpr double kTau = 6.283185307179586;
  Image<float> wave = blank<float>(40, 4, 1);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 40; ++x) wave.texels[y * 40 + x] = static_cast<float>(std::sin(kTau * (x + 0.5) / 5.0));
  const Footprint one_to_one = footprint_of(Eigen::Matrix2d::Identity());
  ASSERT_TRUE(one_to_one.cubic);
  EXPECT_FALSE(footprint_of(0.4 * Eigen::Matrix2d::Identity()).cubic);  // magnified: bilinear
  EXPECT_GT(footprint_of(3.0 * Eigen::Matrix2d::Identity()).samples_x, 1);  // minified: box
  double cubic_error = 0, bilinear_error = 0;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector2d at(10.0 + 0.5 * i / 2.0, 2.0);
    const double truth = std::sin(kTau * at.x() / 5.0);
    double c, b;
    sample_texture(view_of(wave), at, one_to_one, &c);
    sample_texture(view_of(wave), at, Footprint{}, &b);
    cubic_error += (c - truth) * (c - truth);
    bilinear_error += (b - truth) * (b - truth);
  }
  EXPECT_LT(cubic_error, 0.5 * bilinear_error);

  // A step: the cubic stays within the two texels it lies between.
  Image<float> step = blank<float>(8, 4, 1);
  for (int y = 0; y < 4; ++y)
    for (int x = 4; x < 8; ++x) step.texels[y * 8 + x] = 1.0f;
  for (double u = 3.5; u <= 4.5; u += 0.125) {
    double v;
    sample_texture(view_of(step), Eigen::Vector2d(u, 2.0), one_to_one, &v);
    EXPECT_GE(v, 0.0);
    EXPECT_LE(v, 1.0);
  }
}

TEST(Bake, QuarterTurnedChartsAreCopiedBitForBitAndCounted) {
  // Float noise: any blend of two texels would show in the low bits.
  auto none = [](int, const Eigen::Vector2d&) { return Colour{}; };
  const Eigen::Matrix2d kept = 0.5 * Eigen::Matrix2d::Identity();  // 32 texels on a 64 page
  const Eigen::Matrix2d turned = turn(0.5, 0, -1, 1, 0);
  // Old uv = o + kept * l, new uv = n + turned * l: old = o + kept * turned^-1 (new - n).
  const Eigen::Vector2d old_offset = Eigen::Vector2d(8, 8) / 64, new_offset = Eigen::Vector2d(45, 6) / 64;
  Scene<float> sc = scene<float>({{kept, old_offset, 0}}, {{turned, new_offset, 0}}, 64, {{64, 64}}, 3, 0.0, none,
                                 Colour{}, 1, 4);
  std::uint32_t state = 777;
  for (float& v : sc.old_images[0].texels) v = static_cast<float>((state = state * 1664525u + 1013904223u) >> 8) / 16777216.0f;
  BakeStats stats;
  const Image<float> out = sc.bake({}, &stats)[0];
  EXPECT_EQ(stats.covered_texels, 32 * 32);
  EXPECT_EQ(stats.copied_texels, stats.covered_texels);
  const Eigen::Matrix2d new_to_old = kept * turned.inverse();
  const Image<float>& old_page = sc.old_images[0];
  for (int y = 6; y < 6 + 32; ++y)
    for (int x = 45 - 32; x < 45; ++x) {
      const Eigen::Vector2d old_uv = old_offset + new_to_old * (Eigen::Vector2d(x + 0.5, y + 0.5) / 64 - new_offset);
      const int ox = static_cast<int>(std::floor(old_uv.x() * 64)), oy = static_cast<int>(std::floor(old_uv.y() * 64));
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(out.texels[(y * 64 + x) * 3 + k], old_page.texels[(oy * 64 + ox) * 3 + k]) << x << "," << y;
    }

  // Half a texel off the grid: resampled, none copied.
  Scene<float> off = scene<float>({{kept, old_offset, 0}}, {{turned, new_offset + Eigen::Vector2d(0.5, 0) / 64, 0}},
                                  64, {{64, 64}}, 3, 0.0, none, Colour{}, 1, 4);
  off.old_images = sc.old_images;
  off.bake({}, &stats);
  EXPECT_GT(stats.covered_texels, 0);
  EXPECT_EQ(stats.copied_texels, 0);
}

// Charts turned a quarter, mirrored in x, mirrored in y, and kept, on one 128 x 128 page.
std::vector<Placement> reoriented_placements() {
  const double s = 0.6;
  return {{turn(s, 0, -1, 1, 0), Eigen::Vector2d(0.45, 0.05), 0},
          {turn(s, -1, 0, 0, 1), Eigen::Vector2d(0.95, 0.05), 0},
          {turn(s, 1, 0, 0, -1), Eigen::Vector2d(0.05, 0.95), 0},
          {turn(s, 1, 0, 0, 1), Eigen::Vector2d(0.55, 0.55), 0}};
}
// How each chart's tangent frame turned in reoriented_placements().
Eigen::Matrix2d frame_turn(int chart) { return reoriented_placements()[chart].linear / 0.6; }

template <class T>
Image<T> bake_constant_normal(const Colour& code) {
  auto constant = [&](int, const Eigen::Vector2d&) { return code; };
  const Scene<T> sc = scene<T>(old_placements(), reoriented_placements(), 128, {{128, 128}}, 4, 3.0,
                               constant, code);
  BakeOptions options;
  options.normal_map = true;
  return sc.bake(options)[0];
}

template <class T>
void expect_flat_normals_stay_flat(const Colour& flat) {
  const Image<T> out = bake_constant_normal<T>(flat);
  int wrong = 0;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      const Colour got = texel(out, x, y);
      for (int k = 0; k < 4; ++k) wrong += unit(stored<T>(flat[k])) != got[k];
    }
  EXPECT_EQ(wrong, 0);
}

TEST(Bake, FlatNormalMapStaysExactlyFlatWhenChartsTurnOrMirror) {
  expect_flat_normals_stay_flat<float>({0.5, 0.5, 1.0, 0.25});
  expect_flat_normals_stay_flat<std::uint8_t>({128 / 255.0, 128 / 255.0, 1.0, 0.25});
}

TEST(Bake, TiltedNormalTurnsWithItsChartFloat) {
  const Eigen::Vector2d n(0.48, 0.36);  // z = 0.8
  const Image<float> out = bake_constant_normal<float>({(n.x() + 1) / 2, (n.y() + 1) / 2, 0.9, 0.25});
  const ChartedSquare surface = charted_square(2, 4);
  int checked = 0;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      Eigen::Vector2d local;
      const int c = chart_at(surface, reoriented_placements(), 0, out.width, out.height, x, y, 1.0, local);
      if (c < 0) continue;
      const Eigen::Vector2d want = frame_turn(c) * n;
      const Colour got = texel(out, x, y);
      EXPECT_NEAR(2 * got[0] - 1, want.x(), 1e-6) << "chart " << c;
      EXPECT_NEAR(2 * got[1] - 1, want.y(), 1e-6) << "chart " << c;
      EXPECT_FLOAT_EQ(got[2], 0.9f);
      EXPECT_FLOAT_EQ(got[3], 0.25f);
      ++checked;
    }
  EXPECT_GT(checked, 4 * 200);
}

TEST(Bake, TiltedNormalTurnsWithItsChart8Bit) {
  // 8-bit normals store 128 + 127 n: (61, 46) / 127 must come out as exact code permutations.
  const Image<std::uint8_t> out =
      bake_constant_normal<std::uint8_t>({189 / 255.0, 174 / 255.0, 230 / 255.0, 0.25});
  const std::array<std::array<int, 2>, 4> want = {
      {{128 - 46, 128 + 61}, {128 - 61, 174}, {189, 128 - 46}, {189, 174}}};
  const ChartedSquare surface = charted_square(2, 4);
  int checked = 0;
  for (int y = 0; y < out.height; ++y)
    for (int x = 0; x < out.width; ++x) {
      Eigen::Vector2d local;
      const int c = chart_at(surface, reoriented_placements(), 0, out.width, out.height, x, y, 1.0, local);
      if (c < 0) continue;
      const std::uint8_t* t = &out.texels[(static_cast<std::size_t>(y) * out.width + x) * 4];
      ASSERT_EQ(t[0], want[c][0]) << "chart " << c;
      ASSERT_EQ(t[1], want[c][1]) << "chart " << c;
      ASSERT_EQ(t[2], 230);
      ++checked;
    }
  EXPECT_GT(checked, 4 * 200);
}

// Distance in texels from texel centre (x, y) to the rectangle a chart covers.
double distance_to_chart(const ChartedSquare& s, const Placement& pl, int w, int h, int x, int y) {
  Eigen::Vector2d lo(1e9, 1e9), hi(-1e9, -1e9);
  for (const Eigen::Vector2d& corner : {Eigen::Vector2d(0, 0), Eigen::Vector2d(1, 0), Eigen::Vector2d(0, 1),
                                       Eigen::Vector2d(1, 1)}) {
    const Eigen::Vector2d uv = pl.offset + pl.linear * (s.chart_size() * corner);
    lo = lo.cwiseMin(Eigen::Vector2d(uv.x() * w, uv.y() * h));
    hi = hi.cwiseMax(Eigen::Vector2d(uv.x() * w, uv.y() * h));
  }
  const Eigen::Vector2d p(x + 0.5, y + 0.5);
  return (lo - p).cwiseMax(p - hi).cwiseMax(0.0).norm();
}

TEST(Bake, PaddingTakesChartColourAndFillLeavesNoBackground) {
  const Colour sentinel{1.0, 0.0, 1.0, 1.0};
  auto chart_colour = [](int c, const Eigen::Vector2d&) {
    return Colour{(20 + 40 * c) / 255.0, (100 + 30 * c) / 255.0, (200 - 40 * c) / 255.0, 1.0};
  };
  std::vector<Placement> spread = turned_placements();
  Scene<std::uint8_t> sc = scene<std::uint8_t>(old_placements(), spread, 128, {{160, 100}, {32, 32}}, 4,
                                               3.0, chart_colour, sentinel);
  BakeOptions options;
  options.padding = 4;
  const std::vector<Image<std::uint8_t>> out = sc.bake(options);
  const Image<std::uint8_t>& page = out[0];
  int near_checked = 0;
  for (int y = 0; y < page.height; ++y)
    for (int x = 0; x < page.width; ++x) {
      const Colour got = texel(page, x, y);
      // Every fill is an average of chart colours, whose green is >= 100; the sentinel's is 0.
      ASSERT_GE(got[1] * 255, 100 - 1e-9) << x << "," << y;
      std::vector<double> d;
      for (int c = 0; c < 4; ++c)
        d.push_back(distance_to_chart(sc.surface, spread[c], page.width, page.height, x, y));
      for (int c = 0; c < 4; ++c) {
        bool alone = true;
        for (int o = 0; o < 4; ++o) alone &= o == c || d[o] > 9.0;
        if (!alone || d[c] == 0 || d[c] > 3.5) continue;
        const Colour want = chart_colour(c, {});
        for (int k = 0; k < 3; ++k) EXPECT_NEAR(got[k], want[k], 1e-9) << x << "," << y;
        ++near_checked;
      }
    }
  EXPECT_GT(near_checked, 4 * 40);
  // A page no face lands on is still fully defined (zero).
  for (std::uint8_t v : out[1].texels) ASSERT_EQ(v, 0);
}

template <class T>
void expect_minified_checkerboard_is_averaged(double tolerance) {
  // One chart: old texels 64.5..192.5 of 256, new texels 16..48 of 64 (4x smaller). Each
  // new centre lands on an even old texel, so a single bilinear tap would read pure black.
  auto checker = [](int, const Eigen::Vector2d&) { return Colour{}; };
  Scene<T> sc = scene<T>({{0.5 * Eigen::Matrix2d::Identity(), Eigen::Vector2d(64.5, 64.5) / 256, 0}},
                         {{0.5 * Eigen::Matrix2d::Identity(), Eigen::Vector2d(16, 16) / 64, 0}}, 256,
                         {{64, 64}}, 1, 0.0, checker, Colour{}, 1, 2);
  Image<T>& old_page = sc.old_images[0];
  for (int y = 0; y < 256; ++y)
    for (int x = 0; x < 256; ++x) set_texel(old_page, x, y, {double((x + y) % 2)});
  const Image<T> out = sc.bake()[0];
  int checked = 0;
  for (int y = 17; y < 47; ++y)
    for (int x = 17; x < 47; ++x, ++checked)
      EXPECT_NEAR(texel(out, x, y)[0], 0.5, tolerance) << x << "," << y;
  EXPECT_EQ(checked, 30 * 30);
}

TEST(Bake, MinifiedCheckerboardAveragesInsteadOfAliasing) {
  expect_minified_checkerboard_is_averaged<std::uint8_t>(8.0 / 255);
  expect_minified_checkerboard_is_averaged<float>(0.03);
}

TEST(Bake, RejectsBadInputAndHonoursCancel) {
  auto constant = [](int, const Eigen::Vector2d&) { return Colour{0.5, 0.5, 0.5, 1.0}; };
  const Scene<std::uint8_t> sc = turned_scene<std::uint8_t>(constant, Colour{});
  const BakeOptions options;
  const RunControl run;
  auto bake = [&](const Layout& old_layout, const std::vector<ImageView<std::uint8_t>>& views,
                  const Layout& new_layout, const std::vector<PageSize>& pages, const RunControl& control) {
    const std::vector<PageSize> old_pages = sizes_of(views);
    return bake_map<std::uint8_t>(old_layout.view(old_pages), views, new_layout.view(pages), options, control);
  };

  std::vector<ImageView<std::uint8_t>> short_buffer = sc.old_views();
  short_buffer[1].size -= 1;
  EXPECT_THROW(bake(sc.old_layout, short_buffer, sc.new_layout, sc.new_pages, run), InputError);
  std::vector<ImageView<std::uint8_t>> wrong_width = sc.old_views();
  wrong_width[0].width += 1;
  EXPECT_THROW(bake(sc.old_layout, wrong_width, sc.new_layout, sc.new_pages, run), InputError);
  EXPECT_THROW(bake(sc.old_layout, {}, sc.new_layout, sc.new_pages, run), InputError);
  EXPECT_THROW(bake(sc.old_layout, sc.old_views(), sc.new_layout, {}, run), InputError);

  Layout bad_old = sc.old_layout;
  bad_old.face_page[3] = 2;  // only pages 0 and 1 exist
  EXPECT_THROW(bake(bad_old, sc.old_views(), sc.new_layout, sc.new_pages, run), InputError);
  Layout bad_new = sc.new_layout;
  bad_new.face_page[0] = -1;
  EXPECT_THROW(bake(sc.old_layout, sc.old_views(), bad_new, sc.new_pages, run), InputError);
  Layout nan_uv = sc.new_layout;
  nan_uv.uv(4, 1) = std::nan("");
  EXPECT_THROW(bake(sc.old_layout, sc.old_views(), nan_uv, sc.new_pages, run), InputError);
  Layout far_uv = sc.old_layout;
  far_uv.uv(2, 0) = 1e12;  // finite, but no texel index reaches it
  EXPECT_THROW(bake(far_uv, sc.old_views(), sc.new_layout, sc.new_pages, run), InputError);

  RunControl cancelled;
  cancelled.cancel();
  EXPECT_THROW(bake(sc.old_layout, sc.old_views(), sc.new_layout, sc.new_pages, cancelled), Cancelled);
}

// A colour map (4 channels) and a normal map (3 channels) baked in one pass come
// out bit for bit as each baked alone, and the stats count both maps.
TEST(Bake, MapsBakedInOnePassEqualEachBakedAlone) {
  auto colour = [](int, const Eigen::Vector2d& xy) { return linear_colour(xy); };
  auto normal = [](int c, const Eigen::Vector2d& xy) {
    return Colour{0.5 + 0.3 * xy.x(), 0.5 - 0.2 * c / 4.0, 0.9, 1.0};
  };
  const Scene<std::uint8_t> base = scene<std::uint8_t>(old_placements(), reoriented_placements(), 128, {{128, 128}},
                                                       4, 3.0, colour, Colour{1.0, 0.0, 1.0, 1.0});
  const Scene<std::uint8_t> normals = scene<std::uint8_t>(old_placements(), reoriented_placements(), 128,
                                                          {{128, 128}}, 3, 3.0, normal, Colour{0.5, 0.5, 1.0, 1.0});
  BakeOptions normal_options;
  normal_options.normal_map = true;
  BakeStats alone_stats;
  const Image<std::uint8_t> base_alone = base.bake({}, &alone_stats)[0];
  const Image<std::uint8_t> normal_alone = normals.bake(normal_options)[0];

  const std::vector<PageSize> old_pages = sizes_of(base.old_views());
  BakeStats stats;
  const auto together = bake_maps<std::uint8_t>(base.old_layout.view(old_pages),
                                                {{base.old_views(), false}, {normals.old_views(), true}},
                                                base.new_layout.view(base.new_pages), 4, RunControl(), &stats);
  ASSERT_EQ(together.size(), 2u);
  EXPECT_EQ(together[0][0].channels, 4);
  EXPECT_EQ(together[1][0].channels, 3);
  EXPECT_EQ(together[0][0].texels, base_alone.texels);
  EXPECT_EQ(together[1][0].texels, normal_alone.texels);
  EXPECT_EQ(stats.covered_texels, 2 * alone_stats.covered_texels);
}

}  // namespace
}  // namespace atlas
