#include "bake/sample_texture.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace atlas {

namespace {

// Beyond this many old texels per new texel a single bilinear tap skips texels.
constexpr double kBilinearMaxExtent = 1.5;
// Below this many old texels per new texel (magnification) bilinear is kept.
constexpr double kCubicMinExtent = 2.0 / 3.0;
// 8 x 8 taps bound the cost; only extreme (> 8x) minification still aliases a little.
constexpr int kMaxSamplesPerAxis = 8;

// Written as a + (b - a) t so that equal inputs return exactly a: constant textures
// stay bit-exact through any filter weights.
inline double lerp(double a, double b, double t) { return a + (b - a) * t; }

int samples_along(double extent) {
  if (!(extent > 1.0)) return 1;
  return static_cast<int>(std::min<double>(std::ceil(extent), kMaxSamplesPerAxis));
}

// The two texels bracketing continuous coordinate u on a repeating axis of n texels
// (centres at +0.5), and the weight t of the second one.
struct Tap {
  int lo, hi;
  double t;
};

inline Tap wrapped_tap(double u, int n) {
  const double g = u - 0.5;
  // Common case first: inside the page no wrap is needed and truncation is floor.
  if (g >= 0 && g < n - 1) {
    const int lo = static_cast<int>(g);
    return {lo, lo + 1, g - lo};
  }
  // fmod is exact at any magnitude (g - n floor(g / n) is not: far off the
  // page, as a sliver's footprint can reach, its rounding exceeds n).
  double r = std::fmod(g, static_cast<double>(n));
  if (r < 0) r += n;
  if (!(r >= 0 && r < n)) r = 0;  // n by rounding, or g not finite
  const int lo = static_cast<int>(r);
  return {lo, lo + 1 == n ? 0 : lo + 1, r - lo};
}

// Bilinear interpolation of the four texels around the taps, C channels.
template <int C, class T>
void blend(const ImageView<T>& page, const Tap& x, const Tap& y, double* out) {
  const std::size_t row = static_cast<std::size_t>(page.width) * C;
  const T* r0 = page.texels + row * y.lo;
  const T* r1 = page.texels + row * y.hi;
  for (int k = 0; k < C; ++k) {
    const double bottom = lerp(r0[x.lo * C + k], r0[x.hi * C + k], x.t);
    const double top = lerp(r1[x.lo * C + k], r1[x.hi * C + k], x.t);
    out[k] = lerp(bottom, top, y.t);
  }
}

// Catmull-Rom weights of the texels at offsets -1, 0, 1, 2 from Tap::lo, for
// fraction t: w(d) = 1.5|d|^3 - 2.5|d|^2 + 1 for |d| <= 1, and
// -0.5|d|^3 + 2.5|d|^2 - 4|d| + 2 for 1 < |d| < 2. They sum to 1 and
// reproduce linear ramps, so constants and gradients stay exact.
inline void catmull_rom_weights(double t, double w[4]) {
  const double t2 = t * t, t3 = t2 * t;
  w[0] = -0.5 * t3 + t2 - 0.5 * t;
  w[1] = 1.5 * t3 - 2.5 * t2 + 1.0;
  w[2] = -1.5 * t3 + 2.0 * t2 + 0.5 * t;
  w[3] = 0.5 * t3 - 0.5 * t2;
}

// i modulo n in [0, n); the division only where i leaves the page.
inline int wrapped(int i, int n) { return i >= 0 && i < n ? i : (i % n + n) % n; }

// Four floats in one vector register (GCC and Clang vector extensions: SSE
// on x86, NEON on ARM).
typedef float Float4 __attribute__((vector_size(16)));

// Four consecutive values of a page as floats. On x86 the bytes are widened
// in registers: GCC converts a byte vector one lane at a time.
inline Float4 load4(const std::uint8_t* p) {
#if defined(__SSE2__)
  int bytes;
  std::memcpy(&bytes, p, sizeof bytes);
  const __m128i zero = _mm_setzero_si128();
  const __m128i words = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(bytes), zero), zero);
  return reinterpret_cast<Float4>(_mm_cvtepi32_ps(words));
#else
  typedef std::uint8_t Byte4 __attribute__((vector_size(4)));
  Byte4 bytes;
  std::memcpy(&bytes, p, sizeof bytes);
  return __builtin_convertvector(bytes, Float4);
#endif
}
inline Float4 load4(const float* p) {
  Float4 f;
  std::memcpy(&f, p, sizeof f);
  return f;
}

