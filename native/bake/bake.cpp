#include "bake/bake.hpp"

#include <omp.h>

#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <sstream>
#include <tuple>

#include "bake/bilinear_fit.hpp"
#include "bake/pull_push_fill.hpp"
#include "bake/sample_texture.hpp"
#include "bake/texel_encoding.hpp"
#include "core/geometry.hpp"
#include "core/hash_words.hpp"
#include "core/plane_predicates.hpp"
#include "core/rasterize_triangle.hpp"

namespace atlas {

namespace {

// Rows per parallel work item. One thread rasterises a band from all faces overlapping
// it, in face order: writes never race and "first face wins" does not depend on
// scheduling, so the output is deterministic.
constexpr int kBandRows = 16;
// New triangles with a smaller doubled area (texels^2) have no usable new->old map.
constexpr double kMinDoubledArea = 1e-9;
// A face copies texels when its new->old Jacobian is within this of a signed
// permutation and its texel centres within this (old texels) of old centres:
// far below what bilinear weights could show in 8 or 32 bits, far above the
// rounding of UVs stored in page units.
constexpr double kCopyTolerance = 1e-5;
// The least-squares fit (bilinear_fit.hpp) reads kFitSamples x kFitSamples
// points per texel: denser grids fit a little closer for proportionally more
// time (bench/README.md).
constexpr int kFitSamples = 2;
// mu of the fit per sample of a texel: texels that few samples read stay near
// their baked value.
constexpr double kFitPull = 1e-2;
// Conjugate-gradient steps of the fit: it starts from the baked texels, and
// the system is as well conditioned as a mass matrix away from chart borders,
// so its first step takes nearly all of the gain (bench/README.md).
constexpr int kFitIterations = 1;
// is_set values: 0 empty (pull-push fills it), kResampled a texel the fit may
// change, kKept one it keeps (copied unresampled, or a box-filtered average).
constexpr std::uint8_t kResampled = 1, kKept = 2;

// ---- validation ------------------------------------------------------------

template <class T>
int require_old_pages(const std::vector<ImageView<T>>& pages) {
  if (pages.empty()) throw InputError("bake: no old texture pages given");
  const int channels = pages[0].channels;
  for (std::size_t p = 0; p < pages.size(); ++p) {
    const ImageView<T>& page = pages[p];
    std::ostringstream msg;
    msg << "bake: old page " << p << " ";
    if (!page.texels) msg << "has no texel buffer";
    else if (page.width <= 0 || page.height <= 0)
      msg << "has non-positive size " << page.width << "x" << page.height;
    else if (page.channels < 1 || page.channels > kMaxTexelChannels)
      msg << "has " << page.channels << " channels; 1 to " << kMaxTexelChannels << " are supported";
    else if (page.channels != channels)
      msg << "has " << page.channels << " channels but page 0 has " << channels;
    else if (page.size != static_cast<std::size_t>(page.width) * page.height * page.channels)
      msg << "buffer holds " << page.size << " values, expected " << page.width << "x" << page.height
          << "x" << page.channels;
    else continue;
    throw InputError(msg.str());
  }
  return channels;
}

// The old images must be the old layout's pages, size for size.
template <class T>
void require_matching_pages(const std::vector<ImageView<T>>& images, const std::vector<PageSize>& pages) {
  std::ostringstream msg;
  if (images.size() != pages.size()) {
    msg << "bake: " << images.size() << " old image(s) for " << pages.size() << " old page(s)";
    throw InputError(msg.str());
  }
  for (std::size_t p = 0; p < pages.size(); ++p)
    if (images[p].width != pages[p].width || images[p].height != pages[p].height) {
      msg << "bake: old page " << p << " is " << pages[p].width << "x" << pages[p].height << " but its image is "
          << images[p].width << "x" << images[p].height;
      throw InputError(msg.str());
    }
}

// ---- per-face geometry -----------------------------------------------------

// Rotation (det >= 0) or reflection (det < 0) closest to m: the orthogonal factor of its
// polar decomposition. For m = [a b; c d], trace(Q^T m) is maximised over rotations
// [p -q; q p] by (p, q) ~ (a + d, c - b) and over reflections [p q; q -p] by
// (p, q) ~ (a - d, b + c). Normalising rather than using atan2 keeps quarter turns exact.
Eigen::Matrix2d orthogonal_factor(const Eigen::Matrix2d& m) {
  const bool mirrors = m.determinant() < 0;
  double p = mirrors ? m(0, 0) - m(1, 1) : m(0, 0) + m(1, 1);
  double q = mirrors ? m(0, 1) + m(1, 0) : m(1, 0) - m(0, 1);
  const double r = std::hypot(p, q);
  if (!(r > 0)) return Eigen::Matrix2d::Identity();  // m == 0: old triangle is a point
  p /= r;
  q /= r;
  Eigen::Matrix2d out;
  if (mirrors) out << p, q, q, -p;
  else out << p, -q, q, p;
  return out;
}

// One face, ready to rasterise on its new page and to sample its old page.
struct FaceMap {
  int new_page = -1;  // -1: degenerate in the new layout, never rasterised
  int old_page = 0;
  // Zero until map_face sets them (a degenerate face keeps the zeros).
  std::array<Eigen::Vector2d, 3> corner = {Eigen::Vector2d::Zero(), Eigen::Vector2d::Zero(),
                                           Eigen::Vector2d::Zero()};  // new-page texels
  Eigen::Vector2d old_origin = Eigen::Vector2d::Zero();               // corner 0 in old-page texels
  Eigen::Matrix2d new_to_old = Eigen::Matrix2d::Zero();               // Jacobian: old texels per new texel
  Footprint footprint;                                                // new texel's extent in the old page
  Eigen::Matrix2d frame_turn = Eigen::Matrix2d::Identity();           // how the tangent frame turned: applied to normal XY
  bool copies = false;                    // texel centres land on old texel centres (see kCopyTolerance)

