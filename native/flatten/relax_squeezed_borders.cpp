#include "flatten/relax_squeezed_borders.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <utility>

#include "core/geometry.hpp"
#include "core/parallel_for.hpp"
#include "flatten/reference_triangles.hpp"

namespace atlas {
namespace {

// A flattened chart as a mesh of its own: corners of one mesh vertex at one
// UV are one vertex (the two sides of a slit are two).
struct IndexedChart {
  RowMatrixX3i triangles;  // F x 3, rows of uv
  RowMatrixX2d uv;         // n x 2, texels
  std::vector<int> vertex;  // n: mesh vertex
};

IndexedChart indexed_chart(const Mesh& mesh, const FlatChart& chart) {
  IndexedChart out;
  out.triangles.resize(static_cast<Eigen::Index>(chart.faces.size()), 3);
  std::map<std::tuple<int, double, double>, int> index;
  std::vector<Eigen::Vector2d> uv;
  for (size_t i = 0; i < chart.faces.size(); ++i)
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2d p = chart.corner_uv.row(3 * static_cast<Eigen::Index>(i) + k).transpose();
      const int v = mesh.triangles(chart.faces[i], k);
      const auto [it, added] = index.emplace(std::make_tuple(v, p.x(), p.y()), static_cast<int>(uv.size()));
      if (added) uv.push_back(p), out.vertex.push_back(v);
      out.triangles(static_cast<Eigen::Index>(i), k) = it->second;
    }
  out.uv.resize(static_cast<Eigen::Index>(uv.size()), 2);
  for (size_t v = 0; v < uv.size(); ++v) out.uv.row(static_cast<Eigen::Index>(v)) = uv[v].transpose();
  return out;
}

// The smallest texel area of a face of the chart over its original one
// (faces without an original area left out; 1 with none), and the chart's
// texel area.
std::pair<double, double> smallest_area_ratio(const Mesh& mesh, const FlatChart& chart) {
  double smallest = 1, area = 0;
  for (size_t i = 0; i < chart.faces.size(); ++i) {
    const Eigen::Index row = 3 * static_cast<Eigen::Index>(i);
    const auto corner = [&](int k) { return Eigen::Vector2d(chart.corner_uv.row(row + k)); };
    const double now = std::abs(signed_area(corner(0), corner(1), corner(2)));
    const double before = std::abs(mesh.signed_area_uv(chart.faces[i]));
    area += now;
    if (before > 0) smallest = std::min(smallest, now / before);
  }
  return {smallest, area};
}

// Relaxes a solved chart with the boundary near its squeezed faces free
// (RelaxOptions::free_border); returns whether it moved.
bool relax_border(const Mesh& mesh, const ChartGraph& graph, const RelaxOptions& options, FlatChart& chart) {
  const IndexedChart local = indexed_chart(mesh, chart);
  const ChartProblem problem = chart_problem(mesh, graph, chart.faces, local.triangles, local.vertex);
  const ReferenceTriangles reference =
      repaired_reference_triangles(problem.triangles, problem.positions, problem.reference_uv, problem.mirrored);
  RowMatrixX2d uv = local.uv;
  if (!relax_squeezed_faces(local.triangles, reference.corners, options, uv)) return false;
  for (Eigen::Index i = 0; i < local.triangles.rows(); ++i)
    for (int k = 0; k < 3; ++k) chart.corner_uv.row(3 * i + k) = uv.row(local.triangles(i, k));
  return true;
}

constexpr double kDebrisTexels = 64;

}  // namespace

void relax_squeezed_borders(const Mesh& mesh, const ChartGraph& graph, const RelaxOptions& relax,
                            std::vector<FlatChart>& charts) {
  RelaxOptions options = relax;
  options.free_border = true;
  parallel_for(static_cast<int>(charts.size()), 1, [&](int c) {
    FlatChart& chart = charts[c];
    if (chart.kept_original) return;
    auto [smallest, area] = smallest_area_ratio(mesh, chart);
    if (smallest >= kDensityFloor) return;
    if (relax_border(mesh, graph, options, chart)) std::tie(smallest, area) = smallest_area_ratio(mesh, chart);
    if (smallest >= kDensityFloor) return;
    const double growth = options.floor / smallest;
    if (smallest > 0 && area * growth <= kDebrisTexels) chart.corner_uv *= std::sqrt(growth);
  });
}

}  // namespace atlas
