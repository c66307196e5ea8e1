// The chart graph (thesis 5.2): charts are the faces connected across mesh
// edges whose UVs agree at both ends on the same page; two charts are adjacent
// when they share a mesh edge that is no fan edge (see degenerate_faces.hpp).
#pragma once
#include <vector>

#include "charts/mesh_holes.hpp"
#include "core/mesh.hpp"
#include "core/topology.hpp"

namespace atlas {

struct ChartStats {
  double area_3d = 0;
  double area_uv = 0;          // texels^2, sum of unsigned face areas
  double signed_area_uv = 0;   // texels^2; negative when the chart is mirrored
  double perimeter_3d = 0;     // boundary length on the surface
  double perimeter_uv = 0;     // boundary length in texels
  bool mirrored() const { return signed_area_uv < 0; }
};

struct ChartAdjacency {
  int a = 0, b = 0;            // a < b
  double length_3d = 0;        // shared boundary on the surface
  double uv_length_a = 0;      // the shared boundary measured in a's UVs (texels)
  double uv_length_b = 0;
  int shared_edges = 0;
  bool mergeable = true;       // false across non-manifold or inconsistently wound edges
};

struct ChartGraph {
  std::vector<int> face_chart;   // F, -1 for untextured faces (page -1)
  std::vector<char> self_seam;   // per edge, see self_seams: boundary on both sides
  std::vector<ChartStats> charts;
  std::vector<ChartAdjacency> adjacency;
  // The mesh's holes on this surface (mesh_holes, set by the pipeline): a
  // chart holding one whole counts it as filled, and is flattened with it
  // filled. Empty: no hole is counted so.
  MeshHoles holes;
  int chart_count() const { return static_cast<int>(charts.size()); }
};

// Per chart of graph, its faces, ascending.
std::vector<std::vector<int>> faces_of_charts(const ChartGraph& graph);

// Throws InputError unless face_group is empty or holds one group per face.
void require_face_groups(const std::vector<int>& face_group, int face_count);

// face_group (F) or empty (one group): faces of different groups never share
// a chart. Untextured faces (page -1) join no chart.
ChartGraph build_chart_graph(const Mesh& mesh, const MeshTopology& topology,
                             const std::vector<int>& face_group);

// Length of every interior edge whose two faces disagree in UV (or page),
// counted once, divided by sqrt(total 3D area): a scale-free seam measure.
// corner_uv (3F,2), face_page (F).
double seam_length_ratio(const Mesh& mesh, const MeshTopology& topology,
                         const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page);

// A 3D length in the unit of seam_length_ratio: length / sqrt(total 3D
// area), 0 on a mesh without area.
double per_sqrt_area(double length, const Mesh& mesh);

}  // namespace atlas
