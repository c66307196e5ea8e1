#include "metrics.hpp"

#include <omp.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>
#include <utility>

#include "bake/sample_texture.hpp"
#include "charts/chart_graph.hpp"
#include "charts/degenerate_faces.hpp"
#include "core/geometry.hpp"
#include "core/rasterize_triangle.hpp"
#include "core/topology.hpp"

namespace atlas {
namespace {

// Rows per coverage work item: one thread counts a band from every face overlapping
// it, so the per-texel counters need no atomics and only a band-sized buffer.
constexpr int kBandRows = 32;

// ---- validation ------------------------------------------------------------

template <class T>
void require_images(const std::vector<ImageView<T>>& images, const UvLayout& atlas, const char* what) {
  int used = -1;
  for (Eigen::Index f = 0; f < atlas.face_page->size(); ++f) used = std::max(used, (*atlas.face_page)[f]);
  if (used >= static_cast<int>(images.size())) {
    std::ostringstream msg;
    msg << "compare_colors: " << what << " page " << used << " has no image (" << images.size() << " given)";
    throw InputError(msg.str());
  }
  for (int p = 0; p <= used; ++p) {
    const ImageView<T>& image = images[p];
    std::ostringstream msg;
    msg << "compare_colors: " << what << " image " << p << " ";
    if (!image.texels) msg << "has no texel buffer";
    else if (image.width <= 0 || image.height <= 0) msg << "has non-positive size";
    else if (image.channels < 1 || image.channels > kMaxTexelChannels)
      msg << "has " << image.channels << " channels; 1 to " << kMaxTexelChannels << " are supported";
    else if (image.size < static_cast<std::size_t>(image.width) * image.height * image.channels)
      msg << "buffer holds " << image.size << " values, fewer than width x height x channels";
    else continue;
    throw InputError(msg.str());
  }
}

// ---- small helpers ---------------------------------------------------------

// Winding of face f as its UVs are stored (float32 page units in Blender,
// glTF and the OBJ writers): +1 counter-clockwise, -1 clockwise, 0 when the
// stored corners are collinear. The sign of the exact determinant of the
// rounded corners, scaled to texels: every face counts, slivers included.
int stored_winding(const UvLayout& atlas, int f) {
  const PageSize& page = (*atlas.pages)[(*atlas.face_page)[f]];
  Eigen::Vector2d corner[3];
  for (int k = 0; k < 3; ++k)
    corner[k] = {static_cast<double>(static_cast<float>((*atlas.corner_uv)(3 * f + k, 0))) * page.width,
                 static_cast<double>(static_cast<float>((*atlas.corner_uv)(3 * f + k, 1))) * page.height};
  const double area = signed_area(corner[0], corner[1], corner[2]);
  return area > 0 ? 1 : area < 0 ? -1 : 0;
}

double face_signed_area_uv(const UvLayout& atlas, int f) {
  return signed_area(atlas.uv_texels(f, 0), atlas.uv_texels(f, 1), atlas.uv_texels(f, 2));
}

// The smallest value of v[lo, hi) whose cumulative weight, values ascending,
// reaches target (the last one if none does): quickselect on the weight of
// the lower half, linear on average where sorting would not be.
double weighted_select(std::vector<std::pair<double, double>>& v, std::size_t lo, std::size_t hi, double target) {
  while (hi - lo > 1) {
    const std::size_t mid = lo + (hi - lo) / 2;
    std::nth_element(v.begin() + lo, v.begin() + mid, v.begin() + hi);
    double below = 0;
    for (std::size_t i = lo; i < mid; ++i) below += v[i].second;
    if (below >= target) {
      hi = mid;
    } else {
      target -= below;
      lo = mid;
    }
  }
  return v[lo].first;
}

// Area-weighted percentiles: for each fraction q, the smallest value whose
// cumulative weight reaches q of the total. `values` is reordered in place.
std::vector<double> weighted_percentiles(std::vector<std::pair<double, double>>& values,
                                         const std::vector<double>& fractions) {
  std::vector<double> out(fractions.size(), 0.0);
  if (values.empty()) return out;
  double total = 0;
  for (const auto& v : values) total += v.second;
  if (!(total > 0)) return out;
  for (std::size_t i = 0; i < fractions.size(); ++i)
    out[i] = weighted_select(values, 0, values.size(), fractions[i] * total);
  return out;
}

// Unsigned interior angle (radians) of a 2D triangle at p; 0 when an edge has zero length.
double corner_angle(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& r) {
  const Eigen::Vector2d u = q - p, v = r - p;
  return std::atan2(std::abs(u.x() * v.y() - u.y() * v.x()), u.dot(v));
}

// ---- coverage --------------------------------------------------------------

struct Coverage {
  long long covered = 0;
  long long overlap = 0;
};

// The faces' UV triangles in texels, rows clipped to their page, and per
// face whether it claims any texel of its page (untextured faces do not).
struct PageTriangles {
  std::vector<TexelTriangle> tri;
  std::vector<char> live;
};

PageTriangles page_triangles(const UvLayout& atlas, int faces) {
  const std::vector<PageSize>& pages = *atlas.pages;
  const Eigen::VectorXi& face_page = *atlas.face_page;
  PageTriangles out{std::vector<TexelTriangle>(faces), std::vector<char>(faces, 0)};
#pragma omp parallel for schedule(static)
  for (int f = 0; f < faces; ++f) {
    const int p = face_page[f];
    if (p < 0) continue;
    if (!out.tri[f].setup(atlas.uv_texels(f, 0), atlas.uv_texels(f, 1), atlas.uv_texels(f, 2))) continue;
    TexelTriangle& t = out.tri[f];
    t.row_begin = std::max(t.row_begin, 0);
    t.row_end = std::min(t.row_end, pages[p].height);
    out.live[f] = t.row_begin < t.row_end && t.col_begin < pages[p].width && t.col_end > 0;
  }
  return out;
}

// The pages cut into bands of kBandRows rows, and the live faces of every
// band: what one coverage work item counts.
struct Bands {
  // Global band numbering: page p owns bands [base[p], base[p+1]).
  std::vector<int> base;
  std::vector<int> page;  // per band
  // Faces of every band (CSR, in face order).
  std::vector<long long> offsets;
  std::vector<int> faces;
};

Bands face_bands(const std::vector<PageSize>& pages, const Eigen::VectorXi& face_page, const PageTriangles& clipped) {
  const int faces = static_cast<int>(clipped.tri.size());
  Bands out;
  out.base.assign(pages.size() + 1, 0);
  for (std::size_t p = 0; p < pages.size(); ++p)
    out.base[p + 1] = out.base[p] + (pages[p].height + kBandRows - 1) / kBandRows;
  const int bands = out.base.back();
  // Calls visit(band, face) for every band each live face meets, in face order.
  auto for_each_face_band = [&](auto visit) {
    for (int f = 0; f < faces; ++f) {
      if (!clipped.live[f]) continue;
      const int base = out.base[face_page[f]];
      const TexelTriangle& t = clipped.tri[f];
      for (int b = t.row_begin / kBandRows; b <= (t.row_end - 1) / kBandRows; ++b) visit(base + b, f);
    }
  };
  out.offsets.assign(bands + 1, 0);
  for_each_face_band([&](int b, int) { ++out.offsets[b + 1]; });
  for (int b = 0; b < bands; ++b) out.offsets[b + 1] += out.offsets[b];
  out.faces.resize(out.offsets.back());
  std::vector<long long> cursor(out.offsets.begin(), out.offsets.end() - 1);
  for_each_face_band([&](int b, int f) { out.faces[cursor[b]++] = f; });
  out.page.resize(bands);
  for (std::size_t p = 0; p < pages.size(); ++p)
    for (int b = out.base[p]; b < out.base[p + 1]; ++b) out.page[b] = static_cast<int>(p);
  return out;
}

// Covered and overlapping texels of band b, counted in `band` (a buffer of
// kBandRows rows of the widest page).
Coverage band_coverage(const std::vector<PageSize>& pages, const Bands& bands, const std::vector<TexelTriangle>& tri,
                       int b, std::uint8_t* band) {
  const int p = bands.page[b], width = pages[p].width;
  const int y0 = (b - bands.base[p]) * kBandRows, y1 = std::min(pages[p].height, y0 + kBandRows);
  std::memset(band, 0, static_cast<std::size_t>(width) * (y1 - y0));
  for (long long i = bands.offsets[b]; i < bands.offsets[b + 1]; ++i) {
    const TexelTriangle& t = tri[bands.faces[i]];
    const int ya = std::max(y0, t.row_begin), yb = std::min(y1, t.row_end);
    for (int y = ya; y < yb; ++y) {
      int xa, xb;
      t.row_span(y, xa, xb);
      xa = std::max(xa, 0);
      xb = std::min(xb, width);
      std::uint8_t* row = band + static_cast<std::size_t>(y - y0) * width;
      for (int x = xa; x < xb; ++x) row[x] = static_cast<std::uint8_t>(row[x] + (row[x] < 2));
    }
  }
  const std::size_t n = static_cast<std::size_t>(width) * (y1 - y0);
  Coverage c;
  for (std::size_t i = 0; i < n; ++i) {
    c.covered += band[i] != 0;
    c.overlap += band[i] == 2;
  }
  return c;
}

// Texels of the pages that the first `faces` faces cover, and those two or more cover.
Coverage rasterise_coverage(int faces, const UvLayout& atlas) {
  const std::vector<PageSize>& pages = *atlas.pages;
  const PageTriangles clipped = page_triangles(atlas, faces);
  const Bands bands = face_bands(pages, *atlas.face_page, clipped);
  const int band_count = static_cast<int>(bands.page.size());

  int widest = 0;
  for (const PageSize& p : pages) widest = std::max(widest, p.width);

  // Per texel: 0, 1, or 2 = "two or more" triangles claim its centre. One
  // band buffer per thread, allocated here: a bad_alloc must not be thrown
  // inside the OpenMP region, where it would terminate the process.
  std::vector<std::vector<std::uint8_t>> band_counts(omp_get_max_threads());
  for (auto& counts : band_counts) counts.resize(static_cast<std::size_t>(widest) * kBandRows);
  long long covered = 0, overlap = 0;
#pragma omp parallel reduction(+ : covered, overlap)
  {
    std::vector<std::uint8_t>& counts = band_counts[omp_get_thread_num()];
#pragma omp for schedule(dynamic, 4)
    for (int b = 0; b < band_count; ++b) {
      if (bands.offsets[b] == bands.offsets[b + 1]) continue;
      const Coverage c = band_coverage(pages, bands, clipped.tri, b, counts.data());
      covered += c.covered;
      overlap += c.overlap;
    }
  }
  return {covered, overlap};
}

// rasterise_coverage of the faces drawing a triangle (page and corner UVs)
// no earlier face draws: a repeated face, which the pipeline gives the UVs of
// the face it repeats, is the same surface and claims no texel again.
Coverage distinct_coverage(const UvLayout& atlas, int faces) {
  const std::vector<int> drawn = first_of_equal_faces(*atlas.corner_uv, *atlas.face_page);
  if (static_cast<int>(drawn.size()) == faces) return rasterise_coverage(faces, atlas);
  RowMatrixX2d uv;
  Eigen::VectorXi page;
  take_face_uvs(*atlas.corner_uv, *atlas.face_page, drawn, uv, page);
  return rasterise_coverage(static_cast<int>(drawn.size()), {&uv, &page, atlas.pages});
}

// ---- colour sampling -------------------------------------------------------

inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

// (bits >> 11) * 2^-53: the top 53 bits as a double in [0, 1), every value equally likely.
inline double unit_double(std::uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

template <class T>
inline double texel_scale() {
  return 1.0;
}
template <>
inline double texel_scale<std::uint8_t>() {
  return 1.0 / 255.0;
}

}  // namespace

// ---- public ------------------------------------------------------------------

AtlasMeasures measure_atlas(const Mesh& mesh, const MeshTopology& topology, const UvLayout& atlas) {
  require_layout(atlas, mesh.face_count(), "measure_atlas", Untextured::allowed);
  if (topology.corner_edge.size() != 3 * static_cast<std::size_t>(mesh.face_count()))
    throw InputError("measure_atlas: topology was built for a different mesh");
  AtlasMeasures m;

  // The chart graph reads the layout from a Mesh: a copy of the geometry carrying this layout.
  Mesh layout_mesh;
  layout_mesh.positions = mesh.positions;
  layout_mesh.triangles = mesh.triangles;
  layout_mesh.corner_uv = *atlas.corner_uv;
  layout_mesh.face_page = *atlas.face_page;
  layout_mesh.pages = *atlas.pages;
  const ChartGraph graph = build_chart_graph(layout_mesh, topology, {});
  m.charts = graph.chart_count();
  for (const ChartStats& s : graph.charts) m.boundary_texels += s.perimeter_uv;
  m.seam_ratio = seam_length_ratio(mesh, topology, *atlas.corner_uv, *atlas.face_page);

  int flipped = 0;
  const int faces = mesh.face_count();
#pragma omp parallel for reduction(+ : flipped) schedule(static)
  for (int f = 0; f < faces; ++f) {
    const int chart = graph.face_chart[f];
    if (chart < 0) continue;
    const int winding = stored_winding(atlas, f);
    if (winding != 0 && (winding < 0) != graph.charts[chart].mirrored()) ++flipped;
  }
  m.flipped_faces = flipped;

  m.page_texels = page_texels(*atlas.pages);
  const Coverage coverage = distinct_coverage(atlas, faces);
  m.covered_texels = coverage.covered;
  m.overlap_texels = coverage.overlap;
  m.occupancy = m.page_texels > 0 ? static_cast<double>(m.covered_texels) / m.page_texels : 0.0;
  return m;
}

MapMeasures measure_map(const Mesh& mesh, const UvLayout& old_atlas, const UvLayout& new_atlas) {
  require_layout(old_atlas, mesh.face_count(), "measure_map (old)", Untextured::allowed);
  require_layout(new_atlas, mesh.face_count(), "measure_map (new)", Untextured::allowed);
  const int faces = mesh.face_count();

  // Per face: density ratio and 3D area (weight 0: skipped); per corner: angle error.
  std::vector<std::pair<double, double>> ratio(faces, {0.0, 0.0});
  std::vector<std::pair<double, double>> angle(3 * static_cast<std::size_t>(faces), {0.0, 0.0});
#pragma omp parallel for schedule(static)
  for (int f = 0; f < faces; ++f) {
    if ((*old_atlas.face_page)[f] < 0 || (*new_atlas.face_page)[f] < 0) continue;
    const double area = mesh.area_3d(f);
    const double old_uv = std::abs(face_signed_area_uv(old_atlas, f));
    if (!(area > 0) || !(old_uv > 0)) continue;
    const double new_uv = std::abs(face_signed_area_uv(new_atlas, f));
    ratio[f] = {new_uv / old_uv, area};
    const Eigen::Vector2d o[3] = {old_atlas.uv_texels(f, 0), old_atlas.uv_texels(f, 1), old_atlas.uv_texels(f, 2)};
    const Eigen::Vector2d n[3] = {new_atlas.uv_texels(f, 0), new_atlas.uv_texels(f, 1), new_atlas.uv_texels(f, 2)};
    for (int k = 0; k < 3; ++k) {
      const int k1 = (k + 1) % 3, k2 = (k + 2) % 3;
      const double error = std::abs(corner_angle(n[k], n[k1], n[k2]) - corner_angle(o[k], o[k1], o[k2]));
      angle[3 * static_cast<std::size_t>(f) + k] = {error * (180.0 / kPi), area / 3};
    }
  }
  // Drop skipped entries so they do not sit at value 0 with weight 0 in the order.
  auto drop_unweighted = [](std::vector<std::pair<double, double>>& v) {
    v.erase(std::remove_if(v.begin(), v.end(), [](const auto& e) { return !(e.second > 0); }), v.end());
  };
  drop_unweighted(ratio);
  drop_unweighted(angle);

  MapMeasures m;
  double total = 0, lost = 0;
  for (const auto& [r, w] : ratio) {
    total += w;
    if (r < kDensityFloor) lost += w;
  }
  m.density_loss_area_share = total > 0 ? lost / total : 0.0;
  const std::vector<double> rp = weighted_percentiles(ratio, {0.05, 0.50, 0.95});
  m.density_ratio_p5 = rp[0];
  m.density_ratio_p50 = rp[1];
  m.density_ratio_p95 = rp[2];
  const std::vector<double> ap = weighted_percentiles(angle, {0.50, 0.90, 0.99});
  m.angle_error_p50 = ap[0];
  m.angle_error_p90 = ap[1];
  m.angle_error_p99 = ap[2];
  return m;
}

namespace {

constexpr int kNoChart = -1, kManyCharts = -2;

// Per page of the atlas, per texel: the chart whose faces cover its centre,
// kNoChart, or kManyCharts where faces of several charts do.
std::vector<std::vector<int>> texel_charts(const UvLayout& atlas, const std::vector<PageSize>& sizes,
                                           const std::vector<int>& face_chart) {
  std::vector<std::vector<int>> owner(sizes.size());
  for (size_t p = 0; p < sizes.size(); ++p)
    owner[p].assign(static_cast<size_t>(sizes[p].width) * sizes[p].height, kNoChart);
  for (int f = 0; f < static_cast<int>(face_chart.size()); ++f) {
    const int p = (*atlas.face_page)[f];
    if (p < 0 || face_chart[f] < 0) continue;
    const PageSize page = sizes[p];
    const Eigen::Vector2d scale(page.width, page.height);
    Eigen::Vector2d corner[3];
    for (int k = 0; k < 3; ++k) corner[k] = atlas.corner_uv->row(3 * f + k).transpose().cwiseProduct(scale);
    // Tiled UVs (UDIM tiles, repeating textures) are read wrapped, as
    // sample_texture reads them: the triangle moves by whole pages to start
    // in this one, and what passes its far borders wraps around.
    const Eigen::Vector2d tile =
        (corner[0].cwiseMin(corner[1]).cwiseMin(corner[2]).array() / scale.array()).floor().matrix();
    const Eigen::Vector2d shift = tile.cwiseProduct(scale);
    TexelTriangle t;
    if (!tile.allFinite() || !t.setup(corner[0] - shift, corner[1] - shift, corner[2] - shift)) continue;
    for (int y = std::max(0, t.row_begin); y < std::min(t.row_begin + page.height, t.row_end); ++y) {
      int x0, x1;
      t.row_span(y, x0, x1);
      for (int x = std::max(0, x0); x < std::min(x0 + page.width, x1); ++x) {
        int& o = owner[p][static_cast<size_t>(y % page.height) * page.width + x % page.width];
        o = o == kNoChart || o == face_chart[f] ? face_chart[f] : kManyCharts;
      }
    }
  }
  return owner;
}

// Whether the four texels bilinear sampling reads at `at` (texels, wrapping
// as sample_texture does) all belong to `chart`.
bool bilinear_texels_in_chart(const std::vector<int>& owner, const PageSize& page, const Eigen::Vector2d& at,
                              int chart) {
  const int x0 = static_cast<int>(std::floor(at.x() - 0.5)), y0 = static_cast<int>(std::floor(at.y() - 0.5));
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int x = ((x0 + dx) % page.width + page.width) % page.width;
      const int y = ((y0 + dy) % page.height + page.height) % page.height;
      if (owner[static_cast<size_t>(y) * page.width + x] != chart) return false;
    }
  return true;
}

// PSNR = -10 log10(MSE) for values in [0, 1] (peak 1), MSE = error / values.
double psnr_of(double error, long long values) {
  const double mse = values > 0 ? error / values : 0.0;
  const double psnr = mse > 0 ? -10.0 * std::log10(mse) : kMaxPsnrDb;
  // Capped both ways: identical colours give +99, absurd float values at worst -99, never NaN.
  return std::isfinite(psnr) ? std::clamp(psnr, -kMaxPsnrDb, kMaxPsnrDb) : -kMaxPsnrDb;
}

// Faces textured in both layouts with positive 3D area, and the cumulative
// 3D area over them: what surface points are drawn from.
struct AreaCdf {
  std::vector<int> face;
  std::vector<double> cdf;
  double total = 0;
};

AreaCdf textured_area(const Mesh& mesh, const UvLayout& old_atlas, const UvLayout& new_atlas) {
  AreaCdf out;
  for (int f = 0; f < mesh.face_count(); ++f) {
    if ((*old_atlas.face_page)[f] < 0 || (*new_atlas.face_page)[f] < 0) continue;
    const double a = mesh.area_3d(f);
    if (!(a > 0)) continue;
    out.total += a;
    out.face.push_back(f);
    out.cdf.push_back(out.total);
  }
  return out;
}

// The two layouts compared, with what tells a clean sample from a border one.
template <class T>
struct ColorPair {
  const UvLayout& old_atlas;
  const std::vector<ImageView<T>>& old_images;
  const UvLayout& new_atlas;
  const std::vector<ImageView<T>>& new_images;
  const std::vector<int>& face_chart;          // per face
  const std::vector<std::vector<int>>& owner;  // texel_charts of the old layout
  const std::vector<PageSize>& old_sizes;      // of the old images
};

// Colour differences of some samples; [0] clean and [1] border points.
struct ColorSums {
  std::array<double, 2> error = {0.0, 0.0};  // squared differences
  std::array<long long, 2> values = {0, 0};  // channel values compared
  long long off = 0, clean = 0;              // samples off by > 32/255, clean samples
};

// Texel position in `image` of barycentrics (w0, w1, w2) of face f in `atlas`.
template <class T>
Eigen::Vector2d texel_at(const UvLayout& atlas, const ImageView<T>& image, int f, double w0, double w1, double w2) {
  const RowMatrixX2d& uv = *atlas.corner_uv;
  const Eigen::Vector2d p = w0 * uv.row(3 * f).transpose() + w1 * uv.row(3 * f + 1).transpose() +
                            w2 * uv.row(3 * f + 2).transpose();
  return Eigen::Vector2d(p.x() * image.width, p.y() * image.height);
}

// Adds to sums the colours of both layouts at barycentrics (w0, w1, w2) of face f.
template <class T>
void add_sample(const ColorPair<T>& pair, int f, double w0, double w1, double w2, ColorSums& sums) {
  double old_px[kMaxTexelChannels], new_px[kMaxTexelChannels];
  const int old_page = (*pair.old_atlas.face_page)[f];
  const ImageView<T>& old_image = pair.old_images[old_page];
  const ImageView<T>& new_image = pair.new_images[(*pair.new_atlas.face_page)[f]];
  const Eigen::Vector2d old_at = texel_at(pair.old_atlas, old_image, f, w0, w1, w2);
  sample_texture(old_image, old_at, Footprint{}, old_px);
  sample_texture(new_image, texel_at(pair.new_atlas, new_image, f, w0, w1, w2), Footprint{}, new_px);
  const bool clean = pair.owner.empty() || bilinear_texels_in_chart(pair.owner[old_page], pair.old_sizes[old_page],
                                                                    old_at, pair.face_chart[f]);
  const int kind = clean ? 0 : 1;
  const int channels = std::min({3, old_image.channels, new_image.channels});
  bool is_off = false;
  for (int c = 0; c < channels; ++c) {
    double d = std::abs(new_px[c] - old_px[c]) * texel_scale<T>();
    if (!std::isfinite(d)) d = 1.0;
    sums.error[kind] += d * d;
    is_off = is_off || d > 32.0 / 255.0;
  }
  sums.values[kind] += channels;
  sums.off += is_off;
  sums.clean += kind == 0;
}

// Sums of samples [begin, end) of `samples`, drawn over `area` from `stream`.
template <class T>
ColorSums sample_run(const ColorPair<T>& pair, const AreaCdf& area, int samples, std::uint64_t stream, int begin,
                     int end) {
  ColorSums sums;
  // Jittered stratified picks: sample i lands uniformly in the i-th of `samples`
  // equal slices of the cumulative area, so picks rise with i and the face search
  // is a merge walk; samples of one face are consecutive, which keeps texel reads local.
  std::size_t j = 0;
  for (int i = begin; i < end; ++i) {
    const std::uint64_t state = stream + 3 * static_cast<std::uint64_t>(i);
    const double pick = (i + unit_double(splitmix64(state))) / samples * area.total;
    const double s = std::sqrt(unit_double(splitmix64(state + 1))), t = unit_double(splitmix64(state + 2));
    if (i == begin) j = std::upper_bound(area.cdf.begin(), area.cdf.end(), pick) - area.cdf.begin();
    while (j < area.cdf.size() && area.cdf[j] <= pick) ++j;
    j = std::min(j, area.face.size() - 1);
    const double w0 = 1 - s, w1 = s * (1 - t), w2 = s * t;  // uniform barycentrics
    add_sample(pair, area.face[j], w0, w1, w2, sums);
  }
  return sums;
}

// The fidelity figures of `samples` samples from their sums per chunk, added in chunk order.
ColorFidelity fidelity_of(const std::vector<ColorSums>& chunk_sums, int samples) {
  ColorSums sums;
  for (const ColorSums& chunk : chunk_sums) {
    for (int k = 0; k < 2; ++k) sums.error[k] += chunk.error[k], sums.values[k] += chunk.values[k];
    sums.off += chunk.off;
    sums.clean += chunk.clean;
  }
  ColorFidelity result;
  result.clean_samples = sums.clean;
  result.samples = samples;
  result.share_off_32 = static_cast<double>(sums.off) / samples;
  result.psnr_db = psnr_of(sums.error[0] + sums.error[1], sums.values[0] + sums.values[1]);
  result.psnr_clean_db = psnr_of(sums.error[0], sums.values[0]);
  result.psnr_border_db = psnr_of(sums.error[1], sums.values[1]);
  return result;
}

}  // namespace

template <class T>
ColorFidelity compare_colors(const Mesh& mesh, const UvLayout& old_atlas, const std::vector<ImageView<T>>& old_images,
                             const UvLayout& new_atlas, const std::vector<ImageView<T>>& new_images, int samples,
                             unsigned seed, bool borders) {
  require_layout(old_atlas, mesh.face_count(), "compare_colors (old)", Untextured::allowed);
  require_layout(new_atlas, mesh.face_count(), "compare_colors (new)", Untextured::allowed);
  require_images(old_images, old_atlas, "old");
  require_images(new_images, new_atlas, "new");
  const AreaCdf area = textured_area(mesh, old_atlas, new_atlas);
  if (area.face.empty() || samples <= 0) return ColorFidelity{};

  std::vector<PageSize> old_sizes;
  for (const ImageView<T>& image : old_images) old_sizes.push_back({image.width, image.height});
  std::vector<int> face_chart;
  std::vector<std::vector<int>> owner;  // empty: every sample counts as clean
  if (borders) {
    face_chart = build_chart_graph(mesh, build_topology(mesh.triangles, mesh.vertex_count()), {}).face_chart;
    owner = texel_charts(old_atlas, old_sizes, face_chart);
  }
  const ColorPair<T> pair{old_atlas, old_images, new_atlas, new_images, face_chart, owner, old_sizes};

  constexpr int kChunk = 4096;  // per-chunk partial sums keep the total independent of thread count
  const int chunks = static_cast<int>((static_cast<long long>(samples) + kChunk - 1) / kChunk);
  std::vector<ColorSums> chunk_sums(chunks);
  const std::uint64_t stream = splitmix64(0x5eed0000ull ^ seed);
#pragma omp parallel for schedule(dynamic, 1)
  for (int chunk = 0; chunk < chunks; ++chunk) {
    const int begin = chunk * kChunk, end = samples - begin < kChunk ? samples : begin + kChunk;
    chunk_sums[chunk] = sample_run(pair, area, samples, stream, begin, end);
  }
  ColorFidelity result = fidelity_of(chunk_sums, samples);
  if (!borders) {
    result.clean_samples = 0;
    result.psnr_clean_db = result.psnr_border_db = std::numeric_limits<double>::quiet_NaN();
  }
  return result;
}

template ColorFidelity compare_colors<std::uint8_t>(const Mesh&, const UvLayout&,
                                                    const std::vector<ImageView<std::uint8_t>>&, const UvLayout&,
                                                    const std::vector<ImageView<std::uint8_t>>&, int, unsigned, bool);
template ColorFidelity compare_colors<float>(const Mesh&, const UvLayout&, const std::vector<ImageView<float>>&,
                                             const UvLayout&, const std::vector<ImageView<float>>&, int, unsigned,
                                             bool);

}  // namespace atlas