  // Affine map old = old_origin + new_to_old (p - corner 0): barycentric interpolation.
  Eigen::Vector2d old_position(const Eigen::Vector2d& p) const {
    return old_origin + new_to_old * (p - corner[0]);
  }
};

// Whether old = origin + m (p - corner0) maps every texel centre p onto an old
// texel centre: m a signed permutation (quarter turns, mirrors) and the centre
// of texel (0, 0) landing on one. Then all do, since m maps integer steps to
// integer steps.
bool lands_on_texel_centres(const Eigen::Matrix2d& m, const Eigen::Vector2d& origin,
                            const Eigen::Vector2d& corner0) {
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 2; ++j)
      if (std::abs(m(i, j) - std::round(m(i, j))) > kCopyTolerance) return false;
  if (std::abs(std::abs(m.determinant()) - 1.0) > kCopyTolerance ||
      std::abs(m(0, 0) * m(0, 1)) + std::abs(m(1, 0) * m(1, 1)) > kCopyTolerance)
    return false;
  const Eigen::Vector2d at = origin + m * (Eigen::Vector2d(0.5, 0.5) - corner0);
  for (int i = 0; i < 2; ++i)
    if (std::abs(at[i] - 0.5 - std::round(at[i] - 0.5)) > kCopyTolerance) return false;
  return true;
}

Eigen::Matrix2d edge_matrix(const std::array<Eigen::Vector2d, 3>& v) {
  Eigen::Matrix2d m;
  m << v[1] - v[0], v[2] - v[0];
  return m;
}

FaceMap map_face(int f, const UvLayout& old_layout, const PageSize& old_size, const UvLayout& new_layout,
                 const PageSize& new_size) {
  const Eigen::Vector2d old_scale(old_size.width, old_size.height);
  const Eigen::Vector2d new_scale(new_size.width, new_size.height);
  std::array<Eigen::Vector2d, 3> old_uv, new_uv, old_texel;
  FaceMap face;
  for (int k = 0; k < 3; ++k) {
    old_uv[k] = old_layout.corner_uv->row(3 * f + k).transpose();
    new_uv[k] = new_layout.corner_uv->row(3 * f + k).transpose();
    old_texel[k] = old_uv[k].cwiseProduct(old_scale);
    face.corner[k] = new_uv[k].cwiseProduct(new_scale);
  }
  face.old_page = (*old_layout.face_page)[f];
  const Eigen::Matrix2d new_edges = edge_matrix(face.corner);
  const double doubled_area = new_edges.determinant();
  if (!(std::abs(doubled_area) > kMinDoubledArea)) return face;
  face.new_page = (*new_layout.face_page)[f];
  face.old_origin = old_texel[0];
  face.new_to_old = edge_matrix(old_texel) * new_edges.inverse();
  face.footprint = footprint_of(face.new_to_old);
  face.copies = lands_on_texel_centres(face.new_to_old, face.old_origin, face.corner[0]);
  // J = dNewUV/dOldUV is the inverse of old-per-new, whose orthogonal factor is the
  // transpose. Old-per-new exists even when the old triangle is degenerate. UV units,
  // not texels: renderers derive tangent frames from UVs, whatever the page aspect.
  const Eigen::Matrix2d old_per_new_uv = edge_matrix(old_uv) * edge_matrix(new_uv).inverse();
  face.frame_turn = orthogonal_factor(old_per_new_uv).transpose();
  return face;
}

std::vector<FaceMap> map_faces(const UvLayout& old_layout, const UvLayout& new_layout) {
  const int face_count = static_cast<int>(new_layout.face_page->size());
  std::vector<FaceMap> faces(face_count);
#pragma omp parallel for schedule(static)
  for (int f = 0; f < face_count; ++f)
    faces[f] = map_face(f, old_layout, (*old_layout.pages)[(*old_layout.face_page)[f]], new_layout,
                        (*new_layout.pages)[(*new_layout.face_page)[f]]);
  return faces;
}

// Whether the faces of two coinciding edges (3 f + k) lie on either side of it.
bool opposite_sides(const std::vector<FaceMap>& faces, int edge_a, int edge_b) {
  auto side = [&](int edge) {
    const FaceMap& face = faces[edge / 3];
    const int k = edge % 3;
    return signed_area(face.corner[k], face.corner[(k + 1) % 3], face.corner[(k + 2) % 3]) > 0;
  };
  // Both corners of the edge are shared; it may run the other way in the second face.
  const FaceMap& fa = faces[edge_a / 3];
  const FaceMap& fb = faces[edge_b / 3];
  const bool same_direction = fa.corner[edge_a % 3] == fb.corner[edge_b % 3];
  return (side(edge_a) != side(edge_b)) == same_direction;
}

// Where an edge lies: its page and its ends, the lexicographically smaller first.
struct EdgePlace {
  int page = -1;
  std::array<double, 4> ends{};
  bool operator==(const EdgePlace& o) const { return page == o.page && ends == o.ends; }
  std::uint64_t hash() const {
    std::array<std::uint64_t, 5> words{static_cast<std::uint64_t>(page)};
    std::memcpy(&words[1], ends.data(), sizeof ends);
    return hash_words(words.data(), words.size());
  }
};

EdgePlace place_of(const FaceMap& face, int k) {
  // + 0.0 turns -0.0 into 0.0: equal places must hash alike, bit for bit.
  Eigen::Vector2d a = face.corner[k].array() + 0.0, b = face.corner[(k + 1) % 3].array() + 0.0;
  if (std::tie(b.x(), b.y()) < std::tie(a.x(), a.y())) std::swap(a, b);
  return {face.new_page, {a.x(), a.y(), b.x(), b.y()}};
}

// Per face, bit k set when its edge from corner k to corner k + 1 is a
// chart border of the new layout: not shared (same page, same two corner
// positions) with exactly one other face lying on its other side. The union
// of the faces is bounded by these edges alone (stacked or folded faces keep
// theirs), so the point of the union nearest to a texel outside it lies on
// one of them. Degenerate faces are never rasterised and count for none.
std::vector<std::uint8_t> border_edges(const std::vector<FaceMap>& faces) {
  // Open addressing: each slot keeps the first edge (3 f + k) found at a
  // place, with its hash's high half, which rules out nearly every other place
  // without reading that edge's face; per edge, the first one at its place,
  // how many lie there and the second.
  const int edges = static_cast<int>(3 * faces.size());
  std::size_t slots = 16;
  while (slots < static_cast<std::size_t>(edges)) slots *= 2;
  struct Slot {
    std::uint32_t tag = 0;
    int edge = -1;
  };
  std::vector<Slot> table(slots);
  std::vector<int> first(edges, -1), count(edges, 0), second(edges, -1);
  for (int edge = 0; edge < edges; ++edge) {
    if (faces[edge / 3].new_page < 0) continue;
    const EdgePlace place = place_of(faces[edge / 3], edge % 3);
    const std::uint64_t hash = place.hash();
    const auto tag = static_cast<std::uint32_t>(hash >> 32);
    std::size_t slot = hash & (slots - 1);
    for (; table[slot].edge >= 0; slot = (slot + 1) & (slots - 1)) {
      const Slot& other = table[slot];
      if (other.tag == tag && place_of(faces[other.edge / 3], other.edge % 3) == place) break;
    }
    if (table[slot].edge < 0) table[slot] = {tag, edge};
    const int head = table[slot].edge;
    first[edge] = head;
    if (++count[head] == 2) second[head] = edge;
  }
  std::vector<std::uint8_t> border(faces.size(), 0);
#pragma omp parallel for schedule(static)
  for (int f = 0; f < static_cast<int>(faces.size()); ++f)
    for (int k = 0; k < 3; ++k) {
      const int head = first[3 * f + k];
      if (head >= 0 && (count[head] != 2 || !opposite_sides(faces, head, second[head])))
        border[f] |= static_cast<std::uint8_t>(1 << k);
    }
  return border;
}

// Inclusive texel ranges whose centres lie within `reach` texels of the face's bounding
// box, clipped to the page; empty when x0 > x1 or y0 > y1.
struct TexelBox {
  int x0, y0, x1, y1;
};

TexelBox texel_box(const FaceMap& face, double reach, int width, int height) {
  const double lo_x = std::min({face.corner[0].x(), face.corner[1].x(), face.corner[2].x()});
  const double hi_x = std::max({face.corner[0].x(), face.corner[1].x(), face.corner[2].x()});
  const double lo_y = std::min({face.corner[0].y(), face.corner[1].y(), face.corner[2].y()});
  const double hi_y = std::max({face.corner[0].y(), face.corner[1].y(), face.corner[2].y()});
  // Centre i + 0.5 >= lo - reach  <=>  i >= lo - reach - 0.5. Clamped in double first:
  // far-away UVs must not overflow the int conversion.
  auto first = [reach](double lo, int n) {
    return static_cast<int>(std::clamp(std::ceil(lo - reach - 0.5), 0.0, double(n)));
  };
  auto last = [reach](double hi, int n) {
    return static_cast<int>(std::clamp(std::floor(hi + reach - 0.5), -1.0, double(n - 1)));
  };
  return {first(lo_x, width), first(lo_y, height), last(hi_x, width), last(hi_y, height)};
}

// Faces overlapping each band of kBandRows rows (padding reach included), in
// increasing face order, as compressed rows: band b holds face[start[b] .. start[b+1]).
struct BandFaces {
  std::vector<int> page_first_band;  // size pages + 1
  std::vector<int> start;
  std::vector<int> face;
};

BandFaces bin_faces(const std::vector<FaceMap>& faces, const std::vector<PageSize>& pages, double reach) {
  BandFaces bins;
  bins.page_first_band.assign(pages.size() + 1, 0);
  for (std::size_t p = 0; p < pages.size(); ++p)
    bins.page_first_band[p + 1] = bins.page_first_band[p] + (pages[p].height + kBandRows - 1) / kBandRows;
  bins.start.assign(bins.page_first_band.back() + 1, 0);
  auto for_each_band = [&](auto&& visit) {
    for (std::size_t f = 0; f < faces.size(); ++f) {
      const int p = faces[f].new_page;
      if (p < 0) continue;
      const TexelBox box = texel_box(faces[f], reach, pages[p].width, pages[p].height);
      if (box.x0 > box.x1 || box.y0 > box.y1) continue;
      for (int b = box.y0 / kBandRows; b <= box.y1 / kBandRows; ++b)
        visit(bins.page_first_band[p] + b, static_cast<int>(f));
    }
  };
  for_each_band([&](int band, int) { ++bins.start[band + 1]; });
  for (std::size_t b = 1; b < bins.start.size(); ++b) bins.start[b] += bins.start[b - 1];
  bins.face.resize(bins.start.back());
  std::vector<int> cursor(bins.start.begin(), bins.start.end() - 1);
  for_each_band([&](int band, int f) { bins.face[cursor[band]++] = f; });
  return bins;
}

// ---- texel values ----------------------------------------------------------

// Tangent-space normal XY codes: n = 2c - 1 for float texels, n = (c - 128) / 127 for
// 8-bit ones. 8-bit maps store flat as 128, which must decode to exactly 0, or a quarter
// turn would drift flat texels to 127; the symmetric range 1..255 also makes quarter
// turns and mirrors exact permutations of codes.
template <class T>
struct NormalCode;

template <>
struct NormalCode<float> {
  static double decode(double c) { return 2.0 * c - 1.0; }
  static double encode(double n) { return (n + 1.0) / 2.0; }
};

template <>
struct NormalCode<std::uint8_t> {
  static double decode(double c) { return (c - 128.0) / 127.0; }
  static double encode(double n) { return 128.0 + 127.0 * n; }
};

// The new tangent axes, in old UV directions, are R^T e_x and R^T e_y; the same surface
// normal therefore has new XY components R n_xy (R a rotation, or a reflection when the
// chart was mirrored). Z is the normal along the surface normal and does not change.
template <class T>
void reorient_normal(const Eigen::Matrix2d& frame_turn, double* channels) {
  const Eigen::Vector2d n(NormalCode<T>::decode(channels[0]), NormalCode<T>::decode(channels[1]));
  const Eigen::Vector2d turned = frame_turn * n;
  channels[0] = NormalCode<T>::encode(turned.x());
  channels[1] = NormalCode<T>::encode(turned.y());
}

template <class T>
struct BakeJob {
  const std::vector<FaceMap>& faces;
  const std::vector<std::uint8_t>& border;  // see border_edges
  const std::vector<BakeSource<T>>& maps;
  int padding;
};

// Value of one map at old-page point `at` (texels) of a face: the old page
// sampled over the face's footprint.
template <class T>
void bake_texel(const BakeSource<T>& map, const FaceMap& face, const Eigen::Vector2d& at, T* out) {
  const ImageView<T>& old_page = map.old_pages[face.old_page];
  double value[kMaxTexelChannels];
  sample_texture(old_page, at, face.footprint, value);
  if (map.normal_map) reorient_normal<T>(face.frame_turn, value);
  for (int k = 0; k < old_page.channels; ++k) out[k] = encode_texel<T>(value[k]);
}

// Value of one map at the old texel (x, y) a copying face's texel centre lands on.
template <class T>
void copy_texel(const BakeSource<T>& map, const FaceMap& face, int x, int y, T* out) {
  const ImageView<T>& old_page = map.old_pages[face.old_page];
  const T* texel = old_page.texels + (static_cast<std::size_t>(y) * old_page.width + x) * old_page.channels;
  if (!map.normal_map) {
    std::copy(texel, texel + old_page.channels, out);
    return;
  }
  double value[kMaxTexelChannels];
  for (int k = 0; k < old_page.channels; ++k) value[k] = texel[k];
  reorient_normal<T>(face.frame_turn, value);
  for (int k = 0; k < old_page.channels; ++k) out[k] = encode_texel<T>(value[k]);
}

// ---- rasterisation ---------------------------------------------------------

// Rows [row0, row1] of one new page p, in every map, with the set flags of its texels.
template <class T>
struct BandTarget {
  int row0, row1, width, height;
  int p;
  std::vector<std::vector<Image<T>>>& maps;  // [map][page]
  std::vector<std::uint8_t>& is_set;

