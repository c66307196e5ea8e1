#include "charts/aggregate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <Eigen/Geometry>
#include <queue>
#include <unordered_map>

#include "charts/disk_merge.hpp"
#include "core/angle_defects.hpp"

namespace atlas {
namespace {

// A chart of at most this many faces may join any chart whatever the normal
// coherence of the union: it bends the union little, and left alone it keeps
// its whole border as seam.
constexpr size_t kGateFreeFaces = 100;

// max_chart_faces scales with the tessellation up to this factor: a chart of
// four times the faces already takes several times as long to flatten.
constexpr double kMaxCapScale = 4;

// What one cluster knows about its border with one neighbour.
struct Link {
  double length_3d = 0;
  double uv_self = 0;   // the shared border measured in this cluster's UVs
  double uv_other = 0;  // ... and in the neighbour's
  bool mergeable = true;
};

struct Cluster {
  double area_3d = 0, area_uv = 0, perimeter_3d = 0, perimeter_uv = 0;
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();  // sum over faces of A_f n_f
  double curvature = 0;  // sum of the angle defects at the vertices inside it
  unsigned version = 0;
  std::unordered_map<int, Link> links;
};

struct Candidate {
  bool island;     // islands go first (thesis 5.2.2)
  double weight;
  double area;     // tie-break: smaller first
  int a, b;
  unsigned version_a, version_b;
  bool partial;    // weight counts only the arc a partial merge welds
  bool curved;     // past a hemisphere: merges only if developable (checked when popped)
  // std::priority_queue pops the largest, so "greater" means "later".
  bool operator<(const Candidate& o) const {
    if (island != o.island) return !island;
    if (weight != o.weight) return weight > o.weight;
    return area > o.area;
  }
};

// Eq. 5.1, C1 the chart with the smaller UV area:
//   w_UV = A_uv(C1) * (1 - d_uv(C1->C2) / d_uv(C1)) * (d_uv(C1->C2) - d_uv(C2->C1))^2
// The middle factor vanishes for islands; the last favours borders of equal
// texel length on both sides, which stitch without resampling.
double weight_uv(const Cluster& c1, const Link& l) {
  const double share = c1.perimeter_uv > 0 ? std::min(1.0, l.uv_self / c1.perimeter_uv) : 1.0;
  const double mismatch = l.uv_self - l.uv_other;
  return c1.area_uv * (1.0 - share) * mismatch * mismatch;
}

// Eq. 5.2, C1 the chart with the smaller surface area:
//   w_3D = A_3D(C1) * (d_3D(C1C2) / d_3D(C1))^-1
double weight_surface(const Cluster& c1, const Link& l) {
  const double share = c1.perimeter_3d > 0 ? l.length_3d / c1.perimeter_3d : 1.0;
  return share > 0 ? c1.area_3d / share : std::numeric_limits<double>::infinity();
}

// The factor the gates' face counts scale by: textured faces per input
// chart with a neighbour / reference_chart_faces, from 1 to the face count
// (past it no gate changes). Charts with no neighbour are left out: a scan's
// debris (loose triangles and fragments, as phone scans keep) would
// otherwise count as the surface's tessellation.
double tessellation_scale(const ChartGraph& graph, double reference_chart_faces) {
  if (reference_chart_faces <= 0) return 1.0;
  std::vector<char> linked(graph.chart_count(), 0);
  for (const ChartAdjacency& adj : graph.adjacency) linked[adj.a] = linked[adj.b] = 1;
  const auto charts = std::count(linked.begin(), linked.end(), 1);
  const auto faces = std::count_if(graph.face_chart.begin(), graph.face_chart.end(),
                                   [&](int c) { return c >= 0 && linked[c]; });
  if (charts == 0) return 1.0;
  const double scale = static_cast<double>(faces) / charts / reference_chart_faces;
  return std::clamp(scale, 1.0, std::max(1.0, static_cast<double>(graph.face_chart.size())));
}

class Aggregator {
 public:
  Aggregator(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
             const AggregateOptions& options)
      : options_(options),
        graph_(graph),
        disks_(mesh, topology, graph.face_chart, graph.chart_count(), graph.self_seam, options.partial_merges,
               graph.holes),
        clusters_(graph.chart_count()) {
    const double scale = tessellation_scale(graph, options.reference_chart_faces);
    coherence_free_faces_ = static_cast<size_t>(options.coherence_free_faces * scale);
    gate_free_faces_ = static_cast<size_t>(kGateFreeFaces * scale);
    max_chart_faces_ = static_cast<size_t>(options.max_chart_faces * std::min(scale, kMaxCapScale));
    if (options.developable_curvature > 0) {
      defect_ = angle_defects(mesh);
      for (int v = 0; v < mesh.vertex_count(); ++v)
        if (const int c = disks_.cluster_inside(v); c >= 0) clusters_[c].curvature += defect_[v];
    }
    for (int f = 0; f < mesh.face_count(); ++f) {
      if (graph.face_chart[f] < 0) continue;
      const Eigen::Vector3d a = mesh.positions.row(mesh.triangles(f, 0)), b = mesh.positions.row(mesh.triangles(f, 1)),
                            c = mesh.positions.row(mesh.triangles(f, 2));
      clusters_[graph.face_chart[f]].normal_sum += 0.5 * (b - a).cross(c - a);
    }
    for (int c = 0; c < graph.chart_count(); ++c) {
      const ChartStats& s = graph.charts[c];
      clusters_[c].area_3d = s.area_3d;
      clusters_[c].area_uv = s.area_uv;
      clusters_[c].perimeter_3d = s.perimeter_3d;
      clusters_[c].perimeter_uv = s.perimeter_uv;
      total_area_3d_ += s.area_3d;
      total_area_uv_ += s.area_uv;
    }
    for (const ChartAdjacency& adj : graph.adjacency) {
      clusters_[adj.a].links[adj.b] = {adj.length_3d, adj.uv_length_a, adj.uv_length_b, adj.mergeable};
      clusters_[adj.b].links[adj.a] = {adj.length_3d, adj.uv_length_b, adj.uv_length_a, adj.mergeable};
    }
    alive_ = graph.chart_count();
  }

