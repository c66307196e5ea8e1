#include "test_meshes.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <map>

#include "core/geometry.hpp"

namespace atlas::testing {
namespace {

// Quad (a,b,c,d) counter-clockwise -> two triangles.
void add_quad(std::vector<Eigen::Vector3i>& tris, int a, int b, int c, int d) {
  tris.emplace_back(a, b, c);
  tris.emplace_back(a, c, d);
}

RowMatrixX3i to_matrix(const std::vector<Eigen::Vector3i>& tris) {
  RowMatrixX3i m(tris.size(), 3);
  for (size_t i = 0; i < tris.size(); ++i) m.row(i) = tris[i].transpose();
  return m;
}

RowMatrixX3d to_matrix(const std::vector<Eigen::Vector3d>& pts) {
  RowMatrixX3d m(pts.size(), 3);
  for (size_t i = 0; i < pts.size(); ++i) m.row(i) = pts[i].transpose();
  return m;
}

// Periodic grid of (nu x nv) quads; wrap_u/wrap_v close it into a tube or torus.
RowMatrixX3i periodic_grid(int nu, int nv, bool wrap_u, bool wrap_v, int stride) {
  std::vector<Eigen::Vector3i> tris;
  const int cu = wrap_u ? nu : nu + 1;
  (void)cu;
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      const int i1 = wrap_u ? (i + 1) % nu : i + 1;
      const int j1 = wrap_v ? (j + 1) % nv : j + 1;
      add_quad(tris, i * stride + j, i1 * stride + j, i1 * stride + j1, i * stride + j1);
    }
  return to_matrix(tris);
}

}  // namespace

Mesh grid_disk(int n, double uv_scale, int page_size) {
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j) pts.emplace_back(double(i) / n, double(j) / n, 0.0);
  const RowMatrixX3i tris = periodic_grid(n, n, false, false, n + 1);
  RowMatrixX2d uv(3 * tris.rows(), 2);
  for (Eigen::Index f = 0; f < tris.rows(); ++f)
    for (int k = 0; k < 3; ++k) uv.row(3 * f + k) = uv_scale * pts[tris(f, k)].head<2>().transpose();
  return make_mesh(to_matrix(pts), tris, uv, Eigen::VectorXi::Zero(tris.rows()),
                   {PageSize{page_size, page_size}});
}

Mesh unrolled_tube(int rings, int segments, int rings_per_chart) {
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i <= rings; ++i)
    for (int j = 0; j < segments; ++j) {
      const double t = 2 * kPi * j / segments;
      pts.emplace_back(std::cos(t), std::sin(t), double(i) / segments * 2 * kPi);
    }
  const RowMatrixX3i tris = periodic_grid(rings, segments, false, true, segments);
  RowMatrixX2d uv(3 * tris.rows(), 2);
  Eigen::VectorXi page = Eigen::VectorXi::Zero(tris.rows());
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    const int ring = static_cast<int>(f / 2 / segments), column = static_cast<int>(f / 2 % segments);
    const int chart = ring / rings_per_chart;
    for (int k = 0; k < 3; ++k) {
      const int v = tris(f, k), i = v / segments, j = v % segments;
      // The last column's far side sits at u = 1, not back at 0: the seam.
      const double u = (j == 0 && column == segments - 1 ? segments : j) / double(segments + 1);
      // Charts stacked apart in v, so that they never touch in UV.
      uv.row(3 * f + k) << 0.05 + 0.9 * u, 0.05 + 0.9 * (i + chart) / double(rings + rings / rings_per_chart);
    }
  }
  return make_mesh(to_matrix(pts), tris, uv, page, {PageSize{1024, 1024}});
}

Mesh with_chart_uvs(const RowMatrixX3d& positions, const RowMatrixX3i& triangles,
                    const std::vector<int>& face_chart, int page_size) {
  std::map<int, Eigen::Vector3d> normal;
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector3d a = positions.row(triangles(f, 0)), b = positions.row(triangles(f, 1)),
                          c = positions.row(triangles(f, 2));
    normal.try_emplace(face_chart[f], Eigen::Vector3d::Zero()).first->second += (b - a).cross(c - a);
  }
  RowMatrixX2d uv(3 * triangles.rows(), 2);
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const int chart = face_chart[f];
    const Eigen::Vector3d n = normal[chart].stableNormalized();
    const Eigen::Vector3d t = n.unitOrthogonal(), s = n.cross(t);
    const Eigen::Vector2d offset(0.05 + 0.1 * (chart % 9), 0.05 + 0.1 * (chart / 9 % 9));
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = positions.row(triangles(f, k));
      uv.row(3 * f + k) = (offset + 0.02 * Eigen::Vector2d(p.dot(t), p.dot(s))).transpose();
    }
  }
  return make_mesh(positions, triangles, uv, Eigen::VectorXi::Zero(triangles.rows()),
                   {PageSize{page_size, page_size}});
}

