// Least-squares texels for bilinear reading. Renderers read a texture
// bilinearly, so texels sampled at their centres are not the best ones: the
// texels c of a page are fitted to targets t_s at sample points p_s, s dense
// inside the charts,
//   minimise  sum_s |sum_k w_k(p_s) c_k - t_s|^2 + mu sum_i |c_i - c0_i|^2,
// w_k the bilinear weights of the four texels around p_s and c0 the texels as
// baked; mu keeps texels that few samples see near their baked value.
// Normal equations (W^T W + mu I) c = W^T t + mu c0, solved by conjugate
// gradients from c0, one strip of rows at a time (bake.cpp).
#pragma once
#include <cstdint>
#include <vector>

#include "bake/bake.hpp"

namespace atlas {

// The normal equations of rows [row0, row1) of a page, for several maps that
// share the sample points. Texels outside the rows are not seen: samples must
// keep their four texels inside. One object serves strip after strip, its
// memory kept: fresh pages cost more to touch than the fit's arithmetic.
class BilinearFit {
 public:
  // channels[m]: channels of map m (0: map m is not fitted and takes no targets).
  explicit BilinearFit(const std::vector<int>& channels) : channels_(channels), rhs_(channels.size()) {}

  // Sets memory aside for up to `rows` rows of `width` texels: reset and
  // solve then allocate nothing within it (they run on OpenMP threads, where
  // nothing may throw).
  void reserve(int width, int rows);

  // Empties the equations and sets the rows they cover, of a page `width` texels wide.
  void reset(int width, int row0, int row1);

  // One sample at page point (x, y) (texels, centres at +0.5), with
  // row0 + 0.5 <= y <= row1 - 0.5; target[m] holds channels[m] values for
  // each fitted map.
  void add_sample(double x, double y, const double* const* target);

  // Once the samples are in: the texels solve may change are those some
  // sample reads and `kept` (per page texel) does not mark.
  void mark_free(const std::vector<std::uint8_t>& kept);

  // Writes map m's free texels in rows [write0, write1) of `to`, fitted from
  // those of `from` (the same size) after `iterations` conjugate-gradient
  // steps over all the rows; the other texels keep their values. Values are
  // clamped to the channel's range in the rows and rounded as T encodes.
  template <class T>
  void solve(int m, const Image<T>& from, double mu, int iterations, int write0, int write1, Image<T>& to);

 private:
  int width_ = 0, row0_ = 0, row1_ = 0;
  std::size_t stride_ = 2;  // the rows are stored with a ring of one texel that no sample reads
  std::vector<int> channels_;
  // The entries of W^T W of each texel with itself (plane 0) and with its
  // neighbours (+1, 0), (-1, +1), (0, +1) and (+1, +1) (planes 1 to 4); the
  // others follow by symmetry.
  std::vector<float> matrix_[5];
  std::vector<std::vector<float>> rhs_;  // per map: W^T t, channels per texel
  std::vector<float> free_, x_, r_, p_, q_;  // solve's: 1 on the texels it fits, and the iterates

  // Index of page texel (x, y) in the arrays.
  std::size_t index(int x, int y) const { return (y - row0_ + 1) * stride_ + x + 1; }
  std::size_t size() const { return stride_ * (row1_ - row0_ + 2); }
  void add_clamped(int x0, int y0, const double* w, std::size_t* at);
};

}  // namespace atlas
