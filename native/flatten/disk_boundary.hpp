// Boundary loop of a triangulated topological disk, with the checks that make
// it one: a fixed-boundary embedding of anything else folds over.
#pragma once
#include <vector>

#include "core/mesh.hpp"
#include "flatten/solve_status.hpp"

namespace atlas {

// Checks that the faces form a single connected, consistently oriented,
// edge- and vertex-manifold surface with Euler characteristic V - E + F = 1
// and exactly one boundary loop, using every vertex 0..vertex_count-1.
// On success returns an ok status and fills boundary_corners with the loop, in the
// direction of the face winding: corner c = 3f + k starts the boundary edge
// triangles(f,k) -> triangles(f,(k+1)%3), and each edge ends where the next starts.
// Otherwise returns SolveFailure::not_disk and why (boundary_corners is then unspecified).
SolveStatus disk_boundary_loop(const RowMatrixX3i& triangles, int vertex_count,
                               std::vector<int>& boundary_corners);

}  // namespace atlas
