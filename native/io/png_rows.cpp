#include "io/png_rows.hpp"

#include <algorithm>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "core/mesh.hpp"

namespace atlas::png {
namespace {

enum Filter : std::uint8_t { None = 0, Sub = 1, Up = 2, Average = 3, Paeth = 4 };

// PNG spec 9.4: of left a, above b and upper left c, the one nearest to
// a + b - c, ties going to a, then b. Written with the distances reduced
// (p - a = b - c, ...) and no branch: most scan textures filter most rows
// this way, and on their noisy rows a branch would mispredict.
inline std::uint8_t paeth_predictor(int a, int b, int c) {
  const int pa = std::abs(b - c), pb = std::abs(a - c), pc = std::abs(a + b - 2 * c);
  const int nearer_b_or_c = pb <= pc ? b : c;
  return static_cast<std::uint8_t>(pa <= pb && pa <= pc ? a : nearer_b_or_c);
}

// Undoes one row's filter in place: row holds `bytes` filtered bytes, prior
// the row above unfiltered (zeros for the first row), Bpp bytes per pixel.
template <int Bpp>
void unfilter_row(std::uint8_t filter, std::uint8_t* row, const std::uint8_t* prior,
                  std::size_t bytes) {
  switch (filter) {
    case None:
      return;
    case Sub:
      for (std::size_t i = Bpp; i < bytes; ++i) row[i] += row[i - Bpp];
      return;
    case Up:
      for (std::size_t i = 0; i < bytes; ++i) row[i] += prior[i];
      return;
    case Average:
      for (std::size_t i = 0; i < Bpp; ++i) row[i] += prior[i] >> 1;
      for (std::size_t i = Bpp; i < bytes; ++i)
        row[i] += static_cast<std::uint8_t>((row[i - Bpp] + prior[i]) >> 1);
      return;
    case Paeth: {
      // The left and upper-left pixels stay in registers: read back from
      // `row`, each byte waited on the store of the one before it.
      int left[Bpp] = {}, upper_left[Bpp] = {};  // zeros left of the first pixel
      for (std::size_t x = 0; x < bytes; x += Bpp) {
        for (int k = 0; k < Bpp; ++k) {
          const int above = prior[x + k];
          row[x + k] += paeth_predictor(left[k], above, upper_left[k]);
          left[k] = row[x + k];
          upper_left[k] = above;
        }
      }
      return;
    }
    default: {
      std::ostringstream msg;
      msg << "PNG row filter type " << int(filter) << " is not one of 0-4";
      throw InputError(msg.str());
    }
  }
}

// Every row, bottom row first in `out`, unfiltered in place there, each
// against the row written before it.
template <int Bpp>
void unfilter_image(const std::uint8_t* scanlines, int width, int height, std::uint8_t* out) {
  const std::size_t row_bytes = std::size_t(width) * Bpp;
  const std::vector<std::uint8_t> zeros(row_bytes, 0);
  const std::uint8_t* prior = zeros.data();
  for (int y = 0; y < height; ++y) {
    const std::uint8_t* line = scanlines + std::size_t(y) * (row_bytes + 1);
    std::uint8_t* row = out + std::size_t(height - 1 - y) * row_bytes;
    std::copy(line + 1, line + 1 + row_bytes, row);
    unfilter_row<Bpp>(line[0], row, prior, row_bytes);
    prior = row;
  }
}

}  // namespace

void check_sizes(std::size_t scanline_bytes, int width, int height, int channels) {
  std::ostringstream msg;
  if (width <= 0 || height <= 0)
    msg << "PNG size must be positive, got " << width << "x" << height;
  else if (channels < 3 || channels > 4)
    msg << "PNG channels must be 3 or 4, got " << channels;
  else if (scanline_bytes != static_cast<std::size_t>(height) * (1 + std::size_t(width) * channels))
    msg << "PNG data holds " << scanline_bytes << " bytes, a " << width << "x" << height
        << " image with " << channels << " channels needs "
        << static_cast<std::size_t>(height) * (1 + std::size_t(width) * channels);
  if (msg.tellp() > 0) throw InputError(msg.str());
}

void unfilter_rows(const std::uint8_t* scanlines, std::size_t scanline_bytes, int width,
                   int height, int channels, std::uint8_t* out) {
  check_sizes(scanline_bytes, width, height, channels);
  if (channels == 3) unfilter_image<3>(scanlines, width, height, out);
  if (channels == 4) unfilter_image<4>(scanlines, width, height, out);
}

}  // namespace atlas::png