  std::size_t index(int x, int y) const { return static_cast<std::size_t>(y) * width + x; }
  T* texel(std::size_t m, std::size_t i) const {
    Image<T>& page = maps[m][p];
    return page.texels.data() + i * page.channels;
  }
};

// Every map's value at new-page point p of the face.
template <class T>
void bake_texels(const BakeJob<T>& job, const FaceMap& face, const Eigen::Vector2d& p, const BandTarget<T>& band,
                 std::size_t i) {
  const Eigen::Vector2d at = face.old_position(p);
  for (std::size_t m = 0; m < job.maps.size(); ++m) bake_texel(job.maps[m], face, at, band.texel(m, i));
}

// Every map's value at new texel centre p of a copying face: the old texel it
// lands on, wrapped as sample_texture wraps.
template <class T>
void copy_texels(const BakeJob<T>& job, const FaceMap& face, const Eigen::Vector2d& p, const BandTarget<T>& band,
                 std::size_t i) {
  const Eigen::Vector2d at = face.old_position(p);
  const PageSize size{job.maps[0].old_pages[face.old_page].width, job.maps[0].old_pages[face.old_page].height};
  const int x = ((static_cast<int>(std::lround(at.x() - 0.5)) % size.width) + size.width) % size.width;
  const int y = ((static_cast<int>(std::lround(at.y() - 0.5)) % size.height) + size.height) % size.height;
  for (std::size_t m = 0; m < job.maps.size(); ++m) copy_texel(job.maps[m], face, x, y, band.texel(m, i));
}

// Whether the fit reads the face: not when it copies texels (already exact)
// or minifies (its texels average a footprint; point samples would alias).
bool fitted(const FaceMap& face) {
  return !face.copies && face.footprint.samples_x == 1 && face.footprint.samples_y == 1;
}

// Bakes the texels of the band whose centres the face claims and no earlier face took.
// TexelTriangle decides coverage exactly, so faces sharing an edge tile it without gaps.
template <class T>
void cover_band(const BakeJob<T>& job, const FaceMap& face, const BandTarget<T>& band, BakeStats& stats) {
  // Set up per band rather than kept per face: faces span a band or two, and
  // a kept raster would more than double the memory of every face's map.
  TexelTriangle raster;
  if (!raster.setup(face.corner[0], face.corner[1], face.corner[2])) return;
  const std::uint8_t claimed = fitted(face) ? kResampled : kKept;
  const int last_row = std::min(raster.row_end - 1, band.row1);
  for (int y = std::max(raster.row_begin, band.row0); y <= last_row; ++y) {
    int x0, x1;
    raster.row_span(y, x0, x1);
    for (int x = std::max(x0, 0); x < std::min(x1, band.width); ++x) {
      const std::size_t i = band.index(x, y);
      if (band.is_set[i]) continue;
      band.is_set[i] = claimed;
      ++stats.covered_texels;
      const Eigen::Vector2d centre(x + 0.5, y + 0.5);
      if (face.copies) {
        copy_texels(job, face, centre, band, i);
        ++stats.copied_texels;
      } else {
        bake_texels(job, face, centre, band, i);
      }
    }
  }
}

// Nearest face found so far for every uncovered texel of a band. Only touched entries
// are reset between bands: clearing whole bands would cost more than the padding itself.
struct PaddingCandidates {
  std::vector<double> distance2;       // +inf where no face is within reach
  std::vector<int> face;               // -1 where no face is within reach
  std::vector<Eigen::Vector2d> point;  // closest point of that face, new-page texels
  std::vector<std::size_t> touched;    // capacity for every entry: never reallocates

