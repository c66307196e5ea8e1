#include "pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <map>
#include <numeric>
#include <sstream>
#include <string>
#include <tuple>

#include "core/corners.hpp"
#include "core/geometry.hpp"
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

// The graph with no merge offered to an original chart that keeps a handle:
// a merged chart holding it could only be split back.
ChartGraph without_merges_of_handles(const Mesh& mesh, const MeshTopology& topology, ChartGraph graph) {
  const std::vector<char> handle =
      charts_with_handles(mesh, topology, graph, faces_of_charts(graph));
  for (ChartAdjacency& adj : graph.adjacency)
    if (handle[adj.a] || handle[adj.b]) adj.mergeable = false;
  return graph;
}

// The seams the refinement must keep: those the graph kept, plus every edge
// inside a flattened chart whose two faces disagree in UV there (the cuts of
// cut_to_disk and relief_cut).
std::vector<char> seams_in_flat_charts(const Mesh& mesh, const MeshTopology& topology, std::vector<char> seams,
                                       const std::vector<FlatChart>& charts) {
  RowMatrixX2d uv = RowMatrixX2d::Zero(3 * static_cast<Eigen::Index>(mesh.face_count()), 2);
  std::vector<int> label(mesh.face_count(), -1);
  for (size_t c = 0; c < charts.size(); ++c)
    for (size_t j = 0; j < charts[c].faces.size(); ++j) {
      label[charts[c].faces[j]] = static_cast<int>(c);
      uv.middleRows(3 * charts[c].faces[j], 3) = charts[c].corner_uv.middleRows(3 * j, 3);
    }
  const std::vector<char> cut =
      self_seams(topology, mesh.triangles, uv, Eigen::VectorXi::Zero(mesh.face_count()), label);
  for (size_t e = 0; e < seams.size(); ++e) seams[e] = seams[e] || cut[e];
  return seams;
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

// Flattened charts come out at arbitrary angles; turned to their smallest
// bounding box they pack tighter. Kept charts keep their angle, so that the
// packer moves them by whole texels and the bake copies their texels.
void turn_solved_charts(std::vector<FlatChart>& charts) {
  parallel_for(static_cast<int>(charts.size()), 8, [&](int c) {
    if (!charts[c].kept_original) charts[c].corner_uv = turned_to_smallest_box(charts[c].corner_uv);
  });
}

// Texels per unit of surface length of the charts: sqrt(texel area / 3D area).
double texel_density(const Mesh& mesh, const std::vector<FlatChart>& charts, const std::vector<int>& members) {
  double texel_area = 0, surface_area = 0;
  for (int c : members) {
    const RowMatrixX2d& uv = charts[c].corner_uv;
    for (size_t j = 0; j < charts[c].faces.size(); ++j) {
      texel_area += std::abs(signed_area(uv.row(3 * j), uv.row(3 * j + 1), uv.row(3 * j + 2)));
      surface_area += mesh.area_3d(charts[c].faces[j]);
    }
  }
  return surface_area > 0 && texel_area > 0 ? std::sqrt(texel_area / surface_area) : 0;
}

// pack_charts with the budget derived from the source texels: a refusal then
// names the input that causes it, as the user never set texel_budget.
PackResult pack_in_source_budget(const std::vector<RowMatrixX2d>& uv, const PackOptions& options,
                                 long long source_texels, const RunControl& control) {
  std::ostringstream msg;
  msg << "the source texture of these faces holds only " << source_texels << " texels";
  if (options.texel_budget < kSideQuantum * kSideQuantum)
    throw InputError(msg.str() + ", too few for any output page (" + std::to_string(kSideQuantum) + "x" +
                     std::to_string(kSideQuantum) + " at least): use a larger image, a higher density_scale "
                     "or a fixed_page_size");
  try {
    return pack_charts(uv, options, control);
  } catch (const ChartsDoNotFit&) {
    msg << ", too few for its " << uv.size() << " charts with "
        << padding_for_side(options, budget_page_side(options))
        << " texels of padding around each (charts collapsed to points or slivers need a texel or more "
           "each): use a smaller padding, a higher density_scale or a fixed_page_size";
    throw InputError(msg.str());
  }
}

// With texels_at_most_input and no texel_budget of the caller's, each group's
// budget is its input's texels (pack_in_source_budget names it on refusal).
bool budget_from_source(const PipelineOptions& pipeline) {
  return pipeline.texels_at_most_input && pipeline.pack.texel_budget <= 0;
}

// The input's texels on the `used` pages, at the density options ask for.
double wanted_texels(const Mesh& mesh, const std::vector<char>& used, const PackOptions& options) {
  return static_cast<double>(page_texels(mesh.pages, used)) * options.density_scale * options.density_scale;
}

// The pack options for one face group: its density, and unless the page is
// fixed, as many pages as the input used (or as hold its texels) and, with
// texels_at_most_input, the input's texels as the budget. used[p]: the group
// has faces on input page p.
PackOptions group_pack_options(const Mesh& mesh, const std::vector<FlatChart>& charts, const std::vector<int>& members,
                               const std::vector<char>& used, const PipelineOptions& pipeline) {
  PackOptions options = pipeline.pack;
  if (pipeline.texels_per_unit > 0) {
    const double density = texel_density(mesh, charts, members);
    if (density > 0) options.density_scale = pipeline.texels_per_unit / density;
  }
  if (options.fixed_page_size > 0) return options;
  const double wanted = wanted_texels(mesh, used, options);
  // As many pages as the input used, or as many of the largest allowed side
  // (max_page_size rounded down to the page kind) as hold its texels.
  const double side = largest_allowed_side(options.max_page_size, options.page_sides);
  const double max_page = side * side;
  if (options.max_pages <= 0)
    options.max_pages = static_cast<int>(std::min<double>(
        4096, std::max<double>(static_cast<double>(std::count(used.begin(), used.end(), 1)),
                               std::ceil(wanted / max_page))));
  options.max_pages = std::max(1, options.max_pages);
  // A density far beyond any page makes `wanted` overflow: max_pages limits it then.
  if (budget_from_source(pipeline)) options.texel_budget = static_cast<long long>(std::min(wanted, 4e18));
  return options;
}

// Writes the placed UVs and pages of one group's charts (members) into result.
void write_placed(const std::vector<FlatChart>& charts, const std::vector<int>& members, const PackResult& packed,
                  PipelineResult& result) {
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
  result.page_padding.resize(result.pages.size(), packed.padding);
}

// How much larger than its input's texels (at the density asked for) a
// group's pages may come out before fit_cut_seam's cuts are made: a tenth
// more texture costs less than the charts and seam that would save it.
constexpr double kOutgrowth = 1.1;

// Packs each face group on pages of its own and writes the placed UVs.
// Returns whether some group's charts were shrunk or, on pages not fixed,
// outgrew its input's texels by more than kOutgrowth.
bool pack_groups(const Mesh& mesh, const std::vector<int>& face_group, const std::vector<FlatChart>& charts,
                 const PipelineOptions& pipeline, const RunControl& control, PipelineResult& result) {
  std::map<int, std::vector<int>> by_group;
  for (size_t c = 0; c < charts.size(); ++c)
    by_group[face_group.empty() ? 0 : face_group[charts[c].faces.front()]].push_back(static_cast<int>(c));
  double covered = 0, total = 0, scale = std::numeric_limits<double>::infinity();
  bool outgrew = false;
  result.report.shrunk = false;
  for (const auto& [group, members] : by_group) {
    std::vector<char> used(mesh.pages.size(), 0);
    std::vector<RowMatrixX2d> uv;
    for (int c : members) {
      uv.push_back(charts[c].corner_uv);
      for (int f : charts[c].faces) used[mesh.face_page[f]] = 1;
    }
    const PackOptions options = group_pack_options(mesh, charts, members, used, pipeline);
    const PackResult packed = budget_from_source(pipeline) && options.fixed_page_size <= 0
                                  ? pack_in_source_budget(uv, options, page_texels(mesh.pages, used), control)
                                  : pack_charts(uv, options, control);
    write_placed(charts, members, packed, result);
    const double texels = static_cast<double>(page_texels(packed.pages, {}));
    covered += packed.efficiency * texels;
    total += texels;
    scale = std::min(scale, packed.scale);
    result.report.shrunk |= packed.shrunk;
    const bool grown = options.fixed_page_size <= 0 && texels > kOutgrowth * wanted_texels(mesh, used, options);
    outgrew |= packed.shrunk || grown;
  }
  result.report.packing_efficiency = total > 0 ? covered / total : 0;
  result.report.scale = by_group.empty() ? 1.0 : scale;
  return outgrew;
}

// Sign of the exact determinant of face f's corners as float32 stores them,
// v either as is (Blender, OBJ) or, after that, as 1 - v (glTF): when the
// two disagree, the one against `expected` wins.
int stored_winding(const PipelineResult& result, int f, double expected) {
  const PageSize& page = result.pages[result.face_page[f]];
  int worst = expected > 0 ? 1 : -1;
  for (bool flipped_v : {false, true}) {
    Eigen::Vector2d corner[3];
    for (int k = 0; k < 3; ++k) {
      const double u = static_cast<float>(result.corner_uv(3 * f + k, 0));
      const float v = static_cast<float>(result.corner_uv(3 * f + k, 1));  // as Blender holds it
      const double stored_v = flipped_v ? 1.0 - static_cast<float>(1.0 - v) : v;
      corner[k] = {u * page.width, stored_v * page.height};
    }
    const double area = signed_area(corner[0], corner[1], corner[2]);
    const int winding = area > 0 ? 1 : area < 0 ? -1 : 0;
    if (winding * expected < 0) worst = winding;
  }
  return worst;
}

// Faces whose stored winding is the opposite of their chart's leave it, each
// as a chart of its own: its 3D triangle laid flat at its original texel
// density, and at least a texel across. Returns how many left.
int detach_turned_faces(const Mesh& mesh, const PipelineResult& result, std::vector<FlatChart>& charts) {
  std::vector<FlatChart> detached;
  for (FlatChart& chart : charts) {
    double winding = 0;  // of the placed chart, as packed
    for (int f : chart.faces)
      winding +=
          signed_area(result.corner_uv.row(3 * f), result.corner_uv.row(3 * f + 1), result.corner_uv.row(3 * f + 2));
    if (chart.faces.size() < 2 || winding == 0) continue;
    // The last face stays: a chart is never emptied.
    for (size_t j = 0; j < chart.faces.size() && chart.faces.size() > 1; ++j) {
      const int f = chart.faces[j];
      if (stored_winding(result, f, winding) * winding >= 0) continue;
      const Eigen::Vector3d a = mesh.positions.row(mesh.triangles(f, 0)), b = mesh.positions.row(mesh.triangles(f, 1));
      const double area = mesh.area_3d(f);
      if ((b - a).norm() <= 0 || area <= 0) continue;
      FlatChart lone;
      lone.faces = {f};
      lone.corner_uv.resize(3, 2);
      write_flattened(a, b, mesh.positions.row(mesh.triangles(f, 2)), 1.0, lone.corner_uv);
      const double density = std::sqrt(std::abs(mesh.signed_area_uv(f)) / area);  // texels per unit length
      lone.corner_uv *= density > 0 ? density : 1.0;
      detached.push_back(std::move(lone));
      // Out of its chart: the last face takes its rows.
      const size_t last = chart.faces.size() - 1;
      chart.faces[j] = chart.faces[last];
      chart.corner_uv.middleRows(3 * j, 3) = chart.corner_uv.middleRows(3 * last, 3);
      chart.faces.pop_back();
      chart.corner_uv.conservativeResize(3 * static_cast<Eigen::Index>(last), 2);
      --j;
    }
  }
  enlarge_tiny_charts(detached);
  const int count = static_cast<int>(detached.size());
  for (FlatChart& lone : detached) charts.push_back(std::move(lone));
  return count;
}

double total_area(const Mesh& mesh) {
  double area = 0;
  for (int f = 0; f < mesh.face_count(); ++f) area += mesh.area_3d(f);
  return area;
}

// The cuts for packing see the charts at the scale the packer will use:
// density_scale, or texels_per_unit over the charts' mean density (per
// group the packer's differs a little; a fixed page size scales them later).
PackingCutOptions packing_cut_options(const Mesh& mesh, const std::vector<FlatChart>& charts,
                                      const PipelineOptions& options) {
  PackingCutOptions cut;
  cut.scale = options.pack.density_scale;
  if (options.texels_per_unit > 0) {
    std::vector<int> all(charts.size());
    std::iota(all.begin(), all.end(), 0);
    const double density = texel_density(mesh, charts, all);
    if (density > 0) cut.scale = options.texels_per_unit / density;
  }
  cut.padding = options.pack.padding;
  cut.seam_budget = options.packing_cut_seam * std::sqrt(total_area(mesh));
  return cut;
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

// PipelineReport::opposed_winding_edges of the mesh: between two textured
// faces of one group, the edges a chart could otherwise grow across.
int opposed_winding_edges(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                          const std::vector<int>& face_group) {
  int count = 0;
  for (int e = 0; e < topology.edge_count(); ++e) {
    if (topology.edge_valence(e) != 2) continue;
    const int ci = topology.edge_corners[topology.edge_offsets[e]];
    const int cj = topology.edge_corners[topology.edge_offsets[e] + 1];
    const int fi = ci / 3, fj = cj / 3;
    if (graph.face_chart[fi] < 0 || graph.face_chart[fj] < 0 || mesh.repeats_vertex(fi) || mesh.repeats_vertex(fj) ||
        (!face_group.empty() && face_group[fi] != face_group[fj]))
      continue;
    count += corner_vertex(mesh.triangles, ci) == corner_vertex(mesh.triangles, cj);  // run the same way
  }
  return count;
}

// The input's chart count, seam length, texels (of the pages its textured
// faces use) and opposed windings, into report.
void report_input(const Mesh& welded, const MeshTopology& topology, const ChartGraph& graph,
                  const std::vector<int>& face_group, PipelineReport& report) {
  report.charts_before = graph.chart_count();
  report.opposed_winding_edges = opposed_winding_edges(welded, topology, graph, face_group);
  report.seam_before = seam_length_ratio(welded, topology, welded.corner_uv, welded.face_page);
  std::vector<char> used(welded.pages.size(), 0);
  for (int f = 0; f < welded.face_count(); ++f)
    if (welded.face_page[f] >= 0) used[welded.face_page[f]] = 1;
  report.texels_before = page_texels(welded.pages, used);
}

// The flattened charts of mesh (the cut surface of welded) made ready to
// pack: strips of faces along their borders, then single faces, moved
// between them where that shortens the seams (graph_seams,
// per edge, and the cuts of the flattening stay), tiny charts enlarged and
// solved ones turned to their smallest box. What moved goes into report.
void refine_charts(const Mesh& welded, const Mesh& mesh, const MeshTopology& topology,
                   const std::vector<char>& graph_seams, const std::vector<int>& face_group,
                   const Polygons& polygons, const RefineOptions& options, std::vector<FlatChart>& charts,
                   PipelineReport& report) {
  // Before tiny charts are enlarged: the refinement compares texel areas.
  const std::vector<char> kept_seams = seams_in_flat_charts(mesh, topology, graph_seams, charts);
  const RefineInput input{mesh, topology, kept_seams, face_group, options, polygons};
  const RefineStats strips = straighten_borders(input, charts);
  const RefineStats teeth = refine_seams(input, charts);
  report.refine_faces_moved = strips.faces_moved + teeth.faces_moved;
  report.refine_seam_removed = per_sqrt_area(strips.seam_removed_3d + teeth.seam_removed_3d, welded);
  enlarge_tiny_charts(charts);
  turn_solved_charts(charts);
}

// Packs the charts into result. Untextured faces keep their input UVs and
// page -1. A face whose winding float32 storage turns over becomes a chart of
// its own and all is packed again (rare: slivers a hundredth of a texel high).
// Returns what pack_groups does.
bool pack_keeping_windings(const Mesh& mesh, const std::vector<int>& face_group, const PipelineOptions& options,
                           const RunControl& control, std::vector<FlatChart>& charts, PipelineResult& result) {
  for (;;) {
    result.corner_uv = mesh.corner_uv;
    result.face_page = Eigen::VectorXi::Constant(mesh.face_count(), -1);
    result.pages.clear();
    result.page_padding.clear();
    const bool outgrew = pack_groups(mesh, face_group, charts, options, control, result);
    const int detached = detach_turned_faces(mesh, result, charts);
    if (detached == 0) return outgrew;
    result.report.faces_detached += detached;
  }
}

// Whether packing a keeps more of the density asked for than packing b or,
// as much, takes fewer texels.
bool packs_better(const PipelineResult& a, const PipelineResult& b) {
  if (a.report.scale != b.report.scale) return a.report.scale > b.report.scale;
  return page_texels(a.pages, {}) < page_texels(b.pages, {});
}

// Packs the charts into result; where they outgrow the input (see
// pack_groups), cuts more of them for packing, up to fit_cut_seam in all
// (cuts: those made so far, updated), and packs them again, keeping the cuts
// only if they pack better: the cuts judge the charts by their boxes, which
// the packer may fill as well either way.
void pack_within_input(const Mesh& mesh, const MeshTopology& topology, const std::vector<int>& face_group,
                       const PipelineOptions& options, const RunControl& control, std::vector<FlatChart>& charts,
                       PackingCutStats& cuts, PipelineResult& result) {
  if (!pack_keeping_windings(mesh, face_group, options, control, charts, result)) return;
  PackingCutOptions more = packing_cut_options(mesh, charts, options);
  more.seam_budget = options.fit_cut_seam * std::sqrt(total_area(mesh)) - cuts.seam_added_3d;
  if (!(more.seam_budget > 0)) return;
  std::vector<FlatChart> uncut = charts;
  const PackingCutStats added = cut_for_packing(mesh, topology, more, charts, control);
  if (added.cuts == 0) return;
  PipelineResult whole = result;
  pack_keeping_windings(mesh, face_group, options, control, charts, result);
  if (!packs_better(result, whole)) {
    charts = std::move(uncut);
    result = std::move(whole);
    return;
  }
  cuts.cuts += added.cuts;
  cuts.seam_added_3d += added.seam_added_3d;
  result.report.cut_to_fit = true;
}

// Into result: each face's chart (-1 for none; face_count faces), and per chart
// its face count, whether it was solved and its energies.
void record_charts(const std::vector<FlatChart>& charts, int face_count, PipelineResult& result) {
  result.face_chart = Eigen::VectorXi::Constant(face_count, -1);
  for (const FlatChart& c : charts) {
    for (int f : c.faces) result.face_chart[f] = static_cast<int>(result.charts.size());
    result.charts.push_back({static_cast<int>(c.faces.size()), !c.kept_original, c.energy_initial, c.energy_final});
  }
}

PipelineResult defragment_distinct(const Mesh& welded, const std::vector<int>& face_group,
                                   const std::vector<int>& face_polygon, const PipelineOptions& options,
                                   const RunControl& control) {
  PipelineResult result;
  PipelineReport& report = result.report;
  StageClock clock(report);
  const MeshTopology welded_topology = build_topology(welded.triangles, welded.vertex_count());
  const ChartGraph welded_graph = build_chart_graph(welded, welded_topology, face_group);
  report_input(welded, welded_topology, welded_graph, face_group, report);
  // Everything from here on works on the cut surface (see cut_mesh.hpp). Its
  // charts are the input's, except that a chart joined only across a winding
  // flip falls in two.
  const Mesh mesh = cut_internal_seams(welded, welded_topology, welded_graph);
  const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count(), face_polygon);
  ChartGraph graph = without_merges_of_handles(mesh, topology, build_chart_graph(mesh, topology, face_group));
  graph.holes = mesh_holes(mesh, topology, on_holes(mesh_holes(welded, welded_topology), welded_topology, topology));
  clock.lap("charts");
  control.progress("charts", 1.0);

  const Aggregation aggregation = aggregate_charts(mesh, topology, graph, options.aggregate, control);
  report.charts_aggregated = aggregation.chart_count();
  report.aggregate_stops = aggregation.stops;
  clock.lap("aggregate");

  // The flattening keeps the arcs partial merges left open as seams.
  ChartGraph flat_graph = graph;
  flat_graph.self_seam = aggregation.kept_seam;
  AggregationFlattenOptions rule;
  rule.slim = options.slim;
  rule.density_loss_budget = options.density_loss_budget;
  rule.relief_cuts = options.relief_cuts;
  FlattenedAggregation flat = flatten_aggregation(mesh, topology, flat_graph, aggregation, rule, control);
  report.flatten = flat.stats;
  report.density_reflattened = flat.reflattened;
  std::vector<FlatChart> charts = std::move(flat.charts);
  clock.lap("flatten");
  refine_charts(welded, mesh, topology, flat_graph.self_seam, face_group, Polygons(face_polygon), options.refine,
                charts, report);
  relax_squeezed_borders(mesh, graph, options.slim.relax, charts);
  clock.lap("refine");

  PackingCutStats cuts = cut_for_packing(mesh, topology, packing_cut_options(mesh, charts, options), charts, control);
  clock.lap("cut");

  pack_within_input(mesh, topology, face_group, options, control, charts, cuts, result);
  report.packing_cuts = cuts.cuts;
  report.packing_cut_seam = per_sqrt_area(cuts.seam_added_3d, welded);
  report.texels_after = page_texels(result.pages, {});
  report.charts_after = static_cast<int>(charts.size());
  summarize_energy(charts, report);
  record_charts(charts, mesh.face_count(), result);
  clock.lap("pack");

  report.seam_after = seam_length_ratio(welded, welded_topology, result.corner_uv, result.face_page);
  control.progress("pack", 1.0);
  return result;
}

// The result on the kept faces of dup spread over all faces of mesh: a copy
// takes the new UVs and page of the face it repeats, corner for corner
// (an untextured copy keeps its own UVs).
PipelineResult with_copies(PipelineResult kept, const Mesh& mesh, const DuplicateFaces& dup) {
  std::vector<int> kept_index(mesh.face_count(), -1);
  for (size_t i = 0; i < dup.kept.size(); ++i) kept_index[dup.kept[i]] = static_cast<int>(i);
  PipelineResult out = std::move(kept);
  RowMatrixX2d uv = mesh.corner_uv;
  Eigen::VectorXi page = Eigen::VectorXi::Constant(mesh.face_count(), -1);
  Eigen::VectorXi chart = Eigen::VectorXi::Constant(mesh.face_count(), -1);
  for (int f = 0; f < mesh.face_count(); ++f) {
    const int i = kept_index[dup.original[f]];
    page[f] = out.face_page[i];
    chart[f] = out.face_chart[i];
    if (page[f] < 0) continue;
    for (int k = 0; k < 3; ++k) uv.row(3 * f + k) = out.corner_uv.row(3 * i + (dup.shift[f] + k) % 3);
  }
  out.corner_uv = std::move(uv);
  out.face_page = std::move(page);
  out.face_chart = std::move(chart);
  out.report.duplicate_faces = dup.copies();
  return out;
}

}  // namespace

PipelineResult defragment(const Mesh& welded, const std::vector<int>& face_group, const std::vector<int>& face_polygon,
                          const PipelineOptions& options, const RunControl& control) {
  require_face_groups(face_group, welded.face_count());
  if (!face_polygon.empty() && static_cast<int>(face_polygon.size()) != welded.face_count())
    throw InputError("face_polygon must hold one polygon per triangle");
  const DuplicateFaces dup = find_duplicate_faces(welded, face_group);
  if (dup.copies() == 0) return defragment_distinct(welded, face_group, face_polygon, options, control);
  auto kept = [&](const std::vector<int>& per_face) {
    std::vector<int> out;
    if (!per_face.empty())
      for (int f : dup.kept) out.push_back(per_face[f]);
    return out;
  };
  return with_copies(defragment_distinct(mesh_of_faces(welded, dup.kept), kept(face_group), kept(face_polygon),
                                         options, control),
                     welded, dup);
}

}  // namespace atlas
