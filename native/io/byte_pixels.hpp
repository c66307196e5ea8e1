// Blender hands out the pixels of an 8-bit image as floats b / 255 only; the
// bake wants the bytes back, and the conversion of a large texture is worth
// every core.
#pragma once
#include <cstddef>
#include <cstdint>

namespace atlas {

// out[i] = in[i] * 255 + 0.5 truncated, in float32 arithmetic, for i in
// [0, n): b / 255 in float32 gives b back exactly. Values past [0, 1] clamp
// to 0 and 255, NaN gives 0. Runs on all OpenMP threads.
void bytes_from_unit_floats(const float* in, std::size_t n, std::uint8_t* out);

}  // namespace atlas