  explicit PaddingCandidates(std::size_t n)
      : distance2(n, std::numeric_limits<double>::infinity()), face(n, -1), point(n) {
    touched.reserve(n);
  }
  void clear() {
    for (std::size_t local : touched) {
      distance2[local] = std::numeric_limits<double>::infinity();
      face[local] = -1;
    }
    touched.clear();
  }
};

// The closest point to p on the face's border edges (edges: its bits, not 0).
Eigen::Vector2d closest_on_border(const FaceMap& face, std::uint8_t edges, const Eigen::Vector2d& p) {
  Eigen::Vector2d best;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    if (!(edges >> k & 1)) continue;
    const Eigen::Vector2d q = closest_on_segment(face.corner[k], face.corner[(k + 1) % 3], p);
    if ((q - p).squaredNorm() < best_d2) best = q, best_d2 = (q - p).squaredNorm();
  }
  return best;
}

// Records the face as the padding source of uncovered texels within `padding` texels
// (centre to its border edges) that no earlier face is strictly closer to.
template <class T>
void collect_padding(const FaceMap& face, std::uint8_t edges, int face_index, double padding,
                     const BandTarget<T>& band, PaddingCandidates& candidates) {
  const TexelBox box = texel_box(face, padding, band.width, band.height);
  for (int y = std::max(box.y0, band.row0); y <= std::min(box.y1, band.row1); ++y)
    for (int x = box.x0; x <= box.x1; ++x) {
      if (band.is_set[band.index(x, y)]) continue;
      const Eigen::Vector2d p(x + 0.5, y + 0.5);
      const Eigen::Vector2d q = closest_on_border(face, edges, p);
      const double d2 = (q - p).squaredNorm();
      const std::size_t local = static_cast<std::size_t>(y - band.row0) * band.width + x;
      if (d2 > padding * padding || d2 >= candidates.distance2[local]) continue;
      if (candidates.face[local] < 0) candidates.touched.push_back(local);
      candidates.distance2[local] = d2;
      candidates.face[local] = face_index;
      candidates.point[local] = q;
    }
}

