#include "core/angle_defects.hpp"

#include <cmath>
#include <Eigen/Geometry>

namespace atlas {

std::vector<double> angle_defects(const Mesh& mesh) {
  std::vector<double> defect(mesh.vertex_count(), 2 * M_PI);
  for (int f = 0; f < mesh.face_count(); ++f)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d p = mesh.positions.row(mesh.triangles(f, k));
      const Eigen::Vector3d u = Eigen::Vector3d(mesh.positions.row(mesh.triangles(f, (k + 1) % 3))) - p;
      const Eigen::Vector3d v = Eigen::Vector3d(mesh.positions.row(mesh.triangles(f, (k + 2) % 3))) - p;
      // atan2 of |u x v| and u . v: accurate for the near-flat and near-straight corners of dense scans.
      defect[mesh.triangles(f, k)] -= std::atan2(u.cross(v).norm(), u.dot(v));
    }
  return defect;
}

}  // namespace atlas
