// Squeezed faces at chart borders, relaxed once the borders are final. Most
// faces the flattening leaves below half their texel area touch their
// chart's outline, where the relaxation inside the solve (which holds the
// outline) cannot reach them. The border refinements place a moved face
// where its new chart's outline already has its corners; once they are
// done, the outlines may change, so each solved chart with such a face is
// relaxed again with the boundary near them free: a chart a few texels
// larger where it was squeezed, instead of lost detail.
#pragma once
#include <vector>

#include "charts/chart_graph.hpp"
#include "core/mesh.hpp"
#include "flatten/flatten_without_overlap.hpp"
#include "flatten/relax_squeezed_faces.hpp"

namespace atlas {

// charts: the flattened charts of mesh (graph its chart graph), changed in
// place; charts that kept their original UVs are left alone. relax: as in
// the solve, free_border set here. A chart still squeezed and of at most
// kDebrisTexels (in the .cpp) once grown until no face is (scan debris, a
// few faces of a fraction of a texel each) is grown: it costs a few texels.
void relax_squeezed_borders(const Mesh& mesh, const ChartGraph& graph, const RelaxOptions& relax,
                            std::vector<FlatChart>& charts);

}  // namespace atlas