  void run(const RunControl& control) {
    for (int c = 0; c < static_cast<int>(clusters_.size()); ++c) push_links(c);
    const int start = alive_;
    while (!queue_.empty() && (options_.target_charts <= 0 || alive_ > options_.target_charts)) {
      const Candidate top = queue_.top();
      queue_.pop();
      if (clusters_[top.a].version != top.version_a || clusters_[top.b].version != top.version_b) continue;
      // The curvature costs a pass over the smaller chart: only for the
      // candidates that come up unchanged, not for every one pushed.
      if (top.curved && !developable(top.a, top.b)) continue;
      // Infeasible: dropped until one side changes, which pushes it again.
      if (const MergeCheck check = disks_.check_merge(top.a, top.b)) {
        // A partial merge removes less seam than its weight assumed: it
        // queues again at its real weight.
        if (!check.left_open.empty() && !top.partial) {
          push(top.a, top.b, check.open_length);
          continue;
        }
        collapse(top.a, top.b, check);
        if ((start - alive_) % 256 == 0) control.progress("aggregate", double(start - alive_) / start);
      }
    }
  }

  Aggregation result() {
    Aggregation out;
    out.stops = stops();
    out.kept_seam = disks_.seams();
    out.merges = merges_;
    std::vector<int> renumber(clusters_.size(), -1);
    out.face_chart.assign(graph_.face_chart.size(), -1);
    for (size_t f = 0; f < graph_.face_chart.size(); ++f) {
      if (graph_.face_chart[f] < 0) continue;
      const int cluster = disks_.cluster_of(static_cast<int>(f));
      if (renumber[cluster] < 0) renumber[cluster] = out.chart_count(), out.members.emplace_back();
      out.face_chart[f] = renumber[cluster];
    }
    std::vector<char> seen(graph_.chart_count(), 0);
    for (size_t f = 0; f < graph_.face_chart.size(); ++f) {
      const int original = graph_.face_chart[f];
      if (original < 0 || seen[original]) continue;
      seen[original] = 1;
      out.members[out.face_chart[f]].push_back(original);
    }
    return out;
  }

 private:
  // The options' limits on merging a and b, first one that refuses it.
  // Curved: past a hemisphere, so it merges only if developable(a, b).
  enum class Gate { Open, MinChartFraction, MaxChartFaces, NormalCoherence, Curved };
  Gate gate(int a, int b) const {
    const Cluster& ca = clusters_[a];
    const Cluster& cb = clusters_[b];
    const bool uv = options_.weighting == Weighting::UV;
    const double smaller = uv ? std::min(ca.area_uv, cb.area_uv) : std::min(ca.area_3d, cb.area_3d);
    if (smaller / (uv ? total_area_uv_ : total_area_3d_) >= options_.min_chart_fraction) return Gate::MinChartFraction;
    if (max_chart_faces_ > 0 && disks_.faces(a).size() + disks_.faces(b).size() > max_chart_faces_)
      return Gate::MaxChartFaces;
    const double area = ca.area_3d + cb.area_3d;
    const size_t fa = disks_.faces(a).size(), fb = disks_.faces(b).size();
    const bool small = fa + fb <= coherence_free_faces_ || std::min(fa, fb) <= gate_free_faces_;
    if (!small && area > 0 && (ca.normal_sum + cb.normal_sum).norm() < options_.min_normal_coherence * area)
      return defect_.empty() ? Gate::NormalCoherence : Gate::Curved;
    return Gate::Open;
  }

  bool developable(int a, int b) { return std::abs(union_curvature(a, b)) <= options_.developable_curvature; }

  // Sum of the angle defects inside the union of a and b (0 when
  // developable_curvature is off).
  double union_curvature(int a, int b) {
    if (defect_.empty()) return 0;
    return clusters_[a].curvature + clusters_[b].curvature + disks_.sum_inside_union(a, b, defect_);
  }

