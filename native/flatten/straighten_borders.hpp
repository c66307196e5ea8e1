// Border straightening: strips of faces along the border of two flattened
// charts change sides where a minimum cut says the border gets shorter.
// A zig-zag border loses its teeth to refine_seams one face at a time; the
// faces of a strip each lengthen the seam alone and shorten it together, so
// only a cut over all the faces near the border finds them.
//
// Per pair of adjacent solved charts, the faces within kBandRings rings of
// their border are relabelled by a minimum cut of the dual graph (an edge
// costs its 3D length; faces beyond the band, and faces on a kept seam, keep
// their chart). Each connected strip that changes sides takes the
// receiver's UVs at the vertices it shares with it across an edge; its other
// vertices are placed by unfolding each face, in its shape in the giver,
// across an edge already placed, then relaxed by a few as-rigid-as-possible
// iterations (Sorkine and Alexa 2007) towards those shapes. A strip moves
// only when every face keeps its winding and at least min_area_ratio of its
// texel area (a hundredth of a texel at least), it overlaps neither the
// receiver nor itself, the giver stays connected and the seam gets shorter;
// so the output guarantees hold.
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "core/topology.hpp"
#include "flatten/flatten_without_overlap.hpp"
#include "flatten/refine_seams.hpp"

namespace atlas {

// Arguments as for refine_seams (charts changed in place). Kept charts
// (original UVs) take no part. Returns the faces moved and the 3D seam
// length removed.
RefineStats straighten_borders(const RefineInput& input, std::vector<FlatChart>& charts);

}  // namespace atlas
