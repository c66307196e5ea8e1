// A rectangle of texels stored one bit per texel, rows packed into 64-bit
// words, so that "do these two masks share a texel?" is a few word ANDs.
// Bit i of word k in row y stands for texel (64k + i, y) of the mask.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#if defined(_MSC_VER)
#include <intrin.h>
#endif

namespace atlas {

struct TexelMask {
  int width = 0;     // texels
  int height = 0;    // texels
  int origin_x = 0;  // texel coordinates of mask texel (0, 0) in the frame it was built in
  int origin_y = 0;
  int words_per_row = 0;
  std::vector<std::uint64_t> words;  // height rows of words_per_row words, all bits clear

  TexelMask() = default;
  TexelMask(int width_, int height_, int origin_x_, int origin_y_)
      : width(width_),
        height(height_),
        origin_x(origin_x_),
        origin_y(origin_y_),
        words_per_row((width_ + 63) / 64),
        words(static_cast<std::size_t>(words_per_row) * height_, 0) {}

  std::uint64_t* row(int y) { return words.data() + static_cast<std::size_t>(y) * words_per_row; }
  const std::uint64_t* row(int y) const {
    return words.data() + static_cast<std::size_t>(y) * words_per_row;
  }
  bool test(int x, int y) const { return (row(y)[x >> 6] >> (x & 63)) & 1u; }
};

// ---- bit ranges inside one row of words; ranges are [begin, end) in texels --

inline int count_trailing_zeros(std::uint64_t w) {  // w != 0
#if defined(_MSC_VER)
  unsigned long i;
  _BitScanForward64(&i, w);
  return static_cast<int>(i);
#else
  return __builtin_ctzll(w);
#endif
}

inline int count_bits(std::uint64_t w) {
#if defined(_MSC_VER)
  return static_cast<int>(__popcnt64(w));
#else
  return __builtin_popcountll(w);
#endif
}

inline long long count_set_texels(const TexelMask& mask) {
  long long n = 0;
  for (std::uint64_t w : mask.words) n += count_bits(w);
  return n;
}

// Bits [lo, hi) of one word, 0 <= lo < hi <= 64.
inline std::uint64_t word_bits(int lo, int hi) {
  const std::uint64_t below_hi = hi == 64 ? ~std::uint64_t(0) : (std::uint64_t(1) << hi) - 1;
  return below_hi & (~std::uint64_t(0) << lo);
}

inline void set_bits(std::uint64_t* row, int begin, int end) {
  if (begin >= end) return;
  const int first = begin >> 6, last = (end - 1) >> 6;
  if (first == last) {
    row[first] |= word_bits(begin & 63, ((end - 1) & 63) + 1);
    return;
  }
  row[first] |= word_bits(begin & 63, 64);
  for (int k = first + 1; k < last; ++k) row[k] = ~std::uint64_t(0);
  row[last] |= word_bits(0, ((end - 1) & 63) + 1);
}

// First texel in [begin, end) whose bit equals `value`, or end if none.
inline int find_bit(const std::uint64_t* row, int begin, int end, bool value) {
  const std::uint64_t flip = value ? 0 : ~std::uint64_t(0);
  for (int k = begin >> 6, x = begin; x < end; ++k, x = k << 6) {
    const std::uint64_t hits = (row[k] ^ flip) & word_bits(x & 63, 64);
    if (hits) {
      const int found = (k << 6) + count_trailing_zeros(hits);
      return found < end ? found : end;
    }
  }
  return end;
}

// Per column, the row of the first set texel met when scanning rows upwards
// (from_top = false) or downwards (from_top = true); -1 for empty columns.
inline std::vector<int> first_set_row_per_column(const TexelMask& mask, bool from_top) {
  std::vector<int> first(mask.width, -1);
  std::vector<std::uint64_t> seen(mask.words_per_row, 0);
  for (int i = 0; i < mask.height; ++i) {
    const int r = from_top ? mask.height - 1 - i : i;
    const std::uint64_t* row = mask.row(r);
    for (int k = 0; k < mask.words_per_row; ++k) {
      // Each set bit is visited only the first time its column shows one.
      for (std::uint64_t fresh = row[k] & ~seen[k]; fresh; fresh &= fresh - 1)
        first[(k << 6) + count_trailing_zeros(fresh)] = r;
      seen[k] |= row[k];
    }
  }
  return first;
}

}  // namespace atlas
