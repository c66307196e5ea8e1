#include "charts/degenerate_faces.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <numeric>

#include "core/hash_words.hpp"

namespace atlas {
namespace {

// (group, textured, a, b, c): the face's vertices in the rotation that is
// smallest lexicographically, keeping their cyclic order; and that rotation.
using FaceKey = std::array<int, 5>;

FaceKey face_key(const Mesh& mesh, const std::vector<int>& face_group, int f, int& rotation) {
  const auto t = mesh.triangles.row(f);
  auto rotated = [&](int r) { return std::array<int, 3>{t(r), t((r + 1) % 3), t((r + 2) % 3)}; };
  rotation = 0;
  for (int r = 1; r < 3; ++r)
    if (rotated(r) < rotated(rotation)) rotation = r;
  const std::array<int, 3> v = rotated(rotation);
  return {face_group.empty() ? 0 : face_group[f], mesh.face_page[f] >= 0 ? 1 : 0, v[0], v[1], v[2]};
}

}  // namespace

DuplicateFaces find_duplicate_faces(const Mesh& mesh, const std::vector<int>& face_group) {
  const int n = mesh.face_count();
  std::vector<FaceKey> keys(n);
  std::vector<int> rotation(n);
  for (int f = 0; f < n; ++f) keys[f] = face_key(mesh, face_group, f, rotation[f]);
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  // Stable on index: the first face of each run of equal keys is the smallest.
  std::sort(order.begin(), order.end(), [&](int a, int b) { return keys[a] != keys[b] ? keys[a] < keys[b] : a < b; });

  DuplicateFaces out;
  out.original.resize(n);
  out.shift.assign(n, 0);
  for (int i = 0; i < n; ++i) {
    const int f = order[i];
    const bool repeats = i > 0 && keys[f] == keys[order[i - 1]];
    const int first = repeats ? out.original[order[i - 1]] : f;
    out.original[f] = first;
    // Corner rotation[f] of f and corner rotation[first] of first sit at the same vertex.
    out.shift[f] = ((rotation[first] - rotation[f]) % 3 + 3) % 3;
    if (!repeats) out.kept.push_back(f);
  }
  std::sort(out.kept.begin(), out.kept.end());
  return out;
}

std::vector<int> first_of_equal_faces(const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page) {
  const int n = static_cast<int>(face_page.size());
  // Bit patterns, not values: NaN (which a caller may pass) equals nothing, itself included.
  auto key = [&](int f) {
    std::array<std::uint64_t, 7> k{static_cast<std::uint64_t>(static_cast<std::uint32_t>(face_page[f]))};
    for (int i = 0; i < 6; ++i) std::memcpy(&k[1 + i], &corner_uv(3 * f + i / 2, i % 2), sizeof(double));
    return k;
  };
  // Open addressing in face order: a face whose key is not in the table yet
  // is the first to draw its triangle.
  std::size_t slots = 16;
  while (slots < 2 * static_cast<std::size_t>(n)) slots *= 2;
  std::vector<int> table(slots, -1);
  std::vector<int> kept;
  for (int f = 0; f < n; ++f) {
    const std::array<std::uint64_t, 7> k = key(f);
    std::size_t slot = hash_words(k.data(), k.size()) & (slots - 1);
    while (table[slot] >= 0 && key(table[slot]) != k) slot = (slot + 1) & (slots - 1);
    if (table[slot] >= 0) continue;
    table[slot] = f;
    kept.push_back(f);
  }
  return kept;
}

Mesh mesh_of_faces(const Mesh& mesh, const std::vector<int>& faces) {
  Mesh out;
  out.positions = mesh.positions;
  out.pages = mesh.pages;
  const Eigen::Index n = static_cast<Eigen::Index>(faces.size());
  out.triangles.resize(n, 3);
  out.corner_uv.resize(3 * n, 2);
  out.face_page.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    out.triangles.row(i) = mesh.triangles.row(faces[i]);
    out.corner_uv.middleRows(3 * i, 3) = mesh.corner_uv.middleRows(3 * faces[i], 3);
    out.face_page[i] = mesh.face_page[faces[i]];
  }
  return out;
}

}  // namespace atlas
