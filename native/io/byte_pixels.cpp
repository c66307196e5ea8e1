#include "io/byte_pixels.hpp"

#include <algorithm>

namespace atlas {
namespace {

// Pixels per OpenMP iteration: large enough that scheduling costs nothing,
// small enough that a 4K texture still splits evenly between the cores.
constexpr std::size_t kBlock = 1 << 14;

inline std::uint8_t byte_of(float value) {
  const float scaled = value * 255.0f + 0.5f;
  if (!(scaled > 0.0f)) return 0;
  if (scaled >= 255.0f) return 255;
  return static_cast<std::uint8_t>(scaled);
}

}  // namespace

bool bytes_from_unit_floats(const float* in, std::size_t pixels, int channels, int kept, std::uint8_t* out) {
  const long long blocks = static_cast<long long>((pixels + kBlock - 1) / kBlock);
  bool filler = true;
#pragma omp parallel for schedule(static) reduction(&& : filler)
  for (long long b = 0; b < blocks; ++b) {
    const std::size_t end = std::min(pixels, static_cast<std::size_t>(b + 1) * kBlock);
    for (std::size_t p = static_cast<std::size_t>(b) * kBlock; p < end; ++p) {
      const float* pixel = in + p * channels;
      for (int k = 0; k < kept; ++k) out[p * kept + k] = byte_of(pixel[k]);
      for (int k = kept; k < channels; ++k)
        filler = filler && byte_of(pixel[k]) == (k < 3 ? out[p * kept + kept - 1] : 255);
    }
  }
  return filler;
}

}  // namespace atlas
