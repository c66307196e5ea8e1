#include "bake/bilinear_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>

#include "bake/texel_encoding.hpp"

namespace atlas {

namespace {

// Stored neighbour offsets (dx, dy) of matrix_ entries 1..4; entry 0 is the diagonal.
constexpr int kOffsetX[5] = {0, 1, -1, 0, 1};
constexpr int kOffsetY[5] = {0, 0, 1, 1, 1};

int stored_entry(int dx, int dy) {
  for (int e = 1; e < 5; ++e)
    if (kOffsetX[e] == dx && kOffsetY[e] == dy) return e;
  return -1;
}

// Per channel, the sum of a * b over texels (channels interleaved).
template <int C>
void channel_dots(const std::vector<float>& a, const std::vector<float>& b, double* dots) {
  double sum[C] = {};
  for (std::size_t i = 0; i < a.size(); i += C)
    for (int c = 0; c < C; ++c) sum[c] += double(a[i + c]) * b[i + c];
  std::copy(sum, sum + C, dots);
}

// out = free (A + mu I) v for C interleaved channels, A given by its five
// planes (see BilinearFit::matrix_) with rows `stride` texels apart, v read at
// any texel (0 on the ring).
template <int C>
void apply_stencil(const std::vector<float>* a, std::ptrdiff_t stride, const std::vector<float>& v, float mu,
                   const std::vector<float>& free, std::vector<float>& out) {
  // From the first texel of the first row to the last of the last: the ring
  // texels around them are never free, and their neighbours stay in bounds.
  const std::ptrdiff_t s = stride, end = static_cast<std::ptrdiff_t>(free.size()) - s - 1;
  const float *a0 = a[0].data(), *a1 = a[1].data(), *a2 = a[2].data(), *a3 = a[3].data(), *a4 = a[4].data();
  const float* in = v.data();
  for (std::ptrdiff_t i = s + 1; i < end; ++i) {
    const float w[9] = {a0[i] + mu, a1[i], a2[i], a3[i], a4[i], a1[i - 1], a2[i - s + 1], a3[i - s], a4[i - s - 1]};
    const std::ptrdiff_t at[9] = {i, i + 1, i + s - 1, i + s, i + s + 1, i - 1, i - s + 1, i - s, i - s - 1};
    for (int c = 0; c < C; ++c) {
      float sum = 0;
      for (int k = 0; k < 9; ++k) sum += w[k] * in[at[k] * C + c];
      out[i * C + c] = free[i] * sum;
    }
  }
}

// Conjugate gradients on free (A + mu I) for C channels at once, each with
// its own step: x (the start) and r (its residual, 0 off the free texels)
// are updated in place; p and q are work space.
template <int C>
void conjugate_gradients(const std::vector<float>* a, std::ptrdiff_t stride, float mu, const std::vector<float>& free,
                         int iterations, std::vector<float>& x, std::vector<float>& r, std::vector<float>& p,
                         std::vector<float>& q) {
  p = r;
  double rr[C], pq[C], next[C];
  channel_dots<C>(r, r, rr);
  for (int step = 0; step < iterations; ++step) {
    apply_stencil<C>(a, stride, p, mu, free, q);
    channel_dots<C>(p, q, pq);
    float alpha[C], beta[C];
    for (int c = 0; c < C; ++c) alpha[c] = pq[c] > 0 ? static_cast<float>(rr[c] / pq[c]) : 0.0f;
    for (std::size_t i = 0; i < x.size(); i += C)
      for (int c = 0; c < C; ++c) x[i + c] += alpha[c] * p[i + c], r[i + c] -= alpha[c] * q[i + c];
    channel_dots<C>(r, r, next);
    for (int c = 0; c < C; ++c) beta[c] = rr[c] > 0 ? static_cast<float>(next[c] / rr[c]) : 0.0f;
    for (std::size_t i = 0; i < x.size(); i += C)
      for (int c = 0; c < C; ++c) p[i + c] = r[i + c] + beta[c] * p[i + c];
    std::copy(next, next + C, rr);
  }
}

}  // namespace

void BilinearFit::reserve(int width, int rows) {
  const std::size_t n = (static_cast<std::size_t>(width) + 2) * (rows + 2);
  for (std::vector<float>& plane : matrix_) plane.reserve(n);
  int widest = 1;
  for (std::size_t m = 0; m < channels_.size(); ++m) {
    rhs_[m].reserve(channels_[m] * n);
    widest = std::max(widest, channels_[m]);
  }
  free_.reserve(n);
  for (std::vector<float>* v : {&x_, &r_, &p_, &q_}) v->reserve(widest * n);
}

void BilinearFit::reset(int width, int row0, int row1) {
  width_ = width, row0_ = row0, row1_ = row1, stride_ = static_cast<std::size_t>(width) + 2;
  for (std::vector<float>& plane : matrix_) plane.assign(size(), 0.0f);
  for (std::size_t m = 0; m < channels_.size(); ++m) rhs_[m].assign(channels_[m] * size(), 0.0f);
}

void BilinearFit::add_sample(double x, double y, const double* const* target) {
  const double gx = x - 0.5, gy = y - 0.5;
  const int x0 = static_cast<int>(std::floor(gx)), y0 = static_cast<int>(std::floor(gy));
  const double fx = gx - x0, fy = gy - y0;
  const double w[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
  std::size_t at[4];
  if (x0 >= 0 && y0 >= row0_ && x0 + 1 < width_ && y0 + 1 < row1_) {
    at[0] = index(x0, y0), at[1] = at[0] + 1, at[2] = at[0] + stride_, at[3] = at[2] + 1;
    for (int k = 0; k < 4; ++k) matrix_[0][at[k]] += static_cast<float>(w[k] * w[k]);
    // The pairs among the four texels, each stored at its lower (then left) texel.
    matrix_[1][at[0]] += static_cast<float>(w[0] * w[1]);
    matrix_[1][at[2]] += static_cast<float>(w[2] * w[3]);
    matrix_[3][at[0]] += static_cast<float>(w[0] * w[2]);
    matrix_[3][at[1]] += static_cast<float>(w[1] * w[3]);
    matrix_[4][at[0]] += static_cast<float>(w[0] * w[3]);
    matrix_[2][at[1]] += static_cast<float>(w[1] * w[2]);
  } else {
    add_clamped(x0, y0, w, at);
  }
  for (std::size_t m = 0; m < channels_.size(); ++m)
    for (int k = 0; k < 4; ++k) {
      float* rhs = rhs_[m].data() + channels_[m] * at[k];
      for (int c = 0; c < channels_[m]; ++c) rhs[c] += static_cast<float>(w[k] * target[m][c]);
    }
}

// A sample whose texels leave the rows reads the edge texels instead, as
// clamp-to-edge does: two of them may then be one texel.
void BilinearFit::add_clamped(int x0, int y0, const double* w, std::size_t* at) {
  int tx[4], ty[4];
  for (int k = 0; k < 4; ++k) {
    tx[k] = std::clamp(x0 + (k & 1), 0, width_ - 1);
    ty[k] = std::clamp(y0 + (k >> 1), row0_, row1_ - 1);
    at[k] = index(tx[k], ty[k]);
  }
  for (int k = 0; k < 4; ++k)
    for (int l = k; l < 4; ++l) {
      int a = k, b = l;
      if (ty[b] < ty[a] || (ty[b] == ty[a] && tx[b] < tx[a])) std::swap(a, b);
      const int e = stored_entry(tx[b] - tx[a], ty[b] - ty[a]);
      matrix_[std::max(e, 0)][at[a]] += static_cast<float>((e < 0 && k != l ? 2.0 : 1.0) * w[k] * w[l]);
    }
}

void BilinearFit::mark_free(const std::vector<std::uint8_t>& kept) {
  free_.assign(size(), 0.0f);
  for (int y = row0_; y < row1_; ++y)
    for (int x = 0; x < width_; ++x)
      free_[index(x, y)] = !kept[std::size_t(y) * width_ + x] && matrix_[0][index(x, y)] > 0;
}

template <class T>
void BilinearFit::solve(int m, const Image<T>& from, double mu, int iterations, int write0, int write1,
                        Image<T>& to) {
  const int channels = channels_[m];
  for (std::vector<float>* v : {&x_, &r_, &p_, &q_}) v->assign(size() * channels, 0.0f);
  float lo[kMaxTexelChannels], hi[kMaxTexelChannels];
  std::fill(lo, lo + channels, std::numeric_limits<float>::infinity());
  std::fill(hi, hi + channels, -std::numeric_limits<float>::infinity());
  for (int y = row0_; y < row1_; ++y)
    for (int i = 0; i < width_; ++i)
      for (int c = 0; c < channels; ++c) {
        const float value = static_cast<float>(from.texels[(std::size_t(y) * width_ + i) * channels + c]);
        x_[index(i, y) * channels + c] = value, lo[c] = std::min(lo[c], value), hi[c] = std::max(hi[c], value);
      }
  // Residual at x0 = c0, where the pull towards c0 is 0: W^T t - W^T W x0,
  // kept texels entering as constants.
  auto run = [&](auto channel_count) {
    constexpr int C = decltype(channel_count)::value;
    apply_stencil<C>(matrix_, static_cast<std::ptrdiff_t>(stride_), x_, 0.0f, free_, q_);
    for (std::size_t i = 0; i < r_.size(); ++i) r_[i] = free_[i / C] * (rhs_[m][i] - q_[i]);
    conjugate_gradients<C>(matrix_, static_cast<std::ptrdiff_t>(stride_), static_cast<float>(mu), free_, iterations,
                           x_, r_, p_, q_);
  };
  switch (channels) {
    case 1: run(std::integral_constant<int, 1>()); break;
    case 2: run(std::integral_constant<int, 2>()); break;
    case 3: run(std::integral_constant<int, 3>()); break;
    default: run(std::integral_constant<int, 4>()); break;
  }
  for (int y = write0; y < write1; ++y)
    for (int i = 0; i < width_; ++i)
      if (free_[index(i, y)] > 0)
        for (int c = 0; c < channels; ++c)
          to.texels[(std::size_t(y) * width_ + i) * channels + c] =
              encode_texel<T>(std::clamp(x_[index(i, y) * channels + c], lo[c], hi[c]));
}

template void BilinearFit::solve<std::uint8_t>(int, const Image<std::uint8_t>&, double, int, int, int,
                                               Image<std::uint8_t>&);
template void BilinearFit::solve<float>(int, const Image<float>&, double, int, int, int, Image<float>&);

}  // namespace atlas
