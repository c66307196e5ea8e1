// Small constructed meshes shared by the GoogleTest suites.
#pragma once
#include <vector>

#include "core/mesh.hpp"

namespace atlas::testing {

// n x n quads on the unit square (z = 0), one UV chart with uv = scale * xy,
// on one page of page_size x page_size texels.
Mesh grid_disk(int n, double uv_scale = 1.0, int page_size = 256);

// Builds a Mesh from positions and triangles; face_chart[f] names the UV chart
// of face f. Each chart gets a planar projection of its faces (seen along the
// mean normal), moved to its own place in UV so that charts never touch.
Mesh with_chart_uvs(const RowMatrixX3d& positions, const RowMatrixX3i& triangles,
                    const std::vector<int>& face_chart, int page_size = 1024);

// rings x segments quads around an annulus in the plane; chart = segment / segments_per_chart.
Mesh annulus(int rings, int segments, int segments_per_chart);
// Closed UV sphere; charts are rings_per_chart rings by a quarter turn, plus two caps.
Mesh uv_sphere(int rings, int segments, int rings_per_chart);
// Closed torus; charts are patches: major_per_chart segments by a quarter of the tube.
Mesh torus(int major, int minor, int major_per_chart);
// An open tube of rings x segments quads, unrolled as strips: ring i goes to
// chart i / rings_per_chart, and each chart's UVs are (angle, height), so every
// chart meets itself at the seam where the angle wraps.
Mesh unrolled_tube(int rings, int segments, int rings_per_chart);
// Three quads sharing one edge (a non-manifold fin), each its own chart.
Mesh nonmanifold_fin();

}  // namespace atlas::testing