  AggregationStops stops() {
    AggregationStops s;
    for (int a = 0; a < static_cast<int>(clusters_.size()); ++a)
      for (const auto& [b, link] : clusters_[a].links) {
        if (b < a) continue;
        if (!link.mergeable) {
          ++s.non_manifold;
          continue;
        }
        switch (gate(a, b)) {
          case Gate::MinChartFraction: ++s.min_chart_fraction; continue;
          case Gate::MaxChartFaces: ++s.max_chart_faces; continue;
          case Gate::NormalCoherence: ++s.normal_coherence; continue;
          case Gate::Curved:
            if (!developable(a, b)) {
              ++s.normal_coherence;
              continue;
            }
            break;
          case Gate::Open: break;
        }
        switch (disks_.check_merge(a, b).refusal) {
          case MergeRefusal::None: ++s.feasible; break;
          case MergeRefusal::NonManifold: ++s.non_manifold; break;
          case MergeRefusal::NotDisk: ++s.not_disk; break;
        }
      }
    return s;
  }

  void push_links(int c) {
    for (const auto& [n, link] : clusters_[c].links)
      if (c < n && link.mergeable) push(c, n);
  }

  // open_length < 0: a full merge; else a partial one leaving that much 3D
  // length of the shared border open.
  void push(int a, int b, double open_length = -1) {
    const Gate g = gate(a, b);
    if (g != Gate::Open && g != Gate::Curved) return;
    const Cluster& ca = clusters_[a];
    const Cluster& cb = clusters_[b];
    const bool uv = options_.weighting == Weighting::UV;
    // C1 is the smaller chart in the measure the weighting uses.
    const bool a_small = uv ? ca.area_uv <= cb.area_uv : ca.area_3d <= cb.area_3d;
    const Cluster& small = a_small ? ca : cb;
    const Link link = welded_part(small.links.at(a_small ? b : a), open_length);
    const bool island = open_length < 0 && link.length_3d >= small.perimeter_3d * (1 - 1e-6);
    const double w = uv ? weight_uv(small, link) : weight_surface(small, link);
    queue_.push({island, w, uv ? small.area_uv : small.area_3d, a, b, ca.version, cb.version, open_length >= 0,
                 g == Gate::Curved});
  }

  // The part of a border that a merge leaving open_length of it open welds;
  // its UV lengths in proportion (open_length < 0: all of it).
  static Link welded_part(Link link, double open_length) {
    if (open_length <= 0 || link.length_3d <= 0) return link;
    const double kept = std::max(0.0, 1.0 - open_length / link.length_3d);
    link.length_3d *= kept, link.uv_self *= kept, link.uv_other *= kept;
    return link;
  }

  void collapse(int a, int b, const MergeCheck& check) {
    const double curvature = union_curvature(a, b);
    const int keep = disks_.merge(a, b, check), gone = keep == a ? b : a;
    merges_.push_back({keep, gone});
    Cluster& k = clusters_[keep];
    Cluster& g = clusters_[gone];
    const Link shared = welded_part(k.links.at(gone), check.left_open.empty() ? -1 : check.open_length);
    k.area_3d += g.area_3d;
    k.area_uv += g.area_uv;
    k.normal_sum += g.normal_sum;
    k.curvature = curvature;
    k.perimeter_3d += g.perimeter_3d - 2 * shared.length_3d;
    k.perimeter_uv += g.perimeter_uv - shared.uv_self - shared.uv_other;
    k.links.erase(gone);
    for (const auto& [n, link] : g.links) {
      if (n == keep) continue;
      Link& mine = k.links[n];
      mine.length_3d += link.length_3d;
      mine.uv_self += link.uv_self;
      mine.uv_other += link.uv_other;
      mine.mergeable = mine.mergeable && link.mergeable;
      auto& theirs = clusters_[n].links;
      theirs.erase(gone);
      theirs[keep] = {mine.length_3d, mine.uv_other, mine.uv_self, mine.mergeable};
    }
    g.links.clear();
    ++g.version;
    ++k.version;
    --alive_;
    for (const auto& [n, link] : k.links)
      if (link.mergeable) push(keep, n);
  }

  const AggregateOptions& options_;
  const ChartGraph& graph_;
  DiskClusters disks_;
  std::vector<double> defect_;  // per vertex, when developable_curvature > 0
  std::vector<Cluster> clusters_;
  std::priority_queue<Candidate> queue_;
  std::vector<std::pair<int, int>> merges_;
  double total_area_3d_ = 0, total_area_uv_ = 0;
  size_t coherence_free_faces_ = 0, gate_free_faces_ = 0, max_chart_faces_ = 0;  // scaled by tessellation_scale
  int alive_ = 0;
};

}  // namespace

Aggregation aggregate_charts(const Mesh& mesh, const MeshTopology& topology, const ChartGraph& graph,
                             const AggregateOptions& options, const RunControl& control) {
  Aggregator aggregator(mesh, topology, graph, options);
  aggregator.run(control);
  return aggregator.result();
}

}  // namespace atlas
