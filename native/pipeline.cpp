#include "pipeline.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <limits>
#include <map>
#include <numeric>

#include "core/parallel_for.hpp"
#include "core/topology.hpp"
#include "core/uv_layout.hpp"

namespace atlas {
namespace {

class StageClock {
 public:
  explicit StageClock(PipelineReport& report) : report_(report) {}
  void lap(const std::string& stage) {
    const auto now = std::chrono::steady_clock::now();
    report_.seconds.push_back({stage, std::chrono::duration<double>(now - last_).count()});
    last_ = now;
  }

 private:
  PipelineReport& report_;
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

std::vector<std::vector<int>> faces_by_chart(const std::vector<int>& face_chart, int chart_count) {
  std::vector<std::vector<int>> out(chart_count);
  for (size_t f = 0; f < face_chart.size(); ++f)
    if (face_chart[f] >= 0) out[face_chart[f]].push_back(static_cast<int>(f));
  return out;
}

// One aggregated chart per task, largest first so the long ones start early.
std::vector<FlatChart> flatten_all(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                   const Aggregation& aggregation, const SlimOptions& options,
                                   const RunControl& control, PipelineReport& report) {
  const auto chart_faces = faces_by_chart(graph.face_chart, graph.chart_count());
  std::vector<int> order(aggregation.chart_count());
  std::iota(order.begin(), order.end(), 0);
  auto faces_in = [&](int c) {
    size_t n = 0;
    for (int m : aggregation.members[c]) n += chart_faces[m].size();
    return n;
  };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return faces_in(a) > faces_in(b); });

  std::vector<std::vector<FlatChart>> pieces(order.size());
  std::vector<FlattenStats> stats(order.size());
  size_t total_faces = 0;
  for (int c : order) total_faces += faces_in(c);
  std::atomic<size_t> finished_faces{0};
  parallel_for(static_cast<int>(order.size()), 1, [&](int i) {
    control.throw_if_cancelled();
    pieces[i] = flatten_without_overlap(mesh, topology, graph, chart_faces, aggregation.members[order[i]], options,
                                        control, stats[i]);
    finished_faces += faces_in(order[i]);
    // Every worker reports, one at a time (the Python callback takes the GIL):
    // thread 0 alone stays silent while it flattens the largest chart, which
    // comes first. Faces, not charts, because time follows the face count.
    std::exception_ptr error;
#pragma omp critical(atlas_flatten_progress)
    try {
      control.progress("flatten", double(finished_faces) / std::max<size_t>(total_faces, 1));
    } catch (...) {
      error = std::current_exception();
    }
    if (error) std::rethrow_exception(error);
  });
  control.throw_if_cancelled();
  std::vector<FlatChart> out;
  for (size_t i = 0; i < pieces.size(); ++i) {
    report.flatten += stats[i];
    for (auto& c : pieces[i]) out.push_back(std::move(c));
  }
  return out;
}

// A chart less than a texel across is scaled up to one texel. Such charts are
// scan debris (closed blobs of a few faces), and their faces would be slivers
// the size of float32 or 6-decimal UV storage noise, whose winding does not
// survive being written out. A texel more per blob costs nothing.
void enlarge_tiny_charts(std::vector<FlatChart>& charts) {
  for (FlatChart& chart : charts) {
    if (chart.corner_uv.rows() == 0) continue;
    const Eigen::Vector2d extent = chart.corner_uv.colwise().maxCoeff() - chart.corner_uv.colwise().minCoeff();
    const double across = extent.maxCoeff();
    if (across > 0 && across < 1) chart.corner_uv /= across;
  }
}

// Packs each face group on pages of its own and writes the placed UVs.
void pack_groups(const Mesh& mesh, const std::vector<int>& face_group, const std::vector<FlatChart>& charts,
                 const PackOptions& base, const RunControl& control, PipelineResult& result) {
  std::map<int, std::vector<int>> by_group;
  for (size_t c = 0; c < charts.size(); ++c)
    by_group[face_group.empty() ? 0 : face_group[charts[c].faces.front()]].push_back(static_cast<int>(c));
  double covered = 0, total = 0, scale = std::numeric_limits<double>::infinity();
  for (const auto& [group, members] : by_group) {
    std::vector<char> used(mesh.pages.size(), 0);
    std::vector<RowMatrixX2d> uv;
    for (int c : members) {
      uv.push_back(charts[c].corner_uv);
      for (int f : charts[c].faces) used[mesh.face_page[f]] = 1;
    }
    PackOptions options = base;
    // By default the output may hold as many texels as the input, times the
    // area scale the caller asked for.
    if (options.texel_budget <= 0 && options.fixed_page_size <= 0)
      options.texel_budget = static_cast<long long>(static_cast<double>(page_texels(mesh.pages, used)) *
                                                    options.density_scale * options.density_scale);
    const PackResult packed = pack_charts(uv, options, control);
    const int first_page = static_cast<int>(result.pages.size());
    for (size_t i = 0; i < members.size(); ++i) {
      const FlatChart& chart = charts[members[i]];
      for (size_t j = 0; j < chart.faces.size(); ++j) {
        const int f = chart.faces[j];
        result.corner_uv.middleRows(3 * f, 3) = packed.placed_uv[i].middleRows(3 * j, 3);
        result.face_page[f] = first_page + packed.chart_page[i];
      }
    }
    result.pages.insert(result.pages.end(), packed.pages.begin(), packed.pages.end());
    const double texels = static_cast<double>(page_texels(packed.pages, {}));
    covered += packed.efficiency * texels;
    total += texels;
    scale = std::min(scale, packed.scale);
  }
  result.report.packing_efficiency = total > 0 ? covered / total : 0;
  result.report.scale = by_group.empty() ? 1.0 : scale;
}

double median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

void summarize_energy(const std::vector<FlatChart>& charts, PipelineReport& report) {
  std::vector<double> before, after;
  for (const FlatChart& c : charts)
    if (!c.kept_original) before.push_back(c.energy_initial), after.push_back(c.energy_final);
  report.charts_solved = static_cast<int>(after.size());
  if (after.empty()) return;
  report.energy_initial_median = median(before);
  report.energy_median = median(after);
  report.energy_max = *std::max_element(after.begin(), after.end());
  const auto largest = std::max_element(charts.begin(), charts.end(), [](const FlatChart& a, const FlatChart& b) {
    return (a.factorize_seconds > 0 ? a.faces.size() : 0) < (b.factorize_seconds > 0 ? b.faces.size() : 0);
  });
  if (largest->factorize_seconds > 0) {
    report.largest_chart_faces = static_cast<int>(largest->faces.size());
    report.iteration_over_factorization = largest->iteration_seconds / largest->factorize_seconds;
  }
}

}  // namespace