Mesh annulus(int rings, int segments, int segments_per_chart) {
  std::vector<Eigen::Vector3d> pts;
  for (int s = 0; s < segments; ++s)
    for (int r = 0; r <= rings; ++r) {
      const double a = 2 * kPi * s / segments, radius = 1.0 + double(r) / rings;
      pts.emplace_back(radius * std::cos(a), radius * std::sin(a), 0.0);
    }
  const RowMatrixX3i tris = periodic_grid(segments, rings, true, false, rings + 1);
  std::vector<int> chart(tris.rows());
  for (Eigen::Index f = 0; f < tris.rows(); ++f) chart[f] = int(f / (2 * rings)) / segments_per_chart;
  return with_chart_uvs(to_matrix(pts), tris, chart);
}

Mesh uv_sphere(int rings, int segments, int rings_per_chart) {
  // Poles are rings of tiny radius rather than single vertices: keeps the grid regular,
  // and the two caps close the surface.
  std::vector<Eigen::Vector3d> pts;
  for (int s = 0; s < segments; ++s)
    for (int r = 0; r <= rings; ++r) {
      const double phi = kPi * (0.02 + 0.96 * r / rings), theta = 2 * kPi * s / segments;
      pts.emplace_back(std::sin(phi) * std::cos(theta), std::sin(phi) * std::sin(theta), std::cos(phi));
    }
  RowMatrixX3i band = periodic_grid(segments, rings, true, false, rings + 1);
  std::vector<Eigen::Vector3i> tris;
  for (Eigen::Index f = 0; f < band.rows(); ++f) tris.push_back(band.row(f).transpose());
  const int north = static_cast<int>(pts.size());
  pts.emplace_back(0, 0, 1);
  pts.emplace_back(0, 0, -1);
  for (int s = 0; s < segments; ++s) {
    const int s1 = (s + 1) % segments;
    tris.emplace_back(north, s1 * (rings + 1), s * (rings + 1));
    tris.emplace_back(north + 1, s * (rings + 1) + rings, s1 * (rings + 1) + rings);
  }
  std::vector<int> chart(tris.size());
  for (size_t f = 0; f < tris.size(); ++f)
    chart[f] = f < size_t(band.rows())
                   ? int(f / 2 % rings) / rings_per_chart * 4 + int(f / 2 / rings) * 4 / segments
                   : 1000 + int(f % 2);  // the two polar caps
  return with_chart_uvs(to_matrix(pts), to_matrix(tris), chart);
}

Mesh torus(int major, int minor, int major_per_chart) {
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < major; ++i)
    for (int j = 0; j < minor; ++j) {
      const double u = 2 * kPi * i / major, v = 2 * kPi * j / minor, r = 2.0 + 0.5 * std::cos(v);
      pts.emplace_back(r * std::cos(u), r * std::sin(u), 0.5 * std::sin(v));
    }
  const RowMatrixX3i tris = periodic_grid(major, minor, true, true, minor);
  std::vector<int> chart(tris.rows());
  for (Eigen::Index f = 0; f < tris.rows(); ++f) {
    const int i = int(f / (2 * minor)), j = int(f / 2 % minor);
    chart[f] = i / major_per_chart * 4 + j * 4 / minor;  // 4 patches around the tube
  }
  return with_chart_uvs(to_matrix(pts), tris, chart);
}

Mesh nonmanifold_fin() {
  const std::vector<Eigen::Vector3d> pts = {{0, 0, 0}, {0, 1, 0}, {1, 0, 0}, {1, 1, 0},
                                            {-1, 0, 0}, {-1, 1, 0}, {0, 0, 1}, {0, 1, 1}};
  std::vector<Eigen::Vector3i> tris;
  add_quad(tris, 0, 2, 3, 1);
  add_quad(tris, 4, 0, 1, 5);
  add_quad(tris, 0, 6, 7, 1);
  return with_chart_uvs(to_matrix(pts), to_matrix(tris), {0, 0, 1, 1, 2, 2});
}

}  // namespace atlas::testing