// Edge texels take the old texture at the nearest point of the nearest face: the chart
// is extrapolated with its own border colours, not blended with the fill.
template <class T>
void pad_band(const BakeJob<T>& job, const int* band_faces, int count, const BandTarget<T>& band,
              PaddingCandidates& candidates) {
  for (int j = 0; j < count; ++j)
    if (const std::uint8_t edges = job.border[band_faces[j]])
      collect_padding(job.faces[band_faces[j]], edges, band_faces[j], job.padding, band, candidates);
  for (std::size_t local : candidates.touched) {
    const std::size_t i = band.index(0, band.row0) + local;
    band.is_set[i] = kResampled;
    bake_texels(job, job.faces[candidates.face[local]], candidates.point[local], band, i);
  }
  candidates.clear();
}

template <class T>
void rasterize(const BakeJob<T>& job, const BandFaces& bins, const std::vector<PageSize>& pages,
               std::vector<std::vector<Image<T>>>& baked, std::vector<std::vector<std::uint8_t>>& is_set,
               const RunControl& control, BakeStats& stats) {
  const int band_count = bins.page_first_band.back();
  int widest = 0;
  for (const PageSize& page : pages) widest = std::max(widest, page.width);
  // Allocated up front: nothing may throw inside the parallel region.
  std::vector<PaddingCandidates> scratch;
  for (int t = 0; t < omp_get_max_threads(); ++t)
    scratch.emplace_back(static_cast<std::size_t>(kBandRows) * widest);
  long long covered = 0, copied = 0;
#pragma omp parallel for schedule(dynamic) reduction(+ : covered, copied)
  for (int b = 0; b < band_count; ++b) {
    if (control.cancelled()) continue;
    BakeStats band_stats;
    const auto after = std::upper_bound(bins.page_first_band.begin(), bins.page_first_band.end(), b);
    const int p = static_cast<int>(after - bins.page_first_band.begin()) - 1;
    const int row0 = (b - bins.page_first_band[p]) * kBandRows;
    const BandTarget<T> band{row0, std::min(row0 + kBandRows, pages[p].height) - 1, pages[p].width, pages[p].height,
                             p, baked, is_set[p]};
    const int* band_faces = bins.face.data() + bins.start[b];
    const int count = bins.start[b + 1] - bins.start[b];
    for (int j = 0; j < count; ++j) cover_band(job, job.faces[band_faces[j]], band, band_stats);
    if (job.padding > 0) pad_band(job, band_faces, count, band, scratch[omp_get_thread_num()]);
    covered += band_stats.covered_texels;
    copied += band_stats.copied_texels;
  }
  control.throw_if_cancelled();
  stats.covered_texels += covered;
  stats.copied_texels += copied;
}

