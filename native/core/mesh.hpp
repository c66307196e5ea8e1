// Mesh intake: the validated, welded triangle mesh every later stage reads.
#pragma once
#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

namespace atlas {

// Bad user input. The Python layer turns it into ValueError with this message.
struct InputError : std::invalid_argument {
  using std::invalid_argument::invalid_argument;
};

struct PageSize {
  int width = 0;   // texels
  int height = 0;  // texels
};

using RowMatrixX3d = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using RowMatrixX3i = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using RowMatrixX2d = Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor>;

// A triangle mesh with one UV per face corner and one texture page per face.
// Row 3*f+k of corner_uv is the UV of corner k of face f, in page units [0,1]
// (values outside are allowed: they wrap when sampled).
struct Mesh {
  RowMatrixX3d positions;       // V x 3, welded: no two rows are equal
  RowMatrixX3i triangles;       // F x 3 indices into positions
  RowMatrixX2d corner_uv;       // 3F x 2
  Eigen::VectorXi face_page;    // F, index into pages; -1: untextured, UVs pass through
  std::vector<PageSize> pages;  // texel size of each page

  int face_count() const { return static_cast<int>(triangles.rows()); }
  int vertex_count() const { return static_cast<int>(positions.rows()); }
  // UV of corner k of face f in texels of that face's page.
  Eigen::Vector2d uv_texels(int f, int k) const;
  // Surface area of face f.
  double area_3d(int f) const;
  // Signed area of face f in texels of its page, positive counter-clockwise.
  double signed_area_uv(int f) const;
  // Which corner (0, 1 or 2) of face f sits at vertex v; -1 if none.
  int corner_of(int f, int v) const {
    for (int k = 0; k < 3; ++k)
      if (triangles(f, k) == v) return k;
    return -1;
  }
  // A face naming one vertex twice has no edges of its own to share: it joins
  // no other face's chart and never merges (later stages rely on three
  // distinct corners per face).
  bool repeats_vertex(int f) const {
    return triangles(f, 0) == triangles(f, 1) || triangles(f, 1) == triangles(f, 2) || triangles(f, 0) == triangles(f, 2);
  }
};

// Checks every array and builds a Mesh, welding positions that are exactly
// equal (glTF and PLY duplicate vertices along UV seams). Throws InputError
// naming the first problem found: shapes, indices out of range, NaN or inf,
// page index without a page (-1 marks an untextured face), non-positive page
// size, empty mesh.
// Degenerate faces (zero 3D or UV area) are kept: later stages handle them.
// weld false keeps every vertex as given, for callers that only sample
// faces (a weld sorts every vertex).
Mesh make_mesh(const RowMatrixX3d& positions, const RowMatrixX3i& triangles,
               const RowMatrixX2d& corner_uv, const Eigen::VectorXi& face_page,
               const std::vector<PageSize>& pages, bool weld = true);

}  // namespace atlas
