#include "flatten/packing_cuts.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <optional>
#include <utility>

#include "core/geometry.hpp"
#include "core/parallel_for.hpp"
#include "core/union_find.hpp"
#include "flatten/disk_boundary.hpp"
#include "pack/chart_raster.hpp"
#include "pack/smallest_box_turn.hpp"

namespace atlas {
namespace {

// Chords are looked for on a grid of at most this many cells a side: a
// chart's shape at that resolution is enough to find where its box shrinks,
// and each chord costs a flood fill of the smaller side it leaves.
constexpr int kGridCells = 64;
// Chords tried per axis, evenly spaced.
constexpr int kLinesPerAxis = 32;
// Best chords kept per chart: the next is tried when one cannot be made.
constexpr int kChordsKept = 4;

// A chart's conservative raster on square cells of `cell` page texels (the
// packer's scale) a side.
struct CellGrid {
  int width = 0, height = 0;
  // Page texels a side, a whole number in a double: a chart far wider than
  // any page (a texel density beyond it, which the packer then shrinks)
  // would overflow an int.
  double cell = 1;
  std::vector<char> set;  // row-major
  // Chart UV of the grid's corner (0, 0), and chart UV units per cell.
  Eigen::RowVector2d origin = Eigen::RowVector2d::Zero();
  double step = 1.0;

