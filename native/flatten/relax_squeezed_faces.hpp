// A local density repair after a chart's solve. SLIM's optimum can leave a
// few faces squeezed below half their texel area, each among neighbours that
// could give up a little of theirs. Relaxing only the vertices near them,
// with the rest of the chart (its boundary included) held still, lifts them
// without growing the chart, without a new seam and for little time. The
// global repair (SlimOptions::repair_rounds) re-solves the whole chart
// instead, which grows it. Most faces left squeezed touch the boundary; once
// no later step needs the outline as it is, free_border lets the boundary
// near them move as well (relax_squeezed_borders.hpp).
#pragma once

#include "core/mesh.hpp"

namespace atlas {

struct RelaxOptions {
  // Sweeps over the free vertices, one SLIM-like step each; 0: no relaxing.
  int sweeps = 30;
  // Vertex rings around the squeezed faces that may move (0: only their own
  // corners). Boundary vertices move only with free_border.
  int rings = 4;
  // Each sweep multiplies the weight of a face below `floor` of its
  // reference area by floor / ratio, so one that stays squeezed weighs more
  // and more; a floor a little over one half lifts faces clear of the
  // density rule's line. 0: no relaxing.
  double floor = 0.55;
  // The relaxation stops, undone, once the chart's energy has risen by more
  // than this share: a squeeze spread over the neighbours would blur them
  // instead (colour PSNR falls). 0: only relaxations that lower it.
  double energy_rise = 0.02;
  // true: the boundary vertices within `rings` move too, each move only
  // where the boundary stays a simple closed curve with a little room to
  // spare (see BorderGuard in the .cpp), so the chart may grow at its edge;
  // false: the boundary stays where it is.
  bool free_border = false;
};

// triangles (F,3) local vertices of a disk; reference (3F,2) each face's
// reference triangle, all of positive area (ReferenceTriangles); uv (n,2)
// a flip-free map with positive areas, changed in place. Lowers
//   E_w = sum_f w_f A_ref(f) psi(J_f),  psi the symmetric Dirichlet density,
// one vertex at a time (its faces' SLIM proxies give a 2x2 step, then a line
// search that keeps every face's area positive), over the interior vertices
// within `rings` of faces whose area ratio det J_f is below 1/2. The boundary
// stays where it was (or, with free_border, moves without crossing itself),
// so the map stays injective. The result is kept only when it leaves less
// reference area below half and the unweighted energy within the bound;
// returns whether it was kept.
bool relax_squeezed_faces(const RowMatrixX3i& triangles, const RowMatrixX2d& reference, const RelaxOptions& options,
                          RowMatrixX2d& uv);

}  // namespace atlas
