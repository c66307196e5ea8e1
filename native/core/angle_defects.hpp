// Discrete Gaussian curvature.
#pragma once
#include <vector>

#include "core/mesh.hpp"

namespace atlas {

// Per vertex (V), its angle defect 2 pi - sum of the angles of its corners:
// the Gaussian curvature integrated over its share of the surface. Summed over
// the interior vertices of a disk it is what no flattening can keep isometric:
// 0 for a piece of a cylinder or cone however far it wraps, 2 pi (1 - cos t)
// for a spherical cap of half-angle t. Vertices on the mesh's border get the
// same formula (meaningless there; callers skip them).
std::vector<double> angle_defects(const Mesh& mesh);

}  // namespace atlas
