// Texture generation: every texel of the new atlas samples the old texture
// through the old UVs of the same surface point, then empty texels are filled
// by pull-push so that bilinear and mip sampling never see background.
#pragma once
#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "core/uv_layout.hpp"

namespace atlas {

// Row-major texels, row 0 at v = 0 (the bottom, as in Blender and OpenGL).
template <class T>
struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<T> texels;  // width * height * channels
};

template <class T>
struct ImageView {
  const T* texels = nullptr;
  int width = 0;
  int height = 0;
  int channels = 0;
  std::size_t size = 0;  // elements behind texels; bake_map requires width * height * channels
};

struct BakeOptions {
  bool normal_map = false;  // tangent-space normal map: XY re-oriented per face
  int padding = 4;          // texels around charts filled with edge colour before pull-push; 0: none
  // Texels fitted by least squares so that the page read bilinearly matches
  // the old one read bilinearly (bilinear_fit.hpp), where faces are resampled
  // near 1:1, for two to three times the bake's time; false: each texel is
  // the old page at its centre (Catmull-Rom). Normal maps, copied texels and
  // minified faces keep their sampled values either way.
  bool fit_texels = false;
};

// What the bake did with the texels its faces cover (padding and fill not
// counted), summed over the maps baked.
struct BakeStats {
  long long covered_texels = 0;
  // Copied from one old texel, unresampled: the face only moved by whole
  // texels and quarter turns (or mirrors), so its texel centres land on old ones.
  long long copied_texels = 0;
};

// One map of a bake_maps call: old_pages[p] is its image of old page p.
template <class T>
struct BakeSource {
  std::vector<ImageView<T>> old_pages;
  bool normal_map = false;  // tangent-space normal map: XY re-oriented per face
};

// Bakes several maps (uint8_t or float texels) of the same old pages onto the
// pages of new_layout in one pass: which face covers or pads each new texel,
// and where that texel lands in the old page, is worked out once for all of
// them. Every map's images have the sizes old_layout gives its pages (maps of
// other sizes need a call of their own); channel counts may differ. Every face
// must be textured in both layouts. Returns out[map][new page]; stats, when
// given, receives what was copied and what resampled; fit_texels as in BakeOptions.
template <class T>
std::vector<std::vector<Image<T>>> bake_maps(const UvLayout& old_layout, const std::vector<BakeSource<T>>& maps,
                                             const UvLayout& new_layout, int padding, const RunControl& control,
                                             BakeStats* stats = nullptr, bool fit_texels = false);

// bake_maps of one map.
template <class T>
std::vector<Image<T>> bake_map(const UvLayout& old_layout, const std::vector<ImageView<T>>& old_pages,
                               const UvLayout& new_layout, const BakeOptions& options, const RunControl& control,
                               BakeStats* stats = nullptr);

}  // namespace atlas
