#include "pack/smallest_box_turn.hpp"

#include <algorithm>
#include <limits>
#include <vector>

namespace atlas {
namespace {

double cross(const Eigen::RowVector2d& o, const Eigen::RowVector2d& a, const Eigen::RowVector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

// Convex hull, counter-clockwise, collinear points dropped (Andrew's monotone chain).
std::vector<Eigen::RowVector2d> convex_hull(const RowMatrixX2d& uv) {
  std::vector<Eigen::RowVector2d> p(uv.rows());
  for (Eigen::Index i = 0; i < uv.rows(); ++i) p[i] = uv.row(i);
  std::sort(p.begin(), p.end(), [](const Eigen::RowVector2d& a, const Eigen::RowVector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (p.size() < 3) return p;
  std::vector<Eigen::RowVector2d> hull(2 * p.size());
  size_t k = 0;
  for (size_t i = 0; i < p.size(); ++i) {  // lower chain
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (size_t i = p.size() - 1, lower = k + 1; i-- > 0;) {  // upper chain
    while (k >= lower && cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  hull.resize(k - 1);  // the last point repeats the first
  return hull;
}

}  // namespace

RowMatrixX2d turned_to_smallest_box(const RowMatrixX2d& uv) {
  if (!uv.allFinite()) return uv;
  const std::vector<Eigen::RowVector2d> hull = convex_hull(uv);
  if (hull.size() < 3) return uv;
  double best_area = std::numeric_limits<double>::infinity();
  Eigen::Matrix2d best = Eigen::Matrix2d::Identity();
  for (size_t i = 0; i < hull.size(); ++i) {
    const Eigen::RowVector2d edge = hull[(i + 1) % hull.size()] - hull[i];
    const double length = edge.norm();
    if (!(length > 0)) continue;
    // Rows of r: the edge direction and its normal; r * p gives p in that frame.
    Eigen::Matrix2d r;
    r << edge.x() / length, edge.y() / length, -edge.y() / length, edge.x() / length;
    Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const Eigen::RowVector2d& p : hull) {
      const Eigen::Vector2d q = r * p.transpose();
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    const double area = (hi.x() - lo.x()) * (hi.y() - lo.y());
    if (area < best_area) {
      best_area = area;
      best = r;
    }
  }
  return uv * best.transpose();
}

}  // namespace atlas
