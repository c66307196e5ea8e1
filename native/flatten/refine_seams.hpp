// Seam refinement: once the charts are flattened, a face that
// touches a neighbouring chart along two of its edges (a tooth of a zig-zag
// border) moves over to it when that shortens the seam, at the place the
// neighbour's flattening already gives its three corners. No chart is solved
// again: a move is made only when the face then lies inside the neighbour's
// flattening without a flip, an overlap or a loss of texel density, so the
// output guarantees hold as they did. Each face is still baked from its own
// original UV triangle, wherever it goes.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/mesh.hpp"
#include "core/topology.hpp"
#include "flatten/flatten_without_overlap.hpp"

namespace atlas {

struct RefineOptions {
  // A moved face keeps at least this share of its original texel area (the
  // density rule's half); 0 disables the refinement.
  double min_area_ratio = 0.5;
};

// The polygons (quads, n-gons) that faces triangulate: faces leave a chart
// only with every face of their polygons in that chart, since each corner of
// a polygon holds one UV where the mesh came from (Blender). A move may
// bring a polygon's faces together, never part them.
class Polygons {
 public:
  // face_polygon (F): a polygon id per face (any ints); empty: every face
  // is a polygon of its own.
  explicit Polygons(const std::vector<int>& face_polygon);

  // Whether moving `faces` out of their chart parts no polygon: each face
  // of theirs that chart_of(g) puts in the same chart as they are is among
  // them.
  template <class ChartOf>
  bool move_keeps_whole(std::vector<int> faces, ChartOf chart_of) const {
    if (polygon_.empty()) return true;
    std::sort(faces.begin(), faces.end());
    for (int f : faces)
      for (int k = start_[polygon_[f]]; k < start_[polygon_[f] + 1]; ++k) {
        const int g = members_[k];
        if (chart_of(g) == chart_of(f) && !std::binary_search(faces.begin(), faces.end(), g)) return false;
      }
    return true;
  }

 private:
  std::vector<int> polygon_;  // per face, its polygon numbered 0..P-1
  std::vector<int> start_;    // P + 1: polygon p's faces are members_[start_[p] .. start_[p + 1])
  std::vector<int> members_;
};

// What both border refinements read. seam (per edge): edges that stay
// boundary on both sides (the seams kept inside charts: the aggregation's and
// the cuts of the flattening); faces on them do not move. face_group (F) as
// for defragment (may be empty).
struct RefineInput {
  const Mesh& mesh;
  const MeshTopology& topology;
  const std::vector<char>& seam;
  const std::vector<int>& face_group;
  const RefineOptions& options;
  const Polygons& polygons;

  // The texel area a face moved to another chart must keep: min_area_ratio of
  // its original, and a hundredth of a texel at least, so that float32
  // storage keeps its winding.
  double needed_area(int f) const { return std::max(0.01, options.min_area_ratio * std::abs(mesh.signed_area_uv(f))); }
};

struct RefineStats {
  int faces_moved = 0;
  double seam_removed_3d = 0;  // total 3D length of seam the moves removed
};

// charts: the flattened charts (faces and texel corner UVs, see FlatChart),
// changed in place. Moves are made greedily until none shortens the seam:
// each removes |e1| + |e2| - |e3| of seam, e1 and e2 the edges towards the
// new chart and e3 the one towards the old (|e3| counting 0 when e3 was a
// seam already), so this ends.
RefineStats refine_seams(const RefineInput& input, std::vector<FlatChart>& charts);

}  // namespace atlas
