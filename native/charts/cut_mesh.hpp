// The surface the later stages work on: the welded mesh cut open along the
// seams that lie inside an original chart, along non-manifold edges, along
// edges whose two faces disagree on orientation and around faces that name a
// vertex twice. Cutting duplicates vertices,
// one copy per fan of faces still joined through uncut edges.
//
// Why: scanners' charts often carry internal cuts (slits in UV that close in
// 3D), which make the chart an annulus in the welded mesh although it is a disk
// in UV. On the cut surface every original chart has the topology of its UV
// image, every remaining edge is manifold and consistently wound, and merging
// charts only ever removes seams between different charts.
#pragma once
#include "charts/chart_graph.hpp"
#include "core/mesh.hpp"
#include "core/topology.hpp"

namespace atlas {

// Same faces, corner UVs and pages; positions duplicated where cut.
Mesh cut_internal_seams(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph);

}  // namespace atlas