  bool at(int x, int y) const { return set[static_cast<size_t>(y) * width + x] != 0; }
};

CellGrid cell_grid(const RowMatrixX2d& uv, double scale) {
  const double extent = scale * (uv.colwise().maxCoeff() - uv.colwise().minCoeff()).maxCoeff();
  CellGrid grid;
  // extent + 2: a conservative raster spans up to two texels more than the chart.
  grid.cell = std::max(1.0, std::ceil((extent + 2) / kGridCells));
  // Rasterised straight onto the cells: a cell is set when the chart
  // covers any part of it, as it would any of its texels.
  grid.step = grid.cell / scale;
  RowMatrixX2d corners = uv / grid.step;
  const Eigen::RowVector2d shift = corners.colwise().minCoeff().array().floor();
  corners.rowwise() -= shift;
  const TexelMask mask = rasterize_chart(corners);
  grid.width = mask.width;
  grid.height = mask.height;
  grid.set.assign(static_cast<size_t>(grid.width) * grid.height, 0);
  for (int y = 0; y < mask.height; ++y)
    for (int x = 0; x < mask.width; ++x) grid.set[static_cast<size_t>(y) * grid.width + x] = mask.test(x, y);
  grid.origin = (Eigen::RowVector2d(mask.origin_x, mask.origin_y) + shift) * grid.step;
  return grid;
}

CellGrid transposed(const CellGrid& grid) {
  CellGrid out = grid;
  std::swap(out.width, out.height);
  out.origin = Eigen::RowVector2d(grid.origin.y(), grid.origin.x());
  for (int y = 0; y < grid.height; ++y)
    for (int x = 0; x < grid.width; ++x) out.set[static_cast<size_t>(x) * out.width + y] = grid.at(x, y);
  return out;
}

// A straight cut across a chart, in chart UV: where coordinate `axis` equals
// `line`, from `from` to `to` along the other coordinate.
struct Chord {
  int axis = 0;
  double line = 0, from = 0, to = 0;
  double saving = 0;  // padded box texels saved
  double length = 0;  // page texels
  double cell = 0;    // chart UV units per cell of the grid it was found on
};

struct Box {
  int x0 = 1 << 30, y0 = 1 << 30, x1 = -1, y1 = -1;  // cells, inclusive
  void add(int x, int y) {
    x0 = std::min(x0, x), y0 = std::min(y0, y), x1 = std::max(x1, x), y1 = std::max(y1, y);
  }
  bool empty() const { return x1 < x0; }
};

// Page texels of a box of cells grown by the padding on every side.
double padded_box_texels(const Box& box, double cell, int padding) {
  if (box.empty()) return 0;
  return ((box.x1 - box.x0 + 1) * cell + 2.0 * padding) * ((box.y1 - box.y0 + 1) * cell + 2.0 * padding);
}

// Set cells per row and per column of a grid.
struct GridCounts {
  std::vector<int> rows, columns;
  Box box;
};

GridCounts count_cells(const CellGrid& grid) {
  GridCounts counts{std::vector<int>(grid.height, 0), std::vector<int>(grid.width, 0), {}};
  for (int y = 0; y < grid.height; ++y)
    for (int x = 0; x < grid.width; ++x)
      if (grid.at(x, y)) ++counts.rows[y], ++counts.columns[x], counts.box.add(x, y);
  return counts;
}

// Boxes of the cells left of column x and right of it, for every x.
struct ColumnSpans {
  std::vector<Box> before, after;  // before[x]: columns < x; after[x]: columns > x
};

ColumnSpans column_spans(const CellGrid& grid) {
  const int w = grid.width;
  std::vector<Box> column(w);
  for (int y = 0; y < grid.height; ++y)
    for (int x = 0; x < w; ++x)
      if (grid.at(x, y)) column[x].add(x, y);
  ColumnSpans spans{std::vector<Box>(w), std::vector<Box>(w)};
  auto merged = [](Box a, const Box& b) {
    if (!b.empty()) a.add(b.x0, b.y0), a.add(b.x1, b.y1);
    return a;
  };
  for (int x = 1; x < w; ++x) spans.before[x] = merged(spans.before[x - 1], column[x - 1]);
  for (int x = w - 2; x >= 0; --x) spans.after[x] = merged(spans.after[x + 1], column[x + 1]);
  return spans;
}

// Scratch of the flood fills, kept from one chord to the next.
struct FloodScratch {
  std::vector<int> mark;  // per cell: 3 * fill + 0 or 1 (the side that reached it) or 2 (the chord)
  int fill = 0;
  std::array<std::vector<int>, 2> stack, reached;
  std::vector<int> rows, columns;  // cells of the smaller side per row and column
};

// The boxes of the two sides of the chord (column x, rows [y0, y1)) of the
// grid: the cells reached from either side of it without crossing it, and
// the others. Both sides are flooded a cell at a time in turn, so that the
// smaller one, once complete, ends the search: a branch cut off costs its
// own size. Nothing when the sides meet (the chord does not part the
// chart) or one side is empty.
std::optional<std::array<Box, 2>> chord_sides(const CellGrid& grid, const GridCounts& total, int x, int y0, int y1,
                                              FloodScratch& s) {
  const int w = grid.width, h = grid.height, base = 3 * ++s.fill;
  for (int y = y0; y < y1; ++y) s.mark[static_cast<size_t>(y) * w + x] = base + 2;
  for (int side = 0; side < 2; ++side) {
    s.stack[side].clear();
    s.reached[side].clear();
    const int cx = side == 0 ? x - 1 : x + 1;
    for (int y = y0; y < y1; ++y)
      if (grid.at(cx, y)) s.stack[side].push_back(y * w + cx), s.mark[static_cast<size_t>(y) * w + cx] = base + side;
  }
  if (s.stack[0].empty() || s.stack[1].empty()) return std::nullopt;
  int done = -1;
  while (done < 0) {
    for (int side = 0; side < 2 && done < 0; ++side) {
      if (s.stack[side].empty()) {
        done = side;
        break;
      }
      const int i = s.stack[side].back();
      s.stack[side].pop_back();
      s.reached[side].push_back(i);
      const int cx = i % w, cy = i / w;
      const std::array<std::pair<int, int>, 4> next = {{{cx - 1, cy}, {cx + 1, cy}, {cx, cy - 1}, {cx, cy + 1}}};
      for (auto [nx, ny] : next) {
        if (nx < 0 || ny < 0 || nx >= w || ny >= h || !grid.at(nx, ny)) continue;
        int& m = s.mark[static_cast<size_t>(ny) * w + nx];
        if (m == base + 1 - side) return std::nullopt;
        if (m >= base) continue;
        m = base + side;
        s.stack[side].push_back(ny * w + nx);
      }
    }
  }
  // The smaller side's box from its cells; the other's from what the
  // counts leave once the smaller side and the chord are taken out.
  std::array<Box, 2> boxes;
  for (int i : s.reached[done]) {
    const int cx = i % w, cy = i / w;
    boxes[done].add(cx, cy);
    ++s.rows[cy], ++s.columns[cx];
  }
  Box& other = boxes[1 - done];
  for (int y = total.box.y0; y <= total.box.y1; ++y)
    if (total.rows[y] - s.rows[y] - (y >= y0 && y < y1 ? 1 : 0) > 0) other.y0 = std::min(other.y0, y), other.y1 = y;
  for (int cx = total.box.x0; cx <= total.box.x1; ++cx)
    if (total.columns[cx] - s.columns[cx] - (cx == x ? y1 - y0 : 0) > 0) other.x0 = std::min(other.x0, cx), other.x1 = cx;
  for (int i : s.reached[done]) --s.rows[i / w], --s.columns[i % w];
  if (other.empty()) return std::nullopt;
  return boxes;
}

// Chords along grid columns (lines x = const), each a run of set cells of
// one column, kLinesPerAxis columns evenly spaced, two cells or more from
// the sides. Appends those that part the grid, in the coordinates of `axis`
// (grid x is chart axis `axis`).
void column_chords(const CellGrid& grid, int axis, int padding, std::vector<Chord>& out) {
  const int w = grid.width, h = grid.height;
  const GridCounts total = count_cells(grid);
  const double whole = padded_box_texels(total.box, grid.cell, padding);
  FloodScratch scratch{std::vector<int>(grid.set.size(), 0), 0, {}, {}, std::vector<int>(h, 0), std::vector<int>(w, 0)};
  const ColumnSpans spans = column_spans(grid);
  const int stride = std::max(1, (w - 4) / kLinesPerAxis);
  for (int x = 2; x + 2 < w; x += stride) {
    for (int y0 = 0; y0 < h;) {
      if (!grid.at(x, y0)) {
        ++y0;
        continue;
      }
      int y1 = y0;
      while (y1 < h && grid.at(x, y1)) ++y1;
      // A chord that is the column's only run parts everything left of it
      // from everything right of it: no flood fill needed.
      std::optional<std::array<Box, 2>> sides;
      if (y1 - y0 == total.columns[x])
        sides = std::array<Box, 2>{spans.before[x], spans.after[x]};
      else
        sides = chord_sides(grid, total, x, y0, y1, scratch);
      if (sides && !(*sides)[0].empty() && !(*sides)[1].empty()) {
        Chord chord;
        chord.axis = axis;
        chord.line = grid.origin.x() + (x + 0.5) * grid.step;
        chord.from = grid.origin.y() + y0 * grid.step;
        chord.to = grid.origin.y() + y1 * grid.step;
        chord.saving = whole - padded_box_texels((*sides)[0], grid.cell, padding) -
                       padded_box_texels((*sides)[1], grid.cell, padding);
        chord.length = static_cast<double>(y1 - y0) * grid.cell;
        chord.cell = grid.step;
        out.push_back(chord);
      }
      y0 = y1;
    }
  }
}

// The chords of a chart that save more padded box texels than the padding
// ring the cut adds (2 * padding per texel of its length), best first by
// saving per texel, at most kChordsKept.
std::vector<Chord> best_chords(const RowMatrixX2d& uv, const PackingCutOptions& options) {
  std::vector<Chord> chords;
  if (uv.rows() == 0) return chords;
  const CellGrid grid = cell_grid(uv, options.scale);
  if (grid.width < 3 && grid.height < 3) return chords;
  column_chords(grid, 0, options.padding, chords);
  column_chords(transposed(grid), 1, options.padding, chords);
  chords.erase(std::remove_if(chords.begin(), chords.end(),
                              [&](const Chord& c) { return c.saving <= 2.0 * options.padding * c.length; }),
               chords.end());
  std::stable_sort(chords.begin(), chords.end(),
                   [](const Chord& a, const Chord& b) { return a.saving * b.length > b.saving * a.length; });
  if (chords.size() > static_cast<size_t>(kChordsKept)) chords.resize(kChordsKept);
  return chords;
}

// Which chart holds each mesh face, and as which of its faces.
struct FaceSlots {
  std::vector<int> chart, index;

