#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <random>
#include <vector>

#include "core/mesh.hpp"
#include "io/byte_pixels.hpp"
#include "io/png_rows.hpp"
#include "io/zlib_stream.hpp"

namespace atlas {
namespace {

using Bytes = std::vector<std::uint8_t>;

// PNG spec 9.4, written as the spec does (p, then the nearest of a, b, c).
int spec_paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  if (pa <= pb && pa <= pc) return a;
  if (pb <= pc) return b;
  return c;
}

// The filtered bytes of one row of raw bytes (prior: the raw row above, or zeros).
Bytes filter_row(int type, const Bytes& row, const Bytes& prior, int bpp) {
  Bytes out(row.size());
  for (size_t i = 0; i < row.size(); ++i) {
    const int a = i >= size_t(bpp) ? row[i - bpp] : 0, b = prior[i];
    const int c = i >= size_t(bpp) ? prior[i - bpp] : 0;
    const int predictor[5] = {0, a, b, (a + b) / 2, spec_paeth(a, b, c)};
    out[i] = static_cast<std::uint8_t>(row[i] - predictor[type]);
  }
  return out;
}

struct Image {
  int width = 0, height = 0, channels = 0;
  Bytes pixels;      // top row first, as in the file
  Bytes scanlines;   // what inflating the file's IDAT gives
};

// Random pixels (values below `levels`, so that Paeth's ties occur), row y
// filtered with type filter_of(y).
template <class FilterOf>
Image filtered_image(int width, int height, int channels, int levels, FilterOf filter_of) {
  Image im{width, height, channels, {}, {}};
  std::mt19937 rng(width * 31 + height * 7 + channels);
  std::uniform_int_distribution<int> value(0, levels - 1);
  const size_t row_bytes = size_t(width) * channels;
  im.pixels.resize(row_bytes * height);
  for (auto& p : im.pixels) p = static_cast<std::uint8_t>(value(rng));
  Bytes prior(row_bytes, 0);
  for (int y = 0; y < height; ++y) {
    const Bytes row(im.pixels.begin() + y * row_bytes, im.pixels.begin() + (y + 1) * row_bytes);
    const int type = filter_of(y);
    im.scanlines.push_back(static_cast<std::uint8_t>(type));
    const Bytes f = filter_row(type, row, prior, channels);
    im.scanlines.insert(im.scanlines.end(), f.begin(), f.end());
    prior = row;
  }
  return im;
}

Bytes unfiltered(const Image& im) {
  Bytes out(size_t(im.width) * im.height * im.channels);
  png::unfilter_rows(im.scanlines.data(), im.scanlines.size(), im.width, im.height, im.channels, out.data());
  return out;
}

// The image's pixels, bottom row first.
Bytes flipped(const Image& im) {
  const size_t row_bytes = size_t(im.width) * im.channels;
  Bytes out;
  for (int y = im.height - 1; y >= 0; --y)
    out.insert(out.end(), im.pixels.begin() + y * row_bytes, im.pixels.begin() + (y + 1) * row_bytes);
  return out;
}

TEST(PngRows, EveryFilterTypeGivesThePixelsBackBottomRowFirst) {
  for (int channels : {3, 4})
    for (int levels : {5, 256})
      for (int type = 0; type <= 4; ++type) {
        const Image im = filtered_image(13, 9, channels, levels, [&](int) { return type; });
        ASSERT_EQ(unfiltered(im), flipped(im)) << "filter " << type << ", channels " << channels;
      }
}

TEST(PngRows, RowsOfMixedFilters) {
  const Image im = filtered_image(17, 11, 3, 5, [](int y) { return (y * 3) % 5; });
  EXPECT_EQ(unfiltered(im), flipped(im));
}

TEST(PngRows, RefusesBadFilterBytesSizesAndChannels) {
  Image im = filtered_image(4, 3, 4, 256, [](int) { return 1; });
  Bytes out(4 * 3 * 4);
  im.scanlines[1 + 4 * 4] = 5;  // the second row's filter byte
  EXPECT_THROW(unfiltered(im), InputError);
  im.scanlines[1 + 4 * 4] = 1;
  EXPECT_THROW(png::unfilter_rows(im.scanlines.data(), im.scanlines.size() - 1, 4, 3, 4, out.data()),
               InputError);
  EXPECT_THROW(png::unfilter_rows(im.scanlines.data(), im.scanlines.size(), 4, 3, 2, out.data()), InputError);
  EXPECT_THROW(png::unfilter_rows(im.scanlines.data(), im.scanlines.size(), 0, 3, 4, out.data()), InputError);
}

// data compressed at `level`, as many bytes as the stream took.
Bytes compressed(const Bytes& data, int level) {
  Bytes out(zlib_stream::bound(data.size()));
  out.resize(zlib_stream::compress(data.data(), data.size(), level, out.data()));
  return out;
}

TEST(ZlibStream, InflatesWhatItCompressesAtEveryLevel) {
  std::mt19937 rng(5);
  Bytes noisy(70000), smooth(70000);
  for (size_t i = 0; i < noisy.size(); ++i) {
    noisy[i] = static_cast<std::uint8_t>(rng());
    smooth[i] = static_cast<std::uint8_t>(i / 300);
  }
  for (const Bytes* data : {&noisy, &smooth})
    for (int level : {0, 1, 6, 12}) {
      const Bytes stream = compressed(*data, level);
      Bytes back(data->size());
      zlib_stream::inflate(stream.data(), stream.size(), back.data(), back.size());
      EXPECT_EQ(back, *data) << "level " << level;
    }
  EXPECT_LT(compressed(smooth, 1).size(), smooth.size() / 20);
  EXPECT_THROW(compressed(smooth, 13), InputError);
  EXPECT_THROW(compressed(smooth, -1), InputError);
}

TEST(ZlibStream, RefusesBrokenStreamsAndWrongSizes) {
  const Bytes data(5000, 7);
  const Bytes stream = compressed(data, 1);
  Bytes out(data.size() + 1);
  EXPECT_NO_THROW(zlib_stream::inflate(stream.data(), stream.size(), out.data(), data.size()));
  EXPECT_THROW(zlib_stream::inflate(stream.data(), stream.size(), out.data(), data.size() + 1), InputError);
  EXPECT_THROW(zlib_stream::inflate(stream.data(), stream.size(), out.data(), data.size() - 1), InputError);
  Bytes bad_checksum = stream;
  bad_checksum.back() ^= 1;  // the Adler-32's last byte
  EXPECT_THROW(zlib_stream::inflate(bad_checksum.data(), bad_checksum.size(), out.data(), data.size()), InputError);
  EXPECT_THROW(zlib_stream::inflate(stream.data(), stream.size() / 2, out.data(), data.size()), InputError);
}

TEST(BytesFromUnitFloats, GivesBytesBackAndClamps) {
  // Several OpenMP blocks, every byte value many times.
  const size_t n = 300001;
  std::vector<float> in(n);
  // Blender's own formula (b * (1 / 255) in float), and b / 255, which
  // differs from it in the last bit for about half the bytes.
  for (size_t i = 0; i < n; ++i)
    in[i] = i % 2 ? static_cast<float>(i % 256) * (1.0f / 255.0f) : static_cast<float>(i % 256) / 255.0f;
  std::vector<std::uint8_t> out(n);
  bytes_from_unit_floats(in.data(), n, 1, 1, out.data());
  for (size_t i = 0; i < n; ++i) ASSERT_EQ(out[i], i % 256) << i;
  const float odd[] = {-0.5f, 2.0f, std::numeric_limits<float>::quiet_NaN(),
                       std::numeric_limits<float>::infinity(), 0.499f / 255.0f, 0.501f / 255.0f};
  std::uint8_t got[6];
  bytes_from_unit_floats(odd, 6, 1, 1, got);
  EXPECT_EQ(got[0], 0);
  EXPECT_EQ(got[1], 255);
  EXPECT_EQ(got[2], 0);
  EXPECT_EQ(got[3], 255);
  EXPECT_EQ(got[4], 0);
  EXPECT_EQ(got[5], 1);
}

TEST(BytesFromUnitFloats, KeepsTheFirstChannelsOfEachPixel) {
  const size_t pixels = 70001;  // several OpenMP blocks
  std::vector<float> in(4 * pixels);
  for (size_t i = 0; i < in.size(); ++i) in[i] = static_cast<float>(i % 251) / 255.0f;
  for (int kept : {1, 3, 4}) {
    std::vector<std::uint8_t> out(kept * pixels);
    // Nothing left out is filler here, but for kept == 4, where nothing is left out.
    EXPECT_EQ(bytes_from_unit_floats(in.data(), pixels, 4, kept, out.data()), kept == 4);
    for (size_t p = 0; p < pixels; ++p)
      for (int k = 0; k < kept; ++k) ASSERT_EQ(out[p * kept + k], (4 * p + k) % 251) << kept << " " << p;
  }
}

TEST(BytesFromUnitFloats, TellsWhetherWhatIsLeftOutIsFiller) {
  // Blender's pixels of a grey file: the grey in R, G and B, alpha 1.
  const size_t pixels = 70001;
  std::vector<float> grey(4 * pixels);
  for (size_t p = 0; p < pixels; ++p) {
    const float v = static_cast<float>(p % 256) / 255.0f;
    grey[4 * p] = grey[4 * p + 1] = grey[4 * p + 2] = v;
    grey[4 * p + 3] = 1.0f;
  }
  std::vector<std::uint8_t> out(3 * pixels);
  EXPECT_TRUE(bytes_from_unit_floats(grey.data(), pixels, 4, 1, out.data()));
  EXPECT_TRUE(bytes_from_unit_floats(grey.data(), pixels, 4, 3, out.data()));
  grey[4 * 65000 + 3] = 0.5f;  // one pixel's alpha edited
  EXPECT_FALSE(bytes_from_unit_floats(grey.data(), pixels, 4, 3, out.data()));
  grey[4 * 65000 + 3] = 1.0f;
  grey[4 * 70000 + 2] = 0.0f;  // one pixel no longer grey
  EXPECT_FALSE(bytes_from_unit_floats(grey.data(), pixels, 4, 1, out.data()));
  EXPECT_TRUE(bytes_from_unit_floats(grey.data(), pixels, 4, 3, out.data()));
}

}  // namespace
}  // namespace atlas
