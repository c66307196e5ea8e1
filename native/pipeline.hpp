// The whole job on plain arrays: chart graph -> aggregation -> flattening with
// overlap backtracking -> packing. Baking is separate (see bake.hpp) so that the
// caller can bake each of its image maps through the same new layout.
#pragma once
#include <string>
#include <vector>

#include "charts/charts.hpp"
#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "flatten/flatten.hpp"
#include "pack/pack.hpp"

namespace atlas {

struct PipelineOptions {
  AggregateOptions aggregate;
  RefineOptions refine;
  SlimOptions slim;
  // Slits a chart that loses density may get before it is split (see
  // FlattenOptions::relief_cuts); 0: split at once.
  int relief_cuts = FlattenOptions().relief_cuts;
  // Share of the surface that may end below half its texel density (the
  // flattening's estimate); charts that lose more are first repaired (see
  // SlimOptions::repair_share), then those that lose most are flattened
  // again under stricter rules until the rest fits. The output guarantee
  // is under 1%. The default asks for a fifth of that: it also lowers the
  // share of its own surface above which a chart is repaired, so that a
  // large chart squeezed in a few places is repaired as well, for a chart
  // a little larger rather than a new seam. 0: no loss anywhere, for a few
  // more charts and more time.
  double density_loss_budget = 0.002;
  // Seam that cuts making charts pack tighter may add (packing_cuts.hpp), as
  // 3D length / sqrt(area), the unit of seam_after; 0: no cut. Off by
  // default: the job exists for fewer charts and shorter seams, and each
  // cut adds both for a smaller page.
  double packing_cut_seam = 0;
  // When the packed charts would take over 1.1x the input's texels at the
  // density asked for, or were shrunk to fit, more such cuts up to this seam
  // in all, and the charts packed again; 0: never. Dense atlases (phone apps
  // fill about three quarters of their pages) otherwise come out larger than
  // they went in: a little more seam instead of a larger texture or lost detail.
  double fit_cut_seam = 1.0;
  // max_pages 0: as many pages as the group's faces use in the input (at least
  // 1), or as many of max_page_size as hold the input's texels times
  // density_scale^2 if that is more: charts shrink only when they would not fit.
  PackOptions pack;
  // true and texel_budget 0: at most the input's texel count per group, times
  // density_scale^2 (charts shrink to keep within it).
  bool texels_at_most_input = false;
  // > 0: output texels per unit of surface length (per metre for scans in
  // metres), replacing density_scale; 0: density_scale applies.
  double texels_per_unit = 0;
};

struct StageTime {
  std::string stage;
  double seconds = 0;
};

struct PipelineReport {
  int duplicate_faces = 0;     // faces repeating another, given its UVs (see degenerate_faces.hpp)
  int charts_before = 0;       // UV charts of the input, copies left out
  // Edges whose two faces run along them the same way (faces wound against
  // each other, one normal flipped): no chart grows across them.
  int opposed_winding_edges = 0;
  int charts_aggregated = 0;   // after aggregation, before overlap splits
  AggregationStops aggregate_stops;  // why the aggregation merged no further
  int refine_faces_moved = 0;  // faces the seam refinement moved to a neighbouring chart
  double refine_seam_removed = 0;  // seam length it removed / sqrt(area) (in seam_after already)
  int packing_cuts = 0;        // charts cut in two to pack tighter (see packing_cuts.hpp)
  double packing_cut_seam = 0;  // seam length those cuts added / sqrt(area) (in seam_after already)
  bool cut_to_fit = false;     // some of those cuts were made because the charts outgrew the input (fit_cut_seam)
  int faces_detached = 0;      // faces made charts of their own because float32 storage turned them over
  int charts_after = 0;        // in the output
  int charts_solved = 0;       // flattened by SLIM (the rest kept their original UVs)
  FlattenStats flatten;        // charts split back by reason, scaffolded, halved (see kFlattenCounters)
  int density_reflattened = 0;  // aggregated charts flattened again under a stricter density rule
                                // (flatten_aggregation.hpp)
  double seam_before = 0, seam_after = 0;  // seam length / sqrt(area)
  long long texels_before = 0, texels_after = 0;
  double packing_efficiency = 0;
  double scale = 1;            // smallest uniform texel scale the packer applied
  bool shrunk = false;         // some group's charts got less than the density asked for (scale says how much)
  // Symmetric Dirichlet energy per unit reference area of the solved charts
  // (4 is isometric): median at the initial embedding, then median and max after SLIM
  // (as solved: the border refinements after it move faces and vertices).
  double energy_initial_median = 0, energy_median = 0, energy_max = 0;
  // The chart with the most faces that plain SLIM solved: its faces, and the
  // wall time of its SLIM iterations over that of the numeric factorizations
  // in them (both summed; a retried factorization counts twice).
  int largest_chart_faces = 0;
  double iteration_over_factorization = 0;
  std::vector<StageTime> seconds;
};

// One chart of the output, as the flattening left it.
struct ChartSummary {
  int faces = 0;
  bool flattened = false;             // solved by SLIM (false: the input's UVs kept, or a lone flat face thickened)
  // Per unit reference area, of the flattening (before a chart under a texel
  // across is enlarged, see pipeline.cpp); 0 when kept.
  double energy_initial = 0, energy_final = 0;
};

struct PipelineResult {
  RowMatrixX2d corner_uv;       // 3F x 2, page units of the new pages
  Eigen::VectorXi face_page;    // new page per face, -1 kept for untextured faces
  Eigen::VectorXi face_chart;   // output chart per face (index into charts), -1 for untextured faces
  std::vector<PageSize> pages;
  std::vector<int> page_padding;  // per page: texels of padding its charts got (see PackOptions)
  std::vector<ChartSummary> charts;
  PipelineReport report;
};

// mesh: welded (make_mesh); face_group (F) or empty: faces of different
// groups never share a chart or a page; face_polygon (F) or empty: the
// polygon (quad, n-gon) each face triangulates, whose faces the border
// refinements move together or not at all (see Polygons) and no cut parts
// (MeshTopology::inside_polygon).
PipelineResult defragment(const Mesh& mesh, const std::vector<int>& face_group, const std::vector<int>& face_polygon,
                          const PipelineOptions& options, const RunControl& control);

}  // namespace atlas