  void claim(const FlatChart& flat, int c) {
    for (size_t i = 0; i < flat.faces.size(); ++i) chart[flat.faces[i]] = c, index[flat.faces[i]] = static_cast<int>(i);
  }
};

// Per local face and corner k: the local face across the edge corner k
// starts, when it lies in the chart (chart c of slots) and agrees in UV
// along that edge; else -1.
std::vector<int> chart_neighbours(const Mesh& mesh, const MeshTopology& topology, const FlatChart& chart, int c,
                                  const FaceSlots& slots) {
  std::vector<int> across(3 * chart.faces.size(), -1);
  for (size_t i = 0; i < chart.faces.size(); ++i) {
    const int f = chart.faces[i];
    for (int k = 0; k < 3; ++k) {
      const int e = topology.corner_edge[3 * f + k];
      if (topology.edge_valence(e) != 2) continue;
      int other = topology.edge_corners[topology.edge_offsets[e]];
      if (other / 3 == f) other = topology.edge_corners[topology.edge_offsets[e] + 1];
      const int g = other / 3, j = slots.index[g];
      if (slots.chart[g] != c) continue;
      bool continuous = true;
      for (int end : {k, (k + 1) % 3}) {
        const int kj = mesh.corner_of(g, mesh.triangles(f, end));
        continuous = continuous && kj >= 0 && chart.corner_uv.row(3 * i + end) == chart.corner_uv.row(3 * j + kj);
      }
      if (continuous) across[3 * i + k] = j;
    }
  }
  return across;
}

// Whether the local faces with in_piece set form a disk, joined across the
// edges `across` gives.
bool piece_is_disk(const Mesh& mesh, const FlatChart& chart, const std::vector<int>& across,
                   const std::vector<char>& in_piece) {
  const int n = static_cast<int>(chart.faces.size());
  UnionFind corners(3 * n);
  for (int i = 0; i < n; ++i) {
    if (!in_piece[i]) continue;
    for (int k = 0; k < 3; ++k) {
      const int j = across[3 * i + k];
      if (j < 0 || !in_piece[j]) continue;
      for (int end : {k, (k + 1) % 3})
        corners.unite(3 * i + end, 3 * j + mesh.corner_of(chart.faces[j], mesh.triangles(chart.faces[i], end)));
    }
  }
  std::vector<int> vertex(3 * n, -1);  // per root corner
  int vertices = 0;
  RowMatrixX3i triangles(std::count(in_piece.begin(), in_piece.end(), 1), 3);
  int row = 0;
  for (int i = 0; i < n; ++i) {
    if (!in_piece[i]) continue;
    for (int k = 0; k < 3; ++k) {
      int& v = vertex[corners.find(3 * i + k)];
      if (v < 0) v = vertices++;
      triangles(row, k) = v;
    }
    ++row;
  }
  std::vector<int> loop;
  return disk_boundary_loop(triangles, vertices, loop).ok();
}

// The chart's faces with in_piece set and their UVs; the rest of the
// chart's figures (how it was solved) go with each piece.
FlatChart piece_of(const FlatChart& chart, const std::vector<char>& in_piece) {
  FlatChart piece;
  piece.kept_original = chart.kept_original;
  piece.density_lost_area = chart.density_lost_area;
  piece.energy_initial = chart.energy_initial;
  piece.energy_final = chart.energy_final;
  piece.iteration_seconds = chart.iteration_seconds;
  piece.factorize_seconds = chart.factorize_seconds;
  piece.corner_uv.resize(3 * static_cast<Eigen::Index>(std::count(in_piece.begin(), in_piece.end(), 1)), 2);
  for (size_t i = 0; i < chart.faces.size(); ++i)
    if (in_piece[i]) {
      piece.corner_uv.middleRows(3 * static_cast<Eigen::Index>(piece.faces.size()), 3) =
          chart.corner_uv.middleRows(3 * i, 3);
      piece.faces.push_back(chart.faces[i]);
    }
  return piece;
}

struct Split {
  std::array<FlatChart, 2> pieces;
  double seam_3d = 0;
};

// 3D length of the edge corner k of local face i starts.
double edge_length_3d(const Mesh& mesh, const FlatChart& chart, int i, int k) {
  const int f = chart.faces[i];
  return (mesh.positions.row(mesh.triangles(f, k)) - mesh.positions.row(mesh.triangles(f, (k + 1) % 3))).norm();
}

// Per local face, 0 or 1: the side of the chord's line its centroid lies
// on, faces on opposite sides parted only where their shared edge lies
// within the chord's span (a cell more each way). Of the parts this leaves,
// the two largest are the pieces, and crumbs go to the piece they touch
// most. Nothing when the chord parts nothing.
std::optional<std::vector<char>> chord_pieces(const FlatChart& chart, const std::vector<int>& across,
                                              const Chord& chord) {
  const int n = static_cast<int>(chart.faces.size());
  const int a = chord.axis, b = 1 - chord.axis;
  auto side = [&](int i) {
    const double centroid = (chart.corner_uv(3 * i, a) + chart.corner_uv(3 * i + 1, a) + chart.corner_uv(3 * i + 2, a)) / 3;
    return centroid < chord.line;
  };
  auto parted = [&](int i, int k) {
    if (side(i) == side(across[3 * i + k])) return false;
    const double p = chart.corner_uv(3 * i + k, b), q = chart.corner_uv(3 * i + (k + 1) % 3, b);
    return std::max(p, q) >= chord.from - chord.cell && std::min(p, q) <= chord.to + chord.cell;
  };
  UnionFind parts(n);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k)
      if (across[3 * i + k] > i && !parted(i, k)) parts.unite(i, across[3 * i + k]);
  const std::vector<int> label = parts.dense_labels();
  const int count = *std::max_element(label.begin(), label.end()) + 1;
  if (count < 2) return std::nullopt;
  std::vector<int> size(count, 0);
  for (int l : label) ++size[l];
  std::vector<int> by_size(count);
  std::iota(by_size.begin(), by_size.end(), 0);
  std::stable_sort(by_size.begin(), by_size.end(), [&](int x, int y) { return size[x] > size[y]; });
  std::vector<int> piece(count, -1);  // per part: 0, 1, or -1 for a crumb not yet placed
  piece[by_size[0]] = 0;
  piece[by_size[1]] = 1;
  for (bool placed = true; placed;) {
    placed = false;
    std::vector<std::array<int, 2>> touching(count, {0, 0});
    for (int i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        const int j = across[3 * i + k];
        if (j >= 0 && piece[label[i]] < 0 && piece[label[j]] >= 0) ++touching[label[i]][piece[label[j]]];
      }
    for (int l = 0; l < count; ++l)
      if (piece[l] < 0 && touching[l][0] + touching[l][1] > 0) {
        piece[l] = touching[l][1] > touching[l][0] ? 1 : 0;
        placed = true;
      }
  }
  if (std::count(piece.begin(), piece.end(), -1) > 0) return std::nullopt;
  std::vector<char> out(n);
  for (int i = 0; i < n; ++i) out[i] = static_cast<char>(piece[label[i]]);
  return out;
}

// Faces on a line's side stair-step along it: a face that meets the other
// piece along more 3D length than its own piece moves over, until none does
// (each move shortens the cut, so this ends). A cut across a grid of split
// quads then runs along the grid's lines, not in steps around its cells.
void straighten_cut(const Mesh& mesh, const FlatChart& chart, const std::vector<int>& across,
                    std::vector<char>& piece) {
  const int n = static_cast<int>(chart.faces.size());
  auto gains = [&](int i) {  // 3D length to the other piece over that to its own
    double own = 0, other = 0;
    for (int k = 0; k < 3; ++k) {
      const int j = across[3 * i + k];
      if (j >= 0) (piece[j] == piece[i] ? own : other) += edge_length_3d(mesh, chart, i, k);
    }
    return other > own * (1 + 1e-9);
  };
  // Faces on the cut first; a move puts the mover's neighbours back on the list.
  std::vector<int> stack;
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k)
      if (across[3 * i + k] >= 0 && piece[across[3 * i + k]] != piece[i]) {
        stack.push_back(i);
        break;
      }
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    if (!gains(i)) continue;
    piece[i] = static_cast<char>(1 - piece[i]);
    for (int k = 0; k < 3; ++k)
      if (across[3 * i + k] >= 0) stack.push_back(across[3 * i + k]);
  }
}

