// Corner navigation and half-edge pairing on a triangle array: the one home
// of the mesh combinatorics every stage uses. Corner c = 3f + k is corner k
// of face f; it starts the half-edge from triangles(f,k) to triangles(f,(k+1)%3).
#pragma once
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "core/mesh.hpp"
#include "core/union_find.hpp"

namespace atlas {

inline int corner_face(int c) { return c / 3; }
inline int next_corner(int c) { return c % 3 == 2 ? c - 2 : c + 1; }
inline int previous_corner(int c) { return c % 3 == 0 ? c + 2 : c - 1; }
inline int corner_vertex(const RowMatrixX3i& triangles, int c) { return triangles(c / 3, c % 3); }

// Key of the undirected edge {a, b}: the smaller index in the high 32 bits,
// so sorting keys sorts edges lexicographically by (min, max).
inline std::int64_t edge_key(std::int64_t a, std::int64_t b) { return std::min(a, b) << 32 | std::max(a, b); }

// Sorts keyed[first, last) in place: insertion sort for the few keys a vertex
// starts, std::sort for a fan's centre, where insertion would be quadratic.
inline void sort_bucket(std::vector<std::pair<std::int64_t, int>>::iterator first,
                        std::vector<std::pair<std::int64_t, int>>::iterator last) {
  constexpr std::ptrdiff_t kInsertionMost = 16;
  if (last - first > kInsertionMost) {
    std::sort(first, last);
    return;
  }
  for (auto i = first; i != last; ++i)
    for (auto j = i; j != first && *j < *(j - 1); --j) std::iter_swap(j, j - 1);
}

// (edge key, corner) for corners 0..corner_count-1, sorted: the half-edges
// of one undirected edge are adjacent, in increasing corner order.
// vertex_of(c) is the vertex at corner c, >= 0 (edge_key needs it).
// Every stage pairs half-edges this way, so it is a counting sort on the
// smaller vertex (a few corners per vertex), then each vertex's few keys
// sorted in place: the order std::sort gives, in linear time.
template <class VertexOf>
std::vector<std::pair<std::int64_t, int>> corners_by_edge(int corner_count, VertexOf vertex_of) {
  const auto key = [&](int c) { return edge_key(vertex_of(c), vertex_of(next_corner(c))); };
  std::vector<std::pair<std::int64_t, int>> keyed(corner_count);
  std::int64_t vertices = 0;
  for (int c = 0; c < corner_count; ++c) vertices = std::max(vertices, (key(c) >> 32) + 1);
  // Counts for indices far above the corners (the scaffold numbers its
  // vertices after the chart's) would cost more than sorting.
  if (vertices > 4 * static_cast<std::int64_t>(corner_count) + 64) {
    for (int c = 0; c < corner_count; ++c) keyed[c] = {key(c), c};
    std::sort(keyed.begin(), keyed.end());
    return keyed;
  }
  std::vector<int> start(static_cast<size_t>(vertices) + 1, 0);
  for (int c = 0; c < corner_count; ++c) ++start[(key(c) >> 32) + 1];
  for (std::int64_t v = 0; v < vertices; ++v) start[v + 1] += start[v];
  std::vector<int> end(start.begin(), start.end() - 1);
  for (int c = 0; c < corner_count; ++c) {  // corners stay in increasing order
    const std::int64_t k = key(c);
    keyed[end[k >> 32]++] = {k, c};
  }
  for (std::int64_t v = 0; v < vertices; ++v) sort_bucket(keyed.begin() + start[v], keyed.begin() + end[v]);
  return keyed;
}

// Calls run(first, count) for each undirected edge of corners_by_edge's
// output: keyed[first .. first+count) are the corners starting that edge.
template <class Run>
void for_each_edge_run(const std::vector<std::pair<std::int64_t, int>>& keyed, Run run) {
  for (size_t i = 0; i < keyed.size();) {
    size_t j = i + 1;
    while (j < keyed.size() && keyed[j].first == keyed[i].first) ++j;
    run(static_cast<int>(i), static_cast<int>(j - i));
    i = j;
  }
}

// opposite[c]: the corner starting the other half-edge of c's edge, for edges
// of exactly two half-edges; -1 on a boundary or non-manifold edge.
inline std::vector<int> opposite_corners(const std::vector<std::pair<std::int64_t, int>>& keyed) {
  std::vector<int> opposite(keyed.size(), -1);
  for_each_edge_run(keyed, [&](int first, int count) {
    if (count != 2) return;
    opposite[keyed[first].second] = keyed[first + 1].second;
    opposite[keyed[first + 1].second] = keyed[first].second;
  });
  return opposite;
}

// Gives every class of united corners a vertex, numbered in order of first
// corner: out(f, k) is the vertex of corner 3f+k and source[v] is
// source_of(c) for the first corner c of class v (the vertex it copies).
template <class SourceOf>
void vertices_from_corner_classes(UnionFind& classes, int face_count, SourceOf source_of, RowMatrixX3i& out,
                                  std::vector<int>& source) {
  const std::vector<int> vertex_of_corner = classes.dense_labels();
  out.resize(face_count, 3);
  for (int c = 0; c < 3 * face_count; ++c) {
    const int v = vertex_of_corner[c];
    if (v == static_cast<int>(source.size())) source.push_back(source_of(c));
    out(c / 3, c % 3) = v;
  }
}

}  // namespace atlas
