// Blender hands out the pixels of an 8-bit image as floats b / 255 only; the
// bake wants the bytes back, and the conversion of a large texture is worth
// every core.
#pragma once
#include <cstddef>
#include <cstdint>

namespace atlas {

// out[p * kept + k] = in[p * channels + k] * 255 + 0.5 truncated, in float32
// arithmetic, for pixels p in [0, pixels) and their first `kept` channels
// (0 < kept <= channels): b / 255 in float32 gives b back exactly. Values
// past [0, 1] clamp to 0 and 255, NaN gives 0. Runs on all OpenMP threads.
// Returns whether every channel left out is filler, as Blender fills the
// channels a file lacks: a colour channel (index < 3) whose byte equals the
// last kept channel's (the G and B of a grey file), an alpha (index 3) of
// 255. When it is not, `out` holds the kept channels all the same.
bool bytes_from_unit_floats(const float* in, std::size_t pixels, int channels, int kept, std::uint8_t* out);

}  // namespace atlas