// Each input polygon's triangles (MeshTopology::inside_polygon) into the
// piece that holds most of them, the first of them on a tie: a polygon's
// corners hold one UV each, and the majority moves the fewest triangles off
// the cut the chord chose.
void keep_polygons_whole(const MeshTopology& topology, const FlatChart& chart, const std::vector<int>& across,
                         std::vector<char>& piece) {
  if (topology.inside_polygon.empty()) return;
  const int n = static_cast<int>(chart.faces.size());
  UnionFind polygon(n);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k)
      if (across[3 * i + k] >= 0 && !topology.may_cut(topology.corner_edge[3 * chart.faces[i] + k]))
        polygon.unite(i, across[3 * i + k]);
  std::vector<int> votes(n, 0), first(n, -1);
  for (int i = 0; i < n; ++i) {
    const int p = polygon.find(i);
    votes[p] += piece[i] ? 1 : -1;
    if (first[p] < 0) first[p] = i;
  }
  for (int i = 0; i < n; ++i) {
    const int p = polygon.find(i);
    piece[i] = votes[p] != 0 ? static_cast<char>(votes[p] > 0) : piece[first[p]];
  }
}

// The chart cut along the mesh edges nearest the chord, or nothing when
// that does not give two disks.
std::optional<Split> split_along(const Mesh& mesh, const MeshTopology& topology, const FlatChart& chart,
                                 const std::vector<int>& across, const Chord& chord) {
  auto piece = chord_pieces(chart, across, chord);
  if (!piece) return std::nullopt;
  straighten_cut(mesh, chart, across, *piece);
  keep_polygons_whole(topology, chart, across, *piece);
  const int n = static_cast<int>(chart.faces.size());
  Split split;
  for (int s = 0; s < 2; ++s) {
    std::vector<char> in_piece(n);
    for (int i = 0; i < n; ++i) in_piece[i] = (*piece)[i] == s;
    if (!piece_is_disk(mesh, chart, across, in_piece)) return std::nullopt;  // an empty piece is no disk either
    split.pieces[s] = piece_of(chart, in_piece);
  }
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const int j = across[3 * i + k];
      if (j > i && (*piece)[i] != (*piece)[j]) split.seam_3d += edge_length_3d(mesh, chart, i, k);
    }
  return split;
}