// ---- least-squares fit -------------------------------------------------------

// Per map, its channels in the fit (0: a normal map, whose per-face turns the
// fit would blur across chart borders).
template <class T>
std::vector<int> fitted_channels(const std::vector<BakeSource<T>>& maps) {
  std::vector<int> channels;
  for (const BakeSource<T>& map : maps) channels.push_back(map.normal_map ? 0 : map.old_pages[0].channels);
  return channels;
}

// Rows the fit solves at once (a multiple of kBandRows), and rows solved
// beside them on either side but not written: a conjugate-gradient step
// reaches one texel further, so after kFitIterations steps the written rows
// barely depend on where the solved ones stop.
constexpr int kFitStripRows = 16 * kBandRows;
constexpr int kFitHaloRows = kBandRows;
static_assert(kFitHaloRows >= kFitIterations + 2, "the halo must outreach the fit's steps");

// One thread's memory for the fit, set aside before the parallel loop.
struct FitScratch {
  BilinearFit fit;
  std::vector<std::uint8_t> claimed;  // the points of one band already claimed by a face
  std::vector<std::array<double, kMaxTexelChannels>> values;  // per map: the target at one point
  std::vector<const double*> targets;                          // per map: its values (set by sample_band)

  FitScratch(const std::vector<int>& channels, int width)
      : fit(channels),
        claimed(static_cast<std::size_t>(kBandRows) * kFitSamples * width * kFitSamples),
        values(channels.size()),
        targets(channels.size()) {
    fit.reserve(width, kFitStripRows + 2 * kFitHaloRows);
  }
};

