#include "charts/degenerate_faces.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>

#include "core/hash_words.hpp"

namespace atlas {
namespace {

// (group, textured, a, b, c), packed in three words: the face's vertices in
// the rotation that is smallest lexicographically, keeping their cyclic
// order; and that rotation.
using FaceKey = std::array<std::uint64_t, 3>;

std::uint64_t pair_word(int high, int low) {
  return static_cast<std::uint64_t>(static_cast<std::uint32_t>(high)) << 32 | static_cast<std::uint32_t>(low);
}

FaceKey face_key(const Mesh& mesh, const std::vector<int>& face_group, int f, int& rotation) {
  const auto t = mesh.triangles.row(f);
  auto rotated = [&](int r) { return std::array<int, 3>{t(r), t((r + 1) % 3), t((r + 2) % 3)}; };
  rotation = 0;
  for (int r = 1; r < 3; ++r)
    if (rotated(r) < rotated(rotation)) rotation = r;
  const std::array<int, 3> v = rotated(rotation);
  return {pair_word(face_group.empty() ? 0 : face_group[f], mesh.face_page[f] >= 0 ? 1 : 0), pair_word(v[0], v[1]),
          pair_word(v[2], 0)};
}

}  // namespace

DuplicateFaces find_duplicate_faces(const Mesh& mesh, const std::vector<int>& face_group) {
  const int n = mesh.face_count();
  std::vector<FaceKey> keys(n);
  std::vector<int> rotation(n);
  for (int f = 0; f < n; ++f) keys[f] = face_key(mesh, face_group, f, rotation[f]);
  DuplicateFaces out;
  out.original = first_of_equal_keys(n, [&](int f) { return keys[f]; });
  out.shift.assign(n, 0);
  for (int f = 0; f < n; ++f) {
    const int first = out.original[f];
    // Corner rotation[f] of f and corner rotation[first] of first sit at the same vertex.
    out.shift[f] = ((rotation[first] - rotation[f]) % 3 + 3) % 3;
    if (first == f) out.kept.push_back(f);
  }
  return out;
}

std::vector<int> first_of_equal_faces(const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page) {
  // Bit patterns, not values: equal bits hash equally (0.0 and -0.0 would not),
  // and a NaN, which a caller may pass, equals its own copies. The corners
  // start at the least one: a copy starting at another corner draws the same.
  const std::vector<int> first = first_of_equal_keys(static_cast<int>(face_page.size()), [&](int f) {
    std::array<std::array<std::uint64_t, 2>, 3> corner;
    for (int i = 0; i < 6; ++i) std::memcpy(&corner[i / 2][i % 2], &corner_uv(3 * f + i / 2, i % 2), sizeof(double));
    const int start = static_cast<int>(std::min_element(corner.begin(), corner.end()) - corner.begin());
    std::array<std::uint64_t, 7> k{static_cast<std::uint64_t>(static_cast<std::uint32_t>(face_page[f]))};
    for (int i = 0; i < 3; ++i) k[1 + 2 * i] = corner[(start + i) % 3][0], k[2 + 2 * i] = corner[(start + i) % 3][1];
    return k;
  });
  std::vector<int> kept;
  for (int f = 0; f < static_cast<int>(first.size()); ++f)
    if (first[f] == f) kept.push_back(f);
  return kept;
}

void take_face_uvs(const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page, const std::vector<int>& faces,
                   RowMatrixX2d& uv, Eigen::VectorXi& page) {
  const Eigen::Index n = static_cast<Eigen::Index>(faces.size());
  uv.resize(3 * n, 2);
  page.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    uv.middleRows(3 * i, 3) = corner_uv.middleRows(3 * faces[i], 3);
    page[i] = face_page[faces[i]];
  }
}

Mesh mesh_of_faces(const Mesh& mesh, const std::vector<int>& faces) {
  Mesh out;
  out.positions = mesh.positions;
  out.pages = mesh.pages;
  out.triangles.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t i = 0; i < faces.size(); ++i) out.triangles.row(i) = mesh.triangles.row(faces[i]);
  take_face_uvs(mesh.corner_uv, mesh.face_page, faces, out.corner_uv, out.face_page);
  return out;
}

}  // namespace atlas
