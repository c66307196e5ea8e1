// Aggregation (thesis 5.2): greedy edge collapse on the chart graph, cheapest
// first, refusing any merge whose result is not a topological disk.
#pragma once
#include <vector>

#include "charts/chart_graph.hpp"
#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "core/topology.hpp"

namespace atlas {

enum class Weighting { UV, Surface };

struct AggregateOptions {
  // w_3D by default: on the shared scans it leaves fewer charts and shorter
  // seams than w_UV (bench/README.md, "Measurements behind the defaults").
  Weighting weighting = Weighting::Surface;
  int target_charts = 0;            // stop at this many charts; 0: no target
  // A collapse is made only while the smaller chart covers less than this
  // fraction of the total area; 1 lets charts grow as far as topology
  // allows, 0 refuses every collapse.
  double min_chart_fraction = 1.0;
  // A merged chart's area-weighted mean normal, |sum_f A_f n_f| / sum_f A_f,
  // may not fall below this. A spherical cap of half-angle t has (1 + cos t)/2,
  // so 0.5 stops at a hemisphere: beyond it no flattening keeps the original
  // texel density, and solving such a chart only to split it is what makes
  // large closed scans slow. 0 disables.
  double min_normal_coherence = 0.5;
  // A merge whose union has at most this many faces (or whose smaller chart
  // has at most 100) is exempt from min_normal_coherence: a small chart bent
  // past a hemisphere is cheap to flatten, and a relief cut
  // (flatten/relief_cut.hpp) opens it where it would lose density. Larger, the merged charts bend further and lose
  // colour detail (bench/README.md). 0: the gate applies to every merge but
  // those of a chart of at most 100 faces.
  int coherence_free_faces = 1000;
  // Photogrammetry tools cut charts by camera view, not by triangle: the same
  // scan tessellated four times finer has as many charts of four times the
  // faces. The face counts above (1000 and 100) hold for up to this many
  // textured faces per input chart (charts with a neighbour: loose debris
  // does not count; the shared scans stay under it), and scale with a finer
  // input, so that the same surface merges alike however finely it is
  // tessellated. max_chart_faces scales too, up to 4x: it bounds solver
  // time, which grows faster than the faces. 0: no scaling; else >= 1.
  double reference_chart_faces = 100;
  // A union that min_normal_coherence refuses merges all the same when the
  // Gaussian curvature inside it (the sum of the angle defects at its
  // interior vertices, core/angle_defects.hpp) is at most this many radians
  // either way: it bends like a cylinder or a cone, which unrolls without
  // stretch however far it wraps. 0.6 is the curvature of a spherical cap of
  // about 25 degrees. Curvature of both signs cancels in the sum, and the
  // vertices of arcs a partial merge leaves open count as inside: the density
  // rule splits a chart that then loses detail (bench/README.md for the
  // value). 0 disables.
  double developable_curvature = 0.6;
  // No merged chart grows beyond this many faces (scaled as
  // reference_chart_faces says): the cost of flattening a chart grows faster
  // than its size (sparse Cholesky fill), and many mid-sized charts keep
  // every core busy where one huge chart would leave the others idle.
  // 0 disables.
  int max_chart_faces = 20000;
  // Two charts whose union would not be a disk (they touch along several
  // arcs) merge along their longest shared arc, the others staying a seam
  // inside the chart (see DiskClusters). false refuses such pairs.
  bool partial_merges = true;
};

// Why the adjacent charts left at the end were not merged: one count per pair,
// by the first rule that refuses it. It tells a chart count that topology
// forces (not_disk, non_manifold) from one that the options chose.
struct AggregationStops {
  int non_manifold = 0;        // a non-manifold or flipped shared edge, or a chart that started non-manifold or with a handle
  int not_disk = 0;            // the union would have a hole or a handle
  int normal_coherence = 0;    // see AggregateOptions
  int max_chart_faces = 0;
  int min_chart_fraction = 0;
  int feasible = 0;            // nothing refuses it: the target count was reached first
};

struct Aggregation {
  std::vector<int> face_chart;                 // F, new chart per face, -1 untextured
  std::vector<std::vector<int>> members;       // new chart -> original charts in it
  // Per edge: boundary on both sides. The graph's self seams plus the arcs
  // that partial merges left open between two original charts of one chart.
  std::vector<char> kept_seam;
  // Every merge in the order made: (survivor, absorbed), clusters named by
  // an original chart in them. The flattening undoes them from the last.
  std::vector<std::pair<int, int>> merges;
  AggregationStops stops;
  int chart_count() const { return static_cast<int>(members.size()); }
};

// Greedy edge collapse on the chart graph (thesis 5.2): the adjacent pair of
// lowest cost (w_3D or w_UV, eq. 5.1, 5.2) merges first, while the union
// stays a disk (or merges partially, see AggregateOptions::partial_merges)
// and the options' gates let it. graph is build_chart_graph(mesh, topology, ...).
Aggregation aggregate_charts(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                             const AggregateOptions& options, const RunControl& control);

}  // namespace atlas
