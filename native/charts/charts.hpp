// The charts stage (thesis 5.2). Takes the welded Mesh. Gives its chart graph
// (build_chart_graph: charts, their adjacency and seams), the cut surface the
// later stages work on (cut_internal_seams), and the greedy aggregation of its
// charts into fewer, larger disks (aggregate_charts, with why it stopped).
// disk_merge, the disk test behind every merge, is internal to the stage.
#pragma once
#include "charts/aggregate.hpp"
#include "charts/chart_graph.hpp"
#include "charts/cut_mesh.hpp"
