// How a value computed in double precision is stored back into a texel of type T.
#pragma once
#include <cstdint>

namespace atlas {

// Texels hold 1 to 4 channels (grey, grey + alpha, RGB, RGBA): the baker keeps
// per-texel scratch values on the stack.
constexpr int kMaxTexelChannels = 4;

template <class T>
inline T encode_texel(double value);

// Float texels keep the value as computed: no colour conversion, no clamping.
template <>
inline float encode_texel<float>(double value) {
  return static_cast<float>(value);
}

// 8-bit texels round to nearest and clamp to [0, 255]. Written so that a NaN
// maps to 0 instead of reaching an undefined float->int conversion.
template <>
inline std::uint8_t encode_texel<std::uint8_t>(double value) {
  if (!(value > 0.0)) return 0;
  if (value >= 255.0) return 255;
  return static_cast<std::uint8_t>(value + 0.5);
}

}  // namespace atlas
