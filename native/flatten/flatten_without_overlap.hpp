// Overlaps (thesis 5.1). SLIM hands a chart whose boundary starts crossing
// itself to SCAF (see slim.hpp), so overlaps are rare. A chart that loses too
// much texel density is first slit open (relief_cut.hpp) and solved again; a
// merged chart that still overlaps, fails or loses density is split back by
// undoing the aggregation's last merge among its original charts, each part
// solved again. A group holding a single original chart keeps its original
// UVs, unless they overlap (fold over or cross): then it is flattened, or cut
// into halves that are kept or flattened (down to single faces if need be),
// so this always ends and leaves no face flipped and no boundary crossing.
#pragma once
#include <optional>
#include <utility>
#include <vector>

#include "charts/chart_graph.hpp"
#include "core/mesh.hpp"
#include "core/topology.hpp"
#include "flatten/slim.hpp"

namespace atlas {

// True when two boundary edges of the chart cross or touch (other than at a
// shared end vertex). Uses a uniform grid over the boundary's bounding box.
// triangles are local vertex indices into uv.
bool boundary_self_intersects(const RowMatrixX3i& triangles, const RowMatrixX2d& uv);
// The faces of the first two boundary edges found crossing, if any.
std::optional<std::pair<int, int>> boundary_crossing(const RowMatrixX3i& triangles, const RowMatrixX2d& uv);

// The problem parameterize_chart solves for the mesh faces `faces` as
// triangles (F x 3) over local vertices (`vertices`: local -> mesh vertex):
// their 3D positions, their original UV triangles in texels and whether
// each face's original chart is mirrored. Rows of triangles past F fill
// holes (fill_holes): their reference is left empty, so that it is their
// 3D triangle at the chart's density (repaired_reference_triangles); a
// vertex numbered mesh.vertex_count() + i sits at row i of fill_positions
// (H x 3, fill_holes' centres).
ChartProblem chart_problem(const Mesh& mesh, const ChartGraph& graph, const std::vector<int>& faces,
                           const RowMatrixX3i& triangles, const std::vector<int>& vertices,
                           const RowMatrixX3d& fill_positions = {});

// A chart as it leaves the parameterization stage.
struct FlatChart {
  std::vector<int> faces;      // mesh faces
  RowMatrixX2d corner_uv;      // 3 rows per face, texels, arbitrary placement
  bool kept_original = false;  // single original chart, UVs copied from the input
  double density_lost_area = 0;  // 3D area of its faces left below half their texel density
  double energy_initial = 0, energy_final = 0;  // per unit reference area (0 when kept)
  double iteration_seconds = 0, factorize_seconds = 0;  // see ChartSolution
};

// Why charts were split back (each split counts once, under its first reason).
struct FlattenStats {
  int not_disk = 0;            // handles left after cutting holes open
  int solver_failed = 0;       // SLIM reported a failure or left flipped faces
  int overlapped = 0;          // the new boundary crossed itself
  int density_lost = 0;        // too much of the surface kept less than half its texels (FlattenOptions)
  int overlap_halved = 0;      // not a split of merged charts: lone charts whose own UVs overlap, cut in two
  int scaffolded = 0;          // not a split: solves whose boundary crossed and that SCAF finished
  int relief_cuts = 0;         // not a split: slits cut into charts that lost density (relief_cut.hpp)
  int density_repaired = 0;    // not a split: charts kept with their density repair (SlimOptions::repair_rounds)
  int holes_filled = 0;        // not a split: the mesh's holes inside kept charts, filled for the solve (fill_holes)
};

// Every counter under the name the report gives it: a new counter is a field
// above and a row here, and the sums, the bindings and the report follow.
struct FlattenCounter {
  const char* name;
  int FlattenStats::*field;
};
inline constexpr FlattenCounter kFlattenCounters[] = {
    {"splits_not_disk", &FlattenStats::not_disk},     {"splits_solver", &FlattenStats::solver_failed},
    {"splits_overlap", &FlattenStats::overlapped},    {"splits_density", &FlattenStats::density_lost},
    {"charts_scaffolded", &FlattenStats::scaffolded}, {"overlap_halved", &FlattenStats::overlap_halved},
    {"relief_cuts", &FlattenStats::relief_cuts},     {"density_repaired", &FlattenStats::density_repaired},
    {"holes_filled", &FlattenStats::holes_filled},
};

inline FlattenStats& operator+=(FlattenStats& sum, const FlattenStats& more) {
  for (const FlattenCounter& c : kFlattenCounters) sum.*c.field += more.*c.field;
  return sum;
}

struct FlattenOptions {
  SlimOptions slim;
  // A flattened chart is split when faces covering more than this share of
  // its surface end with less than half their texel density. 0 splits any
  // chart that loses density anywhere.
  double max_density_loss = 0.02;
  // 3D area a chart may leave below half density whatever its share: spares
  // splitting small pieces (closed scan debris above all) whose loss the
  // surface does not notice. 0: none.
  double density_loss_allowance = 0;
  // Slits a chart that loses too much density may get, each followed by a
  // new solve, before it is split instead (relief_cut.hpp). 0: split at once.
  int relief_cuts = 2;
};

// Per original chart: 1 when its faces, joined as the flattening joins them,
// keep a handle once their holes are cut open (UVs that fold a chart onto
// itself can). Every chart holding one would too, so such a chart is better
// left to merge with nothing.
std::vector<char> charts_with_handles(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                      const std::vector<std::vector<int>>& chart_faces);

// Flattens one aggregated chart (its original charts `members`), splitting on
// overlap or solver failure until every piece is valid. merges: the
// aggregation's (Aggregation::merges), which a split undoes from the last;
// empty, or members that are not one cluster of them, regrow two or more
// groups instead.
// chart_faces[c] lists the faces of original chart c.
std::vector<FlatChart> flatten_without_overlap(const Mesh& mesh, const MeshTopology& topology,
                                               const ChartGraph& graph,
                                               const std::vector<std::vector<int>>& chart_faces,
                                               const std::vector<int>& members,
                                               const std::vector<std::pair<int, int>>& merges,
                                               const FlattenOptions& options, const RunControl& control,
                                               FlattenStats& stats);

}  // namespace atlas
