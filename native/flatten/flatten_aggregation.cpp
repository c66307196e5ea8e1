#include "flatten/flatten_aggregation.hpp"

#include <algorithm>
#include <atomic>
#include <numeric>
#include <utility>

#include "core/parallel_for.hpp"

namespace atlas {
namespace {

// The density rule (FlattenOptions::max_density_loss): every chart is first
// flattened allowing kStrictDensityLoss of its surface below half density, or
// kDensityAllowance of the whole surface (which spares splitting small
// pieces, closed scan debris above all). While the whole surface then loses
// more than its budget, the aggregated charts that lost most beyond the rule
// are flattened again under it without the allowance, then under a half and
// a quarter of it. A budget of 0 has no allowance and allows no loss at all,
// from the first flattening to the one round after it.
const double kStrictDensityLoss = FlattenOptions().max_density_loss;
constexpr double kDensityAllowance = 2e-4;
// Repair rounds when no loss is allowed: each round lifts the faces still
// squeezed, and every face a round lifts is one less reason to cut or split
// (bench/README.md, "Density repair before splits").
constexpr int kNoLossRepairRounds = 6;

// Faces of aggregated chart c: the faces of its original charts.
size_t faces_in_aggregate(const Aggregation& aggregation, const std::vector<std::vector<int>>& chart_faces, int c) {
  size_t n = 0;
  for (int m : aggregation.members[c]) n += chart_faces[m].size();
  return n;
}

// Flattens the aggregated charts `which` into pieces[c], stats[c], one chart
// per task, in the given order. Every worker reports progress, by faces
// flattened: time follows the face count, and thread 0 alone would stay
// silent while it flattens the largest chart, which comes first.
void flatten_charts(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                    const std::vector<std::vector<int>>& chart_faces, const Aggregation& aggregation,
                    const std::vector<int>& which, const FlattenOptions& options, const RunControl& control,
                    std::vector<std::vector<FlatChart>>& pieces, std::vector<FlattenStats>& stats) {
  auto faces_of = [&](int c) { return faces_in_aggregate(aggregation, chart_faces, c); };
  size_t total = 0;
  for (int c : which) total += faces_of(c);
  std::atomic<size_t> finished{0};
  parallel_for(static_cast<int>(which.size()), 1, [&](int i) {
    control.throw_if_cancelled();
    const int c = which[i];
    stats[c] = {};
    pieces[c] = flatten_without_overlap(mesh, topology, graph, chart_faces, aggregation.members[c],
                                        aggregation.merges, options, control, stats[c]);
    finished += faces_of(c);
    control.progress_from_worker("flatten", double(finished) / std::max<size_t>(total, 1));
  });
  control.throw_if_cancelled();
}

// The aggregated charts to flatten again under the rule `level`: those whose
// loss exceeds it, most excess first, until the rest of the loss fits
// `budget` (a share of the surface). Empty when it fits already.
std::vector<int> over_budget(const Mesh& mesh, const std::vector<std::vector<FlatChart>>& pieces, double level,
                             double budget) {
  double lost = 0, area = 0;
  std::vector<std::pair<double, int>> excess;
  for (size_t c = 0; c < pieces.size(); ++c) {
    double chart_lost = 0, chart_area = 0;
    for (const FlatChart& piece : pieces[c]) {
      chart_lost += piece.density_lost_area;
      for (int f : piece.faces) chart_area += mesh.area_3d(f);
    }
    lost += chart_lost, area += chart_area;
    if (chart_lost > level * chart_area) excess.push_back({chart_lost - level * chart_area, static_cast<int>(c)});
  }
  std::sort(excess.rbegin(), excess.rend());
  std::vector<int> out;
  for (const auto& [amount, c] : excess) {
    if (lost <= budget * area) break;
    lost -= amount;
    out.push_back(c);
  }
  return out;
}

// The flattening of one round: SLIM as given, up to `level` of a chart's
// surface and `allowance` of 3D area below half density.
FlattenOptions round_rule(const SlimOptions& slim, double level, double allowance, int relief_cuts) {
  FlattenOptions rule;
  rule.slim = slim;
  rule.max_density_loss = level;
  rule.density_loss_allowance = allowance;
  rule.relief_cuts = relief_cuts;
  return rule;
}

double textured_area(const Mesh& mesh, const ChartGraph& graph) {
  double area = 0;
  for (int f = 0; f < mesh.face_count(); ++f)
    if (graph.face_chart[f] >= 0) area += mesh.area_3d(f);
  return area;
}

}  // namespace

FlattenedAggregation flatten_aggregation(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                                         const Aggregation& aggregation, const AggregationFlattenOptions& options,
                                         const RunControl& control) {
  const auto chart_faces = faces_of_charts(graph);
  std::vector<int> order(aggregation.chart_count());
  std::iota(order.begin(), order.end(), 0);
  auto faces_in = [&](int c) { return faces_in_aggregate(aggregation, chart_faces, c); };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return faces_in(a) > faces_in(b); });

  std::vector<std::vector<FlatChart>> pieces(order.size());
  std::vector<FlattenStats> stats(order.size());
  const double budget = options.density_loss_budget;
  const double allowance = budget > 0 ? kDensityAllowance * textured_area(mesh, graph) : 0.0;
  // A chart losing more than the budget would be flattened again or split
  // below: the density repair, which changes no seam, goes first.
  SlimOptions slim = options.slim;
  slim.repair_share = std::min(slim.repair_share, budget);
  if (budget == 0) slim.repair_rounds = std::max(slim.repair_rounds, kNoLossRepairRounds);
  // With no budget the first flattening already allows no loss: under the
  // looser rule every chart that lost any would be solved twice.
  const double first_level = budget == 0 ? 0.0 : kStrictDensityLoss;
  flatten_charts(mesh, topology, graph, chart_faces, aggregation, order,
                 round_rule(slim, first_level, allowance, options.relief_cuts), control, pieces, stats);
  FlattenedAggregation out;
  const std::vector<double> levels = budget == 0 ? std::vector<double>{0.0}
      : std::vector<double>{kStrictDensityLoss, kStrictDensityLoss / 2, kStrictDensityLoss / 4};
  for (double level : levels) {
    std::vector<int> again = over_budget(mesh, pieces, level, budget);
    std::sort(again.begin(), again.end(), [&](int a, int b) { return faces_in(a) > faces_in(b); });
    flatten_charts(mesh, topology, graph, chart_faces, aggregation, again,
                   round_rule(slim, level, 0, options.relief_cuts), control, pieces, stats);
    out.reflattened += static_cast<int>(again.size());
  }
  for (size_t c = 0; c < pieces.size(); ++c) {
    out.stats += stats[c];
    for (auto& piece : pieces[c]) out.charts.push_back(std::move(piece));
  }
  return out;
}

}  // namespace atlas
