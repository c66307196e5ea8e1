// Every aggregated chart flattened under the density rule: each chart is
// split back (flatten_without_overlap) where it loses more than a strict
// share of its surface, and while the whole surface still loses more than
// its budget, the charts that lose most are flattened again under stricter
// rules.
#pragma once
#include <vector>

#include "charts/aggregate.hpp"
#include "charts/chart_graph.hpp"
#include "core/mesh.hpp"
#include "core/run_control.hpp"
#include "core/topology.hpp"
#include "flatten/flatten_without_overlap.hpp"

namespace atlas {

struct AggregationFlattenOptions {
  SlimOptions slim;
  // Share of the surface that may end below half its texel density; 0: no
  // loss anywhere (see PipelineOptions::density_loss_budget).
  double density_loss_budget = 0.002;
  int relief_cuts = FlattenOptions().relief_cuts;  // see FlattenOptions; 0: split at once
};

struct FlattenedAggregation {
  std::vector<FlatChart> charts;  // the pieces of every aggregated chart
  FlattenStats stats;             // summed over the charts, as last flattened
  int reflattened = 0;            // aggregated charts flattened again under a stricter rule
};

// graph: the cut surface's chart graph, with the arcs partial merges left
// open as self seams (Aggregation::kept_seam). Charts are flattened largest
// first, one per task, so that the long ones start early.
FlattenedAggregation flatten_aggregation(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                         const Aggregation& aggregation, const AggregationFlattenOptions& options,
                                         const RunControl& control);

}  // namespace atlas
