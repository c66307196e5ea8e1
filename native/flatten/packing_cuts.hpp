// Cuts that make charts pack tighter (after Box Cutter, Limper, Vining and
// Sheffer 2018). A packed chart takes about its bounding box: a scan chart
// with a bulge or a branch leaves a large void beside it that only small
// charts can fill. A straight chord across the chart, along texel rows or
// columns, splits it into two charts whose boxes together are smaller. The
// pieces keep their UVs, so each stays flip-free and overlap-free and keeps
// its texel density; only the cut's edges become new seam.
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "core/topology.hpp"
#include "flatten/flatten_without_overlap.hpp"

namespace atlas {

struct PackingCutOptions {
  double scale = 1.0;  // page texels per chart texel, as the packer will place them; > 0
  int padding = 4;     // the packer's padding (a ring each chart owns); 0: none
  // Most 3D length the cuts may add, all charts together; 0: no cut.
  double seam_budget = 0;
};

struct PackingCutStats {
  int cuts = 0;
  double seam_added_3d = 0;  // 3D length of the edges the cuts opened
};

// charts: faces and texel corner UVs (see FlatChart), changed in place: a cut
// chart is replaced by its two pieces, each a disk, their UVs those of the
// chart (turned as a whole to their smallest box, unless kept_original);
// an input polygon (MeshTopology::inside_polygon) goes whole to one piece.
// Chords are taken greedily, the most padded box texels saved per 3D length
// first, while they fit the budget and save more than the padding they add;
// the result does not depend on the thread count.
PackingCutStats cut_for_packing(const Mesh& mesh, const MeshTopology& topology, const PackingCutOptions& options,
                                std::vector<FlatChart>& charts, const RunControl& control);

}  // namespace atlas