// The fit's samples of one band of a page: kFitSamples^2 points per texel in
// the band's faces, at rows y within [y_min, y_max], the first face to claim a
// point keeping it; each map's target is the old page read bilinearly there,
// as a renderer reads it.
template <class T>
void sample_band(const BakeJob<T>& job, const int* band_faces, int count, int band_row0, int width, double y_min,
                 double y_max, FitScratch& scratch) {
  const int sub_width = width * kFitSamples, sub_row0 = band_row0 * kFitSamples;
  const int first = std::max(sub_row0, static_cast<int>(std::ceil(y_min * kFitSamples - 0.5)));
  const int last =
      std::min(sub_row0 + kBandRows * kFitSamples - 1, static_cast<int>(std::floor(y_max * kFitSamples - 0.5)));
  if (first > last) return;
  std::vector<std::uint8_t>& claimed = scratch.claimed;
  std::fill(claimed.begin(), claimed.begin() + static_cast<std::size_t>(last - sub_row0 + 1) * sub_width, 0);
  for (std::size_t m = 0; m < scratch.values.size(); ++m) scratch.targets[m] = scratch.values[m].data();
  const Footprint bilinear;
  for (int j = 0; j < count; ++j) {
    const FaceMap& face = job.faces[band_faces[j]];
    TexelTriangle fine;
    if (!fine.setup(kFitSamples * face.corner[0], kFitSamples * face.corner[1], kFitSamples * face.corner[2]))
      continue;
    for (int y = std::max(fine.row_begin, first); y <= std::min(fine.row_end - 1, last); ++y) {
      int x0, x1;
      fine.row_span(y, x0, x1);
      for (int x = std::max(x0, 0); x < std::min(x1, sub_width); ++x) {
        std::uint8_t& taken = claimed[static_cast<std::size_t>(y - sub_row0) * sub_width + x];
        if (taken) continue;
        taken = 1;
        if (!fitted(face)) continue;
        const Eigen::Vector2d p((x + 0.5) / kFitSamples, (y + 0.5) / kFitSamples);
        const Eigen::Vector2d at = face.old_position(p);
        for (std::size_t m = 0; m < job.maps.size(); ++m)
          if (!job.maps[m].normal_map)
            sample_texture(job.maps[m].old_pages[face.old_page], at, bilinear, scratch.values[m].data());
        scratch.fit.add_sample(p.x(), p.y(), scratch.targets.data());
      }
    }
  }
}

// Fits the maps of page p (filled already; normal maps stay as baked) in
// strips of kFitStripRows rows, each solved with kFitHaloRows more on either
// side, one strip per thread.
template <class T>
void fit_page(const BakeJob<T>& job, const BandFaces& bins, int p, const PageSize& page,
              std::vector<std::vector<Image<T>>>& baked, const std::vector<std::uint8_t>& is_set,
              const RunControl& control) {
  const std::vector<int> channels = fitted_channels(job.maps);
  // What the strips start from: their halos reach rows that other strips write.
  std::vector<Image<T>> sampled(job.maps.size());
  for (std::size_t m = 0; m < job.maps.size(); ++m)
    if (channels[m] > 0) sampled[m] = baked[m][p];
  std::vector<std::uint8_t> kept(is_set.size());
  for (std::size_t i = 0; i < kept.size(); ++i) kept[i] = is_set[i] == kKept;
  const int first_band = bins.page_first_band[p], bands = bins.page_first_band[p + 1] - first_band;
  const int strips = (page.height + kFitStripRows - 1) / kFitStripRows;
  const double mu = kFitPull * kFitSamples * kFitSamples;
  // Built in place: a copy would not keep the memory reserve() set aside.
  std::vector<FitScratch> scratch;
  scratch.reserve(omp_get_max_threads());
  for (int t = 0; t < omp_get_max_threads(); ++t) scratch.emplace_back(channels, page.width);
#pragma omp parallel for schedule(dynamic)
  for (int s = 0; s < strips; ++s) {
    if (control.cancelled()) continue;
    const int write0 = s * kFitStripRows, write1 = std::min(write0 + kFitStripRows, page.height);
    const int row0 = std::max(write0 - kFitHaloRows, 0), row1 = std::min(write1 + kFitHaloRows, page.height);
    FitScratch& mine = scratch[omp_get_thread_num()];
    BilinearFit& fit = mine.fit;
    fit.reset(page.width, row0, row1);
    for (int b = row0 / kBandRows; b < std::min(bands, (row1 + kBandRows - 1) / kBandRows); ++b) {
      const int start = bins.start[first_band + b], count = bins.start[first_band + b + 1] - start;
      sample_band(job, bins.face.data() + start, count, b * kBandRows, page.width, row0 + 0.5, row1 - 0.5, mine);
    }
    fit.mark_free(kept);
    for (std::size_t m = 0; m < job.maps.size(); ++m)
      if (channels[m] > 0) fit.solve(static_cast<int>(m), sampled[m], mu, kFitIterations, write0, write1, baked[m][p]);
  }
  control.throw_if_cancelled();
}

}  // namespace

