// Flip-free initial map of a disk chart (thesis 3.3, 5.4): Tutte's barycentric
// embedding with mean-value weights and the boundary on a circle.
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "flatten/solve_status.hpp"

namespace atlas {

// Embeds the disk in the plane:
//  - boundary vertices on a circle, spaced by the reference length of the
//    boundary edges (boundary_corners as returned by disk_boundary_loop);
//  - every interior vertex i at a weighted mean of its neighbours,
//      sum_j w_ij (u_i - u_j) = 0,
//    with Floater's mean-value weights measured on the reference triangles,
//      mv_ij = sum over the faces at edge ij of tan(angle at i / 2) / |r_i - r_j|,
//    symmetrized, w_ij = (mv_ij + mv_ji) / 2. Floater's theorem only needs
//    positive weights for a flip-free map; symmetric ones make the system SPD;
//  - then scaled so that its area equals the total reference area.
// reference holds 3 positively oriented rows per face. Returns an ok status,
// or SolveFailure::embedding and why; uv (vertex_count x 2) is then unspecified.
SolveStatus mean_value_embedding(const RowMatrixX3i& triangles, const RowMatrixX2d& reference,
                                 const std::vector<int>& boundary_corners, int vertex_count,
                                 RowMatrixX2d& uv);

}  // namespace atlas