// Catmull-Rom over the 4 x 4 texels around the taps, each channel clamped to
// the range of the four bilinear texels: no ringing past the values it blends.
// A row's 4 texels are 4 C values side by side, that is C vectors of four:
// the rows are summed with their weights vector by vector, and the 4 texels'
// weights and the channel sums come last:
//   out_k = sum_i wx_i sum_j wy_j v(i, j, k).
template <int C, class T>
void cubic_blend(const ImageView<T>& page, const Tap& x, const Tap& y, double* out) {
  double wx[4], wy[4];
  catmull_rom_weights(x.t, wx);
  catmull_rom_weights(y.t, wy);
  // Inside the page the row's 4 texels are contiguous; at its edges they wrap.
  const bool contiguous = x.lo >= 1 && x.lo + 2 < page.width;
  int column[4];
  for (int i = 0; i < 4; ++i) column[i] = C * wrapped(x.lo - 1 + i, page.width);
  const std::size_t stride = static_cast<std::size_t>(page.width) * C;
  Float4 sum[C] = {}, row[2][C];
  for (int j = 0; j < 4; ++j) {
    const T* r = page.texels + stride * wrapped(y.lo - 1 + j, page.height);
    T gathered[4 * C];
    if (!contiguous)
      for (int i = 0; i < 4 * C; ++i) gathered[i] = r[column[i / C] + i % C];
    const T* values = contiguous ? r + column[0] : gathered;
    const float w = static_cast<float>(wy[j]);
    for (int v = 0; v < C; ++v) {
      const Float4 texels = load4(values + 4 * v);
      sum[v] += w * texels;
      if (j == 1 || j == 2) row[j - 1][v] = texels;
    }
  }
  float total[4 * C], low[4 * C], high[4 * C];
  for (int v = 0; v < C; ++v) {
    const Float4 weight = {static_cast<float>(wx[(4 * v) / C]), static_cast<float>(wx[(4 * v + 1) / C]),
                           static_cast<float>(wx[(4 * v + 2) / C]), static_cast<float>(wx[(4 * v + 3) / C])};
    const Float4 weighted = sum[v] * weight;
    std::memcpy(total + 4 * v, &weighted, sizeof weighted);
    const Float4 lo = row[0][v] < row[1][v] ? row[0][v] : row[1][v];
    const Float4 hi = row[0][v] > row[1][v] ? row[0][v] : row[1][v];
    std::memcpy(low + 4 * v, &lo, sizeof lo);
    std::memcpy(high + 4 * v, &hi, sizeof hi);
  }
  // Texel i's channel k is value i C + k; the bilinear texels are i = 1, 2.
  for (int k = 0; k < C; ++k) {
    const float value = (total[k] + total[C + k]) + (total[2 * C + k] + total[3 * C + k]);
    out[k] = std::clamp(value, std::min(low[C + k], low[2 * C + k]), std::max(high[C + k], high[2 * C + k]));
  }
}

// Channel count as a template argument: the per-tap loops fully unroll.
template <int C, class T>
void sample_channels(const ImageView<T>& page, const Eigen::Vector2d& at, const Footprint& footprint,
                     double* out) {
  const int nx = footprint.samples_x, ny = footprint.samples_y;
  if (nx * ny == 1) {
    const Tap x = wrapped_tap(at.x(), page.width), y = wrapped_tap(at.y(), page.height);
    if (footprint.cubic) cubic_blend<C>(page, x, y, out);
    else blend<C>(page, x, y, out);
    return;
  }
  // Stratified grid: tap (i, j) sits at the centre of cell (i, j) of the new texel,
  // i.e. at offset ((i + 0.5) / nx - 0.5, (j + 0.5) / ny - 0.5) new texels from its centre.
  double sum[C] = {}, tap[C];
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const Eigen::Vector2d cell((i + 0.5) / nx - 0.5, (j + 0.5) / ny - 0.5);
      const Eigen::Vector2d p = at + footprint.axes * cell;
      blend<C>(page, wrapped_tap(p.x(), page.width), wrapped_tap(p.y(), page.height), tap);
      for (int k = 0; k < C; ++k) sum[k] += tap[k];
    }
  // Summing n equal values is exact in double for n <= 64, so constants survive the mean.
  for (int k = 0; k < C; ++k) out[k] = sum[k] / (nx * ny);
}

}  // namespace

Footprint footprint_of(const Eigen::Matrix2d& new_to_old_texels) {
  Footprint footprint;
  footprint.axes = new_to_old_texels;
  const double extent_x = new_to_old_texels.col(0).norm();
  const double extent_y = new_to_old_texels.col(1).norm();
  if (std::max(extent_x, extent_y) <= kBilinearMaxExtent) {
    footprint.cubic = std::min(extent_x, extent_y) >= kCubicMinExtent;
    return footprint;
  }
  footprint.samples_x = samples_along(extent_x);
  footprint.samples_y = samples_along(extent_y);
  return footprint;
}

template <class T>
void sample_texture(const ImageView<T>& page, const Eigen::Vector2d& at, const Footprint& footprint,
                    double* out) {
  switch (page.channels) {
    case 1: return sample_channels<1>(page, at, footprint, out);
    case 2: return sample_channels<2>(page, at, footprint, out);
    case 3: return sample_channels<3>(page, at, footprint, out);
    default: return sample_channels<4>(page, at, footprint, out);
  }
}

template void sample_texture<std::uint8_t>(const ImageView<std::uint8_t>&, const Eigen::Vector2d&,
                                           const Footprint&, double*);
template void sample_texture<float>(const ImageView<float>&, const Eigen::Vector2d&, const Footprint&,
                                    double*);

}  // namespace atlas
