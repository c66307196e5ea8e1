// Fills the empty texels of a baked page from its set texels by pull-push: set texels
// are averaged down a mip pyramid until a level has no hole, then every empty texel
// takes the bilinear interpolation of the level above it. The fill varies smoothly,
// so bilinear and mip sampling across chart borders see chart colours, not background.
#pragma once
#include <cstdint>
#include <vector>

#include "bake/bake.hpp"
#include "core/run_control.hpp"

namespace atlas {

// is_set[y * width + x] != 0 marks texels that keep their value; every other texel is
// overwritten. With no set texel at all the page becomes zero.
template <class T>
void pull_push_fill(Image<T>& image, const std::vector<std::uint8_t>& is_set, const RunControl& control);

}  // namespace atlas