PipelineResult defragment(const Mesh& welded, const std::vector<int>& face_group, const PipelineOptions& options,
                          const RunControl& control) {
  PipelineResult result;
  PipelineReport& report = result.report;
  StageClock clock(report);
  const MeshTopology welded_topology = build_topology(welded.triangles, welded.vertex_count());
  const ChartGraph welded_graph = build_chart_graph(welded, welded_topology, face_group);
  report.charts_before = welded_graph.chart_count();
  report.seam_before = seam_length_ratio(welded, welded_topology, welded.corner_uv, welded.face_page);
  std::vector<char> used(welded.pages.size(), 0);
  for (int f = 0; f < welded.face_count(); ++f)
    if (welded.face_page[f] >= 0) used[welded.face_page[f]] = 1;
  report.texels_before = page_texels(welded.pages, used);
  // Everything from here on works on the cut surface (see cut_mesh.hpp). Its
  // charts are the input's, except that a chart joined only across a winding
  // flip falls in two.
  const Mesh mesh = cut_internal_seams(welded, welded_topology, welded_graph);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
  const ChartGraph graph = build_chart_graph(mesh, topology, face_group);
  clock.lap("charts");
  control.progress("charts", 1.0);

  const Aggregation aggregation = aggregate_charts(mesh, topology, graph, options.aggregate, control);
  report.charts_aggregated = aggregation.chart_count();
  report.aggregate_stops = aggregation.stops;
  clock.lap("aggregate");

  std::vector<FlatChart> charts = flatten_all(mesh, topology, graph, aggregation, options.slim, control, report);
  enlarge_tiny_charts(charts);
  report.charts_after = static_cast<int>(charts.size());
  summarize_energy(charts, report);
  for (const FlatChart& c : charts)
    result.charts.push_back({static_cast<int>(c.faces.size()), !c.kept_original, c.energy_initial, c.energy_final});
  clock.lap("flatten");

  // Untextured faces keep their input UVs and page -1.
  result.corner_uv = mesh.corner_uv;
  result.face_page = Eigen::VectorXi::Constant(mesh.face_count(), -1);
  pack_groups(mesh, face_group, charts, options.pack, control, result);
  report.texels_after = page_texels(result.pages, {});
  clock.lap("pack");

  report.seam_after = seam_length_ratio(welded, welded_topology, result.corner_uv, result.face_page);
  control.progress("pack", 1.0);
  return result;
}

}  // namespace atlas
