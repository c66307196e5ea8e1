// Quality metrics of a texture atlas and of the map old UV -> new UV: what every
// stage and the benchmark are judged by. Untextured faces (page -1) are ignored
// everywhere; no result is ever NaN.
#pragma once
#include <Eigen/Core>
#include <vector>

#include "bake/bake.hpp"
#include "core/mesh.hpp"
#include "core/topology.hpp"
#include "core/uv_layout.hpp"

namespace atlas {

// One layout on its own.
struct AtlasMeasures {
  int charts = 0;
  double seam_ratio = 0;           // seam 3D length / sqrt(3D area) (seam_length_ratio)
  double boundary_texels = 0;      // sum of chart perimeters in texels
  long long page_texels = 0;       // sum of width * height over all pages of the layout
  long long covered_texels = 0;    // texels whose centre some triangle covers
  double occupancy = 0;            // covered / page texels
  int flipped_faces = 0;           // wound against their chart in the float32 UVs as stored (every face; collinear ones have no winding)
  long long overlap_texels = 0;    // texels whose centre two or more triangles cover (a triangle two faces
                                   // draw alike, page and corner UVs, counts once: a repeated face)
};

// Only positions and triangles of `mesh` are used; the UVs come from `atlas`.
// Coverage is rasterised at texel centres on each face's page: a centre on an
// edge shared by two triangles counts once; parts of triangles outside the page
// (UVs outside [0,1]) are clipped, not wrapped; zero-area triangles claim nothing.
// Throws InputError when the atlas does not match the mesh (shapes, pages,
// non-finite UVs).
AtlasMeasures measure_atlas(const Mesh& mesh, const MeshTopology& topology, const UvLayout& atlas);

// The map old UV -> new UV. Texel density of a face = UV area in texels per 3D
// area. Faces untextured in either layout, or with zero 3D area or zero old UV
// area, are skipped; percentiles are area-weighted (the smallest value whose
// cumulative weight reaches the fraction); all zero when no face counts.
struct MapMeasures {
  double density_loss_area_share = 0;  // share of 3D area whose density ratio new/old < 0.5
  double density_ratio_p5 = 0, density_ratio_p50 = 0, density_ratio_p95 = 0;
  double angle_error_p50 = 0, angle_error_p90 = 0, angle_error_p99 = 0;  // degrees, per corner, in texel space
};

MapMeasures measure_map(const Mesh& mesh, const UvLayout& old_atlas, const UvLayout& new_atlas);

// Colour fidelity of a re-bake. psnr_db is capped at kMaxPsnrDb (identical colours).
constexpr double kMaxPsnrDb = 99.0;
struct ColorFidelity {
  double psnr_db = kMaxPsnrDb;  // over RGB (first min(3, channels) channels) in [0,1] units
  double share_off_32 = 0;      // share of points where some channel differs by > 32/255
  long long samples = 0;        // points drawn (0 when no face is textured in both layouts)
  // The same PSNR on two halves of the points: "clean" ones, whose four
  // bilinear texels in the old atlas all lie inside the point's own old chart
  // (a texel lies inside a chart when one of its faces covers the texel
  // centre), and the "border" rest, where the old atlas blends gutter texels.
  double psnr_clean_db = kMaxPsnrDb, psnr_border_db = kMaxPsnrDb;
  long long clean_samples = 0;
};

// Draws `samples` surface points uniformly by 3D area over the faces textured
// in both layouts (jittered stratified along the cumulative area, uniform
// barycentrics; deterministic for a given seed, independent of thread count),
// samples old_images[old page] and new_images[new page] bilinearly with repeat
// wrapping at the points' UVs. uint8 values are divided by 255, floats used as
// they are; a non-finite difference counts as 1. The clean / border split takes
// the old charts from the mesh's own UVs (old_atlas is layout_of(mesh) in every
// caller). borders false skips that split, whose raster of the old atlas
// costs more than the samples: the clean and border PSNR are then NaN and
// clean_samples 0. Throws InputError when a used
// page has no image or an image view is inconsistent.
template <class T>
ColorFidelity compare_colors(const Mesh& mesh, const UvLayout& old_atlas, const std::vector<ImageView<T>>& old_images,
                             const UvLayout& new_atlas, const std::vector<ImageView<T>>& new_images, int samples,
                             unsigned seed, bool borders = true);

}  // namespace atlas