// 3D length per page texel of the chart, to price a chord in seam:
// sqrt(A_3D / A_uv) / scale over the chart's faces.
double length_per_texel(const Mesh& mesh, const FlatChart& chart, double scale) {
  double uv_area = 0, area = 0;
  for (size_t i = 0; i < chart.faces.size(); ++i) {
    uv_area += std::abs(signed_area(chart.corner_uv.row(3 * i), chart.corner_uv.row(3 * i + 1),
                                    chart.corner_uv.row(3 * i + 2)));
    area += mesh.area_3d(chart.faces[i]);
  }
  return uv_area > 0 ? std::sqrt(area / uv_area) / scale : 0.0;
}

// The charts, their best chords and what the search needs to make them.
class CutSearch {
 public:
  CutSearch(const Mesh& mesh, const MeshTopology& topology, const PackingCutOptions& options,
            std::vector<FlatChart>& charts)
      : mesh_(mesh),
        topology_(topology),
        options_(options),
        charts_(charts),
        chords_(charts.size()),
        per_texel_(charts.size()),
        across_(charts.size()),
        slots_{std::vector<int>(mesh.face_count(), -1), std::vector<int>(mesh.face_count(), -1)} {
    for (size_t c = 0; c < charts.size(); ++c) slots_.claim(charts[c], static_cast<int>(c));
  }

