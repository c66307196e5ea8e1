// The charts stage (thesis 5.2). Takes the welded Mesh. Gives the faces that
// repeat another, set aside before the stages (degenerate_faces.hpp), its
// chart graph (build_chart_graph: charts, their adjacency and seams), the cut
// surface the later stages work on (cut_internal_seams), and the greedy
// aggregation of its charts into fewer, larger disks (aggregate_charts, with
// why it stopped). DiskClusters (disk_merge.hpp), the disk test behind every
// merge, is public too: the flatten stage keeps its splits and its moved
// faces to disks with it. mesh_holes is read through chart_graph.hpp.
#pragma once
#include "charts/aggregate.hpp"
#include "charts/chart_graph.hpp"
#include "charts/cut_mesh.hpp"
#include "charts/degenerate_faces.hpp"
#include "charts/disk_merge.hpp"
