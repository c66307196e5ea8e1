// The reference shape of every face of a merged chart: its original UV triangle
// in texels, oriented like the mesh and repaired where it is unusable, so that
// the distortion energy of the map reference -> new UV is finite everywhere.
#pragma once

#include "core/mesh.hpp"

namespace atlas {

struct ReferenceTriangles {
  RowMatrixX2d corners;  // 3F x 2; row 3f+k is corner k of face f; every triangle has positive area
  int folded = 0;        // faces folded over inside their original chart (mirror image used)
  int repaired = 0;      // degenerate references replaced by a well-shaped triangle
};

// Orients and repairs the references of one chart.
//  - mirrored[f] = 1 reflects the reference (x -> -x), so that mirrored original
//    charts wind like the mesh; a reference that still has negative area is a
//    fold-over of the original map and its mirror image is used instead.
//  - A reference with area below 1e-3 of what the face should cover, or an angle
//    below 1 degree, is replaced by the face's 3D triangle scaled by the chart's
//    texel density (sum of reference areas / sum of 3D areas over good faces);
//    if the 3D triangle is degenerate too, by an equilateral triangle of the
//    chart's mean reference area.
// triangles (F,3) index positions (V,3); reference_uv (3F,2); mirrored (F).
ReferenceTriangles repaired_reference_triangles(const RowMatrixX3i& triangles,
                                                const RowMatrixX3d& positions,
                                                const RowMatrixX2d& reference_uv,
                                                const Eigen::VectorXi& mirrored);

// The 3D triangle (a, b, c) laid flat into out (3 x 2): a at the origin, b on
// the positive x axis, c above it (an isometry, so the winding is positive),
// lengths scaled by sqrt(density), density being texel area per 3D area.
void write_flattened(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                     double density, Eigen::Ref<RowMatrixX2d> out);

}  // namespace atlas
