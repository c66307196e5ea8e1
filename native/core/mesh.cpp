#include "core/mesh.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <tuple>

#include "core/geometry.hpp"
#include "core/uv_layout.hpp"

namespace atlas {

Eigen::Vector2d Mesh::uv_texels(int f, int k) const {
  const PageSize& page = pages[face_page[f]];
  return {corner_uv(3 * f + k, 0) * page.width, corner_uv(3 * f + k, 1) * page.height};
}

double Mesh::signed_area_uv(int f) const { return signed_area(uv_texels(f, 0), uv_texels(f, 1), uv_texels(f, 2)); }

double Mesh::area_3d(int f) const {
  return triangle_area(positions.row(triangles(f, 0)), positions.row(triangles(f, 1)), positions.row(triangles(f, 2)));
}

namespace {

template <class Matrix>
void require_finite(const Matrix& m, const char* name) {
  for (Eigen::Index i = 0; i < m.rows(); ++i)
    for (Eigen::Index j = 0; j < m.cols(); ++j)
      if (!std::isfinite(m(i, j))) {
        std::ostringstream msg;
        msg << name << " has a non-finite value (NaN or inf) at row " << i;
        throw InputError(msg.str());
      }
}

void require_counts(const RowMatrixX3d& positions, const RowMatrixX3i& triangles, const std::vector<PageSize>& pages) {
  if (positions.rows() == 0) throw InputError("mesh has no vertices");
  if (triangles.rows() == 0) throw InputError("mesh has no triangles");
  // Corners are numbered 3 f + k with int: past this, they would wrap.
  if (triangles.rows() > std::numeric_limits<int>::max() / 3) {
    std::ostringstream msg;
    msg << "mesh has " << triangles.rows() << " triangles, more than the " << std::numeric_limits<int>::max() / 3
        << " supported";
    throw InputError(msg.str());
  }
  if (pages.empty()) throw InputError("no texture page sizes given");
}

void require_indices(const RowMatrixX3i& triangles, Eigen::Index vertex_count) {
  for (Eigen::Index f = 0; f < triangles.rows(); ++f)
    for (int k = 0; k < 3; ++k)
      if (triangles(f, k) < 0 || triangles(f, k) >= vertex_count) {
        std::ostringstream msg;
        msg << "triangle " << f << " has vertex index " << triangles(f, k)
            << " out of range [0, " << vertex_count << ")";
        throw InputError(msg.str());
      }
}

// Maps every input vertex to the first vertex with bit-identical coordinates.
// Exact equality, not a tolerance: exporters duplicate seam vertices by copying
// them, and a tolerance would fuse genuinely distinct nearby vertices.
std::vector<int> weld_exact(const RowMatrixX3d& positions, RowMatrixX3d& welded) {
  const Eigen::Index n = positions.rows();
  // Each vertex's coordinates beside its index, so that the sort reads
  // contiguous memory; ties in position go by index.
  struct Keyed {
    double x, y, z;
    int index;
    bool same_place(const Keyed& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  std::vector<Keyed> order(n);
  for (Eigen::Index v = 0; v < n; ++v)
    order[v] = {positions(v, 0), positions(v, 1), positions(v, 2), static_cast<int>(v)};
  std::sort(order.begin(), order.end(), [](const Keyed& a, const Keyed& b) {
    return std::tie(a.x, a.y, a.z, a.index) < std::tie(b.x, b.y, b.z, b.index);
  });
  std::vector<int> remap(n);
  std::vector<int> kept;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (i == 0 || !order[i].same_place(order[i - 1])) kept.push_back(order[i].index);
    remap[order[i].index] = static_cast<int>(kept.size()) - 1;
  }
  welded.resize(static_cast<Eigen::Index>(kept.size()), 3);
  for (size_t i = 0; i < kept.size(); ++i) welded.row(i) = positions.row(kept[i]);
  return remap;
}

}  // namespace

Mesh make_mesh(const RowMatrixX3d& positions, const RowMatrixX3i& triangles,
               const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page,
               const std::vector<PageSize>& pages, bool weld) {
  require_counts(positions, triangles, pages);
  require_finite(positions, "positions");
  require_finite(corner_uv, "uvs");  // untextured faces too: their UVs pass through
  require_layout({&corner_uv, &face_page, &pages}, triangles.rows(), "", Untextured::allowed);
  require_indices(triangles, positions.rows());

  Mesh mesh;
  if (weld) {
    const std::vector<int> remap = weld_exact(positions, mesh.positions);
    mesh.triangles.resize(triangles.rows(), 3);
    for (Eigen::Index f = 0; f < triangles.rows(); ++f)
      for (int k = 0; k < 3; ++k) mesh.triangles(f, k) = remap[triangles(f, k)];
  } else {
    mesh.positions = positions;
    mesh.triangles = triangles;
  }
  mesh.corner_uv = corner_uv;
  mesh.face_page = face_page;
  mesh.pages = pages;
  return mesh;
}

}  // namespace atlas