  // Chords of every chart, on all threads.
  void evaluate_all(const RunControl& control) {
    parallel_for(static_cast<int>(charts_.size()), 4, [&](int c) {
      control.throw_if_cancelled();
      evaluate(c);
    });
  }

  // The chart whose best chord saves most per 3D length, or -1 when no
  // chart has a chord left.
  int best_chart() const {
    int best = -1;
    for (int c = 0; c < static_cast<int>(charts_.size()); ++c)
      if (!chords_[c].empty() && (best < 0 || value(c) > value(best))) best = c;
    return best;
  }

  // Takes chart c's best chord off its list and makes that cut if it keeps
  // within `budget` (3D length): the chart is replaced by its two pieces,
  // turned to their smallest boxes unless they keep their original UVs.
  // Returns the seam it added (0: no cut).
  // The 3D length of the seam the cut added (0 for a cut along faces of no
  // area), or nothing when chart c's best chord made no cut.
  std::optional<double> cut_best_chord(int c, double budget) {
    const Chord chord = chords_[c].front();
    chords_[c].erase(chords_[c].begin());
    if (chord.length * per_texel_[c] > budget) return std::nullopt;
    if (across_[c].empty()) across_[c] = chart_neighbours(mesh_, topology_, charts_[c], c, slots_);
    auto split = split_along(mesh_, topology_, charts_[c], across_[c], chord);
    if (!split || split->seam_3d > budget) return std::nullopt;
    for (FlatChart& piece : split->pieces)
      if (!piece.kept_original) piece.corner_uv = turned_to_smallest_box(piece.corner_uv);
    const int added = static_cast<int>(charts_.size());
    charts_[c] = std::move(split->pieces[0]);
    charts_.push_back(std::move(split->pieces[1]));
    chords_.emplace_back();
    per_texel_.push_back(0);
    across_.emplace_back();
    slots_.claim(charts_[c], c);
    slots_.claim(charts_[added], added);
    // On this thread: two charts are too little work to wake the others for.
    evaluate(c);
    evaluate(added);
    return split->seam_3d;
  }

