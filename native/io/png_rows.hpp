// The pixel rows of an 8-bit PNG image once its zlib stream is inflated: the
// add-on reads PNG textures Blender has not loaded from their files this way,
// without Blender's buffer and float pixel array.
#pragma once
#include <cstddef>
#include <cstdint>

namespace atlas::png {

// scanlines: height rows of 1 + width * channels bytes, top row first, each
// a PNG filter type byte (0 None, 1 Sub, 2 Up, 3 Average, 4 Paeth; PNG spec
// section 9) then the filtered bytes of a non-interlaced 8-bit image;
// channels 3 (RGB) or 4 (RGBA). out: height x width x channels bytes, the
// BOTTOM row first as Blender stores images.
// Throws InputError on a filter type above 4, or as check_sizes does.
void unfilter_rows(const std::uint8_t* scanlines, std::size_t scanline_bytes, int width,
                   int height, int channels, std::uint8_t* out);

// Throws InputError unless width and height are positive, scanline_bytes is
// height * (1 + width * channels), and channels is as above: what
// unfilter_rows checks, for callers that allocate `out` first.
void check_sizes(std::size_t scanline_bytes, int width, int height, int channels);

}  // namespace atlas::png
