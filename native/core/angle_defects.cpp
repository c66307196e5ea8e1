#include "core/angle_defects.hpp"

#include <cmath>
#include <Eigen/Geometry>

#include "core/parallel_for.hpp"

namespace atlas {

std::vector<double> angle_defects(const Mesh& mesh) {
  // The corner angles on both threads (the atan2 calls are the cost), summed per vertex after.
  std::vector<double> angle(3 * static_cast<size_t>(mesh.face_count()));
  parallel_for(mesh.face_count(), 4096, [&](int f) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.positions.row(mesh.triangles(f, k));
      const Eigen::Vector3d u = Eigen::Vector3d(mesh.positions.row(mesh.triangles(f, (k + 1) % 3))) - p;
      const Eigen::Vector3d v = Eigen::Vector3d(mesh.positions.row(mesh.triangles(f, (k + 2) % 3))) - p;
      // atan2 of |u x v| and u . v: accurate for the near-flat and near-straight corners of dense scans.
      angle[3 * static_cast<size_t>(f) + k] = std::atan2(u.cross(v).norm(), u.dot(v));
    }
  });
  std::vector<double> defect(mesh.vertex_count(), 2 * M_PI);
  for (int f = 0; f < mesh.face_count(); ++f)
    for (int k = 0; k < 3; ++k) defect[mesh.triangles(f, k)] -= angle[3 * static_cast<size_t>(f) + k];
  return defect;
}

}  // namespace atlas