template <class T>
std::vector<std::vector<Image<T>>> bake_maps(const UvLayout& old_layout, const std::vector<BakeSource<T>>& maps,
                                             const UvLayout& new_layout, int padding, const RunControl& control,
                                             BakeStats* stats, bool fit_texels) {
  if (maps.empty()) throw InputError("bake: no map given");
  const Eigen::Index face_count = old_layout.face_page ? old_layout.face_page->size() : 0;
  require_layout(old_layout, face_count, "bake: old layout", Untextured::refused);
  require_layout(new_layout, face_count, "bake: new layout", Untextured::refused);
  for (const BakeSource<T>& map : maps) {
    const int channels = require_old_pages(map.old_pages);
    require_matching_pages(map.old_pages, *old_layout.pages);
    if (map.normal_map && channels < 2) throw InputError("bake: a normal map needs at least 2 channels");
  }
  const std::vector<PageSize>& new_pages = *new_layout.pages;
  if (new_pages.empty()) throw InputError("bake: no new page sizes given");
  if (padding < 0) throw InputError("bake: padding must not be negative");
  control.throw_if_cancelled();

  const std::vector<FaceMap> faces = map_faces(old_layout, new_layout);
  // One extra texel of reach: coverage uses vertices snapped to 1/256 texel.
  const BandFaces bins = bin_faces(faces, new_pages, padding + 1.0);
  const std::vector<std::uint8_t> border = border_edges(faces);
  std::vector<std::vector<Image<T>>> baked(maps.size(), std::vector<Image<T>>(new_pages.size()));
  std::vector<std::vector<std::uint8_t>> is_set(new_pages.size());
  for (std::size_t p = 0; p < new_pages.size(); ++p) {
    const std::size_t texels = static_cast<std::size_t>(new_pages[p].width) * new_pages[p].height;
    for (std::size_t m = 0; m < maps.size(); ++m) {
      Image<T>& image = baked[m][p];
      image.width = new_pages[p].width;
      image.height = new_pages[p].height;
      image.channels = maps[m].old_pages[0].channels;
      image.texels.resize(texels * image.channels);
    }
    is_set[p].assign(texels, 0);
  }
  // Sampling is most of the work; the fill of each image takes the rest.
  BakeStats counted;
  const BakeJob<T> job{faces, border, maps, padding};
  rasterize(job, bins, new_pages, baked, is_set, control, counted);
  if (stats) {
    stats->covered_texels = counted.covered_texels * static_cast<long long>(maps.size());
    stats->copied_texels = counted.copied_texels * static_cast<long long>(maps.size());
  }
  control.progress("bake", 0.8);
  const std::size_t images = maps.size() * new_pages.size();
  for (std::size_t i = 0; i < images; ++i) {
    pull_push_fill(baked[i / new_pages.size()][i % new_pages.size()], is_set[i % new_pages.size()], control);
    control.progress("bake", 0.8 + (fit_texels ? 0.1 : 0.2) * double(i + 1) / images);
  }
  for (std::size_t p = 0; fit_texels && p < new_pages.size(); ++p) {
    fit_page(job, bins, static_cast<int>(p), new_pages[p], baked, is_set[p], control);
    control.progress("bake", 0.9 + 0.1 * double(p + 1) / new_pages.size());
  }
  return baked;
}

template <class T>
std::vector<Image<T>> bake_map(const UvLayout& old_layout, const std::vector<ImageView<T>>& old_pages,
                               const UvLayout& new_layout, const BakeOptions& options, const RunControl& control,
                               BakeStats* stats) {
  return std::move(bake_maps<T>(old_layout, {{old_pages, options.normal_map}}, new_layout, options.padding, control,
                                stats, options.fit_texels)
                       .front());
}

template std::vector<Image<std::uint8_t>> bake_map<std::uint8_t>(const UvLayout&,
                                                                  const std::vector<ImageView<std::uint8_t>>&,
                                                                  const UvLayout&, const BakeOptions&,
                                                                  const RunControl&, BakeStats*);
template std::vector<Image<float>> bake_map<float>(const UvLayout&, const std::vector<ImageView<float>>&,
                                                   const UvLayout&, const BakeOptions&, const RunControl&,
                                                   BakeStats*);
template std::vector<std::vector<Image<std::uint8_t>>> bake_maps<std::uint8_t>(
    const UvLayout&, const std::vector<BakeSource<std::uint8_t>>&, const UvLayout&, int, const RunControl&, BakeStats*,
    bool);
template std::vector<std::vector<Image<float>>> bake_maps<float>(const UvLayout&, const std::vector<BakeSource<float>>&,
                                                                 const UvLayout&, int, const RunControl&, BakeStats*,
                                                                 bool);

}  // namespace atlas
