#include "flatten/disk_boundary.hpp"

#include <sstream>

#include "core/corners.hpp"

namespace atlas {
namespace {

SolveStatus describe(const char* problem, int where) {
  std::ostringstream msg;
  msg << "chart is not a topological disk: " << problem << " " << where;
  return solve_failed(SolveFailure::not_disk, msg.str());
}

SolveStatus not_disk(const char* why) { return solve_failed(SolveFailure::not_disk, why); }

// Pairs every corner with the corner that starts the opposite half-edge
// (-1 on the boundary) and counts the undirected edges. Returns an ok status,
// or SolveFailure::not_disk naming an edge used by more than two faces, or
// twice in the same direction.
SolveStatus pair_half_edges(const RowMatrixX3i& triangles, std::vector<int>& opposite, int& edge_count) {
  const int corner_count = static_cast<int>(3 * triangles.rows());
  const auto keyed = corners_by_edge(corner_count, [&](int c) { return corner_vertex(triangles, c); });
  opposite.assign(corner_count, -1);
  edge_count = 0;
  SolveStatus problem;
  for_each_edge_run(keyed, [&](int first, int count) {
    if (!problem.ok()) return;
    ++edge_count;
    if (count > 2) problem = describe("edge shared by more than two faces at corner", keyed[first].second);
    if (count != 2) return;
    const int c = keyed[first].second, d = keyed[first + 1].second;
    if (corner_vertex(triangles, c) == corner_vertex(triangles, d))
      problem = describe("faces with opposite orientation meet at corner", c);
    opposite[c] = d;
    opposite[d] = c;
  });
  return problem;
}

// Faces met by turning around the vertex of corner c, from c until the
// boundary or back to c. Turning crosses the edge that ends at the vertex.
int fan_size(const std::vector<int>& opposite, int start) {
  int count = 1;
  for (int c = opposite[previous_corner(start)]; c >= 0 && c != start; c = opposite[previous_corner(c)])
    ++count;
  return count;
}

int reachable_face_count(const std::vector<int>& opposite, int face_count) {
  std::vector<char> seen(face_count, 0);
  std::vector<int> stack = {0};
  seen[0] = 1;
  int count = 0;
  while (!stack.empty()) {
    const int f = stack.back();
    stack.pop_back();
    ++count;
    for (int k = 0; k < 3; ++k) {
      const int across = opposite[3 * f + k];
      if (across >= 0 && !seen[across / 3]) {
        seen[across / 3] = 1;
        stack.push_back(across / 3);
      }
    }
  }
  return count;
}

}  // namespace

SolveStatus disk_boundary_loop(const RowMatrixX3i& triangles, int vertex_count,
                               std::vector<int>& boundary_corners) {
  const int face_count = static_cast<int>(triangles.rows());
  if (face_count == 0) return not_disk("chart has no faces");
  for (int f = 0; f < face_count; ++f)
    for (int k = 0; k < 3; ++k)
      if (triangles(f, k) < 0 || triangles(f, k) >= vertex_count)
        return solve_failed(SolveFailure::bad_input, "vertex index out of range in face " + std::to_string(f));
  for (int f = 0; f < face_count; ++f)
    if (triangles(f, 0) == triangles(f, 1) || triangles(f, 1) == triangles(f, 2) ||
        triangles(f, 2) == triangles(f, 0))
      return describe("repeated vertex in face", f);

  std::vector<int> opposite;
  int edge_count = 0;
  const SolveStatus pairing = pair_half_edges(triangles, opposite, edge_count);
  if (!pairing.ok()) return pairing;

  // One corner per vertex, and the boundary corner leaving each vertex: a
  // vertex with two is where two pieces of boundary touch (a bow tie).
  std::vector<int> vertex_corner_count(vertex_count, 0), any_corner(vertex_count, -1),
      boundary_corner(vertex_count, -1);
  int boundary_edge_count = 0;
  for (int c = 0; c < 3 * face_count; ++c) {
    const int v = corner_vertex(triangles, c);
    ++vertex_corner_count[v];
    any_corner[v] = c;
    if (opposite[c] >= 0) continue;
    if (boundary_corner[v] >= 0) return describe("boundary touches itself at vertex", v);
    boundary_corner[v] = c;
    ++boundary_edge_count;
  }
  for (int v = 0; v < vertex_count; ++v) {
    if (vertex_corner_count[v] == 0) return describe("no face uses vertex", v);
    const int start = boundary_corner[v] >= 0 ? boundary_corner[v] : any_corner[v];
    if (fan_size(opposite, start) != vertex_corner_count[v]) return describe("non-manifold vertex", v);
  }
  if (boundary_edge_count == 0) return not_disk("chart is not a topological disk: it has no boundary");

  // Follow the boundary edges head to tail; if the walk closes before using
  // them all, there is more than one loop (a disk with holes).
  boundary_corners.clear();
  const int start = static_cast<int>(std::find(opposite.begin(), opposite.end(), -1) - opposite.begin());
  int c = start;
  do {
    boundary_corners.push_back(c);
    c = boundary_corner[corner_vertex(triangles, next_corner(c))];
  } while (c != start && c >= 0 && static_cast<int>(boundary_corners.size()) < boundary_edge_count);
  if (c != start || static_cast<int>(boundary_corners.size()) != boundary_edge_count)
    return not_disk("chart is not a topological disk: it has more than one boundary loop");
  if (reachable_face_count(opposite, face_count) != face_count)
    return not_disk("chart is not a topological disk: faces are not connected");
  if (vertex_count - edge_count + face_count != 1)
    return describe("Euler characteristic is not 1 but", vertex_count - edge_count + face_count);
  return {};
}

}  // namespace atlas