 private:
  void evaluate(int c) {
    across_[c].clear();
    // A cut runs along edges inside the chart: a lone face has none.
    if (charts_[c].faces.size() < 2) {
      chords_[c].clear();
      return;
    }
    chords_[c] = best_chords(charts_[c].corner_uv, options_);
    per_texel_[c] = length_per_texel(mesh_, charts_[c], options_.scale);
  }

  // Padded box texels chart c's best chord saves per 3D length of seam.
  double value(int c) const {
    const Chord& chord = chords_[c].front();
    return chord.saving / std::max(1e-12, chord.length * per_texel_[c]);
  }

  const Mesh& mesh_;
  const MeshTopology& topology_;
  const PackingCutOptions& options_;
  std::vector<FlatChart>& charts_;
  std::vector<std::vector<Chord>> chords_;
  std::vector<double> per_texel_;
  std::vector<std::vector<int>> across_;  // chart_neighbours, once a chord of the chart is tried
  FaceSlots slots_;
};

}  // namespace

PackingCutStats cut_for_packing(const Mesh& mesh, const MeshTopology& topology, const PackingCutOptions& options,
                                std::vector<FlatChart>& charts, const RunControl& control) {
  PackingCutStats stats;
  if (options.seam_budget <= 0) return stats;
  if (!(options.scale > 0)) throw InputError("cut_for_packing: scale must be > 0");
  CutSearch search(mesh, topology, options, charts);
  search.evaluate_all(control);
  for (int c = search.best_chart(); c >= 0; c = search.best_chart()) {
    control.throw_if_cancelled();
    if (const auto seam = search.cut_best_chord(c, options.seam_budget - stats.seam_added_3d)) {
      ++stats.cuts;
      stats.seam_added_3d += *seam;
    }
  }
  return stats;
}

}  // namespace atlas
