#include "bake/pull_push_fill.hpp"

#include <algorithm>
#include <cstddef>

#include "bake/texel_encoding.hpp"

namespace atlas {

namespace {

template <class T>
struct Level {
  Image<T> image;
  std::vector<std::uint8_t> is_set;
};

inline double lerp(double a, double b, double t) { return a + (b - a) * t; }

bool has_hole(const std::vector<std::uint8_t>& is_set) {
  return std::find(is_set.begin(), is_set.end(), 0) != is_set.end();
}

// Coarse texel (x, y) = mean of the set texels among fine (2x..2x+1, 2y..2y+1);
// set when any of them is. Means are taken in double: n equal values average exactly.
template <class T>
Level<T> pull(const Image<T>& fine, const std::vector<std::uint8_t>& fine_set) {
  Level<T> coarse;
  Image<T>& img = coarse.image;
  img.width = (fine.width + 1) / 2;
  img.height = (fine.height + 1) / 2;
  img.channels = fine.channels;
  const int c = img.channels;
  img.texels.resize(static_cast<std::size_t>(img.width) * img.height * c);
  coarse.is_set.assign(static_cast<std::size_t>(img.width) * img.height, 0);
#pragma omp parallel for schedule(static)
  for (int y = 0; y < img.height; ++y) {
    double sum[kMaxTexelChannels];
    for (int x = 0; x < img.width; ++x) {
      std::fill(sum, sum + c, 0.0);
      int count = 0;
      for (int fy = 2 * y; fy < std::min(2 * y + 2, fine.height); ++fy)
        for (int fx = 2 * x; fx < std::min(2 * x + 2, fine.width); ++fx) {
          const std::size_t i = static_cast<std::size_t>(fy) * fine.width + fx;
          if (!fine_set[i]) continue;
          for (int k = 0; k < c; ++k) sum[k] += fine.texels[i * c + k];
          ++count;
        }
      if (count == 0) continue;
      const std::size_t o = static_cast<std::size_t>(y) * img.width + x;
      for (int k = 0; k < c; ++k) img.texels[o * c + k] = encode_texel<T>(sum[k] / count);
      coarse.is_set[o] = 1;
    }
  }
  return coarse;
}

// The coarse texels bracketing the centre of fine texel i on an axis of n coarse texels,
// and the weight t of the second. The centre sits at coarse coordinate (i + 0.5) / 2, i.e.
// a quarter texel past coarse centre (i - 1) / 2 for odd i, three quarters for even i.
struct Bracket {
  int lo, hi;
  double t;
};

Bracket bracket(int i, int n) {
  const int lo = (i - 1) >> 1;  // arithmetic shift: floor((i - 1) / 2), -1 for i = 0
  return {std::clamp(lo, 0, n - 1), std::clamp(lo + 1, 0, n - 1), i % 2 ? 0.25 : 0.75};
}

// Every unset fine texel takes the bilinear interpolation of the complete coarse level.
template <class T>
void push(const Image<T>& coarse, Image<T>& fine, const std::vector<std::uint8_t>& fine_set) {
  const int c = fine.channels;
  std::vector<Bracket> columns(fine.width);
  for (int x = 0; x < fine.width; ++x) columns[x] = bracket(x, coarse.width);
#pragma omp parallel for schedule(static)
  for (int y = 0; y < fine.height; ++y) {
    const Bracket by = bracket(y, coarse.height);
    const T* r0 = coarse.texels.data() + static_cast<std::size_t>(by.lo) * coarse.width * c;
    const T* r1 = coarse.texels.data() + static_cast<std::size_t>(by.hi) * coarse.width * c;
    for (int x = 0; x < fine.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * fine.width + x;
      if (fine_set[i]) continue;
      const Bracket& bx = columns[x];
      for (int k = 0; k < c; ++k) {
        const double bottom = lerp(r0[bx.lo * c + k], r0[bx.hi * c + k], bx.t);
        const double top = lerp(r1[bx.lo * c + k], r1[bx.hi * c + k], bx.t);
        fine.texels[i * c + k] = encode_texel<T>(lerp(bottom, top, by.t));
      }
    }
  }
}

}  // namespace

template <class T>
void pull_push_fill(Image<T>& image, const std::vector<std::uint8_t>& is_set, const RunControl& control) {
  if (!has_hole(is_set)) return;
  if (std::all_of(is_set.begin(), is_set.end(), [](std::uint8_t s) { return s == 0; })) {
    std::fill(image.texels.begin(), image.texels.end(), T(0));
    return;
  }
  // levels[k] is mip level k + 1. Pulling stops at the first level without holes, at
  // the latest at 1x1: each level keeps at least one set texel.
  std::vector<Level<T>> levels;
  levels.push_back(pull(image, is_set));
  while (has_hole(levels.back().is_set)) {
    control.throw_if_cancelled();
    Level<T> next = pull(levels.back().image, levels.back().is_set);
    levels.push_back(std::move(next));
  }
  for (std::size_t k = levels.size() - 1; k > 0; --k) {
    control.throw_if_cancelled();
    push(levels[k].image, levels[k - 1].image, levels[k - 1].is_set);
  }
  push(levels[0].image, image, is_set);
}

template void pull_push_fill<std::uint8_t>(Image<std::uint8_t>&, const std::vector<std::uint8_t>&,
                                           const RunControl&);
template void pull_push_fill<float>(Image<float>&, const std::vector<std::uint8_t>&, const RunControl&);

}  // namespace atlas
