// The thin Python layer: numpy arrays in, numpy arrays and dicts out. Every
// call checks shapes and dtypes here (ValueError naming the argument) and
// releases the GIL while the native stages run; defragment and bake forward
// progress to an optional Python callable and honour an optional CancelToken.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <memory>
#include <new>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "bake/bake.hpp"
#include "charts/chart_graph.hpp"
#include "charts/degenerate_faces.hpp"
#include "core/uv_layout.hpp"
#include "io/byte_pixels.hpp"
#include "io/obj_file.hpp"
#include "io/png_rows.hpp"
#include "io/zlib_stream.hpp"
#include "metrics.hpp"
#include "pipeline.hpp"

namespace py = pybind11;
using namespace atlas;

namespace {

std::string shape_of(const py::array& a) {
  std::ostringstream s;
  s << "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s << (i ? ", " : "") << a.shape(i);
  s << (a.ndim() == 1 ? ",)" : ")");
  return s.str();
}

// Checks the trailing dimensions and returns the array as a C-contiguous
// rows x cols block of T. Integer arguments must already be integers: a float
// array of indices is a caller bug, not something to round silently.
template <class T>
py::array_t<T, py::array::c_style | py::array::forcecast> checked(const py::handle& obj, const char* name,
                                                                  std::vector<py::ssize_t> tail,
                                                                  const char* expected) {
  py::array a = py::array::ensure(obj);
  if (!a) throw py::value_error(std::string(name) + " must be an array");
  bool ok = a.ndim() == static_cast<py::ssize_t>(tail.size()) + 1;
  for (size_t i = 0; ok && i < tail.size(); ++i) ok = a.shape(i + 1) == tail[i];
  if (!ok) throw py::value_error(std::string(name) + " must have shape " + expected + ", got " + shape_of(a));
  const char kind = a.dtype().kind();
  if (std::is_integral_v<T> && kind != 'i' && kind != 'u')
    throw py::value_error(std::string(name) + " must be an integer array, got dtype " + std::string(py::str(a.dtype())));
  if (!std::is_integral_v<T> && kind != 'f' && kind != 'i' && kind != 'u')
    throw py::value_error(std::string(name) + " must be a numeric array, got dtype " + std::string(py::str(a.dtype())));
  return py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
}

template <class Matrix, class T>
Matrix to_matrix(const py::array_t<T, py::array::c_style | py::array::forcecast>& a, Eigen::Index rows,
                 Eigen::Index cols) {
  return Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(a.data(), rows, cols)
      .template cast<typename Matrix::Scalar>();
}

std::vector<PageSize> page_sizes(const py::handle& obj, const char* name) {
  const auto a = checked<long long>(obj, name, {2}, "(P, 2) as (width, height)");
  std::vector<PageSize> pages(a.shape(0));
  for (py::ssize_t p = 0; p < a.shape(0); ++p) {
    if (a.at(p, 0) <= 0 || a.at(p, 1) <= 0 || a.at(p, 0) > 65536 || a.at(p, 1) > 65536) {
      std::ostringstream msg;
      msg << name << ": page " << p << " has size " << a.at(p, 0) << "x" << a.at(p, 1)
          << " (each side must be 1..65536 texels)";
      throw py::value_error(msg.str());
    }
    pages[p] = {static_cast<int>(a.at(p, 0)), static_cast<int>(a.at(p, 1))};
  }
  return pages;
}

// An integer array narrowed to int, refusing values that would wrap around.
Eigen::VectorXi int_values(const py::array_t<long long, py::array::c_style | py::array::forcecast>& a, const char* name) {
  Eigen::VectorXi out(a.size());
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    const long long v = a.data()[i];
    if (v < INT32_MIN || v > INT32_MAX) {
      std::ostringstream msg;
      msg << name << "[" << i << "] = " << v << " is out of range";
      throw py::value_error(msg.str());
    }
    out[i] = static_cast<int>(v);
  }
  return out;
}

// The arrays behind a UvLayout, copied out of numpy.
struct LayoutArrays {
  RowMatrixX2d corner_uv;
  Eigen::VectorXi face_page;
  std::vector<PageSize> pages;
  UvLayout view() const { return {&corner_uv, &face_page, &pages}; }
};

LayoutArrays layout_arrays(const py::handle& uvs, const py::handle& face_page, Eigen::Index faces,
                           const char* uv_name, const char* page_name, std::vector<PageSize> pages = {}) {
  const auto uv = checked<double>(uvs, uv_name, {3, 2}, "(F, 3, 2)");
  const auto page = checked<long long>(face_page, page_name, {}, "(F,)");
  if (uv.shape(0) != faces || page.shape(0) != faces) {
    std::ostringstream msg;
    msg << uv_name << " and " << page_name << " must describe the " << faces << " triangles, got "
        << uv.shape(0) << " and " << page.shape(0);
    throw py::value_error(msg.str());
  }
  return {to_matrix<RowMatrixX2d>(uv, 3 * faces, 2), int_values(page, page_name), std::move(pages)};
}

// (F, 3) vertex indices, each in [0, vertex_count): read as 64-bit, so that
// no index wraps into range on its way to int.
RowMatrixX3i triangle_indices(const py::handle& triangles, py::ssize_t vertex_count) {
  const auto tri = checked<long long>(triangles, "triangles", {3}, "(F, 3)");
  RowMatrixX3i t(tri.shape(0), 3);
  const long long* rows = tri.data();  // C order, as checked makes it: row f at 3 f
  for (py::ssize_t f = 0; f < tri.shape(0); ++f)
    for (int k = 0; k < 3; ++k) {
      const long long v = rows[3 * f + k];
      if (v < 0 || v >= vertex_count) {
        std::ostringstream msg;
        msg << "triangle " << f << " has vertex index " << v << " out of range [0, " << vertex_count << ")";
        throw py::value_error(msg.str());
      }
      t(f, k) = static_cast<int>(v);
    }
  return t;
}

Mesh mesh_from(const py::handle& positions, const py::handle& triangles, const py::handle& uvs,
               const py::handle& face_page, const std::vector<PageSize>& pages, bool weld = true) {
  const auto pos = checked<double>(positions, "positions", {3}, "(V, 3)");
  const RowMatrixX3i t = triangle_indices(triangles, pos.shape(0));
  const LayoutArrays l = layout_arrays(uvs, face_page, t.rows(), "uvs", "face_page");
  const RowMatrixX3d p = to_matrix<RowMatrixX3d>(pos, pos.shape(0), 3);
  py::gil_scoped_release release;  // the weld sorts every corner
  return make_mesh(p, t, l.corner_uv, l.face_page, pages, weld);
}

struct CancelToken {
  RunControl::Flag flag = std::make_shared<std::atomic<bool>>(false);
};

RunControl control_from(const py::object& progress, const py::object& cancel) {
  RunControl::ReportFn report;
  if (!progress.is_none()) {
    report = [progress](const std::string& stage, double fraction) {
      py::gil_scoped_acquire gil;
      progress(stage, fraction);
    };
  }
  if (cancel.is_none()) return RunControl(report);
  return RunControl(report, cancel.cast<CancelToken&>().flag);
}

// True or False only: a number or a string is refused, not read as a flag.
bool bool_option(const py::handle& value, const std::string& key) {
  if (!py::isinstance<py::bool_>(value)) throw py::value_error(key + " must be True or False");
  return value.cast<bool>();
}

// An option's value as T, or ValueError naming the option, its range and the
// value: never pybind's "Unable to cast" RuntimeError for 2**40 or "abc".
template <class T>
T option_value(const py::handle& value, const std::string& key, const char* range) {
  constexpr bool integral = std::is_integral_v<T>;
  // Integers (numpy's too) for every option; any real number for a float one. No bools, no text.
  const bool is_text = py::isinstance<py::str>(value) || py::isinstance<py::bytes>(value);
  const bool is_number = !py::isinstance<py::bool_>(value) && !is_text &&
                         (PyIndex_Check(value.ptr()) || (!integral && PyNumber_Check(value.ptr())));
  if (is_number) {
    try {
      const auto number = py::reinterpret_borrow<py::object>(value);
      if constexpr (integral) return py::int_(number).cast<T>();
      else return py::float_(number).cast<T>();
    } catch (const py::error_already_set&) {
    } catch (const py::cast_error&) {
    }
  }
  throw py::value_error(key + " must be " + (integral ? "an integer " : "a number ") + range + ", got " +
                        std::string(py::repr(value)));
}

// A text option's value, or the repr of whatever else was given (for the message).
std::string option_text(const py::handle& value) {
  return py::isinstance<py::str>(value) ? value.cast<std::string>() : std::string(py::repr(value));
}

PageSides page_sides_option(const py::handle& value, const std::string& key) {
  const std::string v = option_text(value);
  if (v == "tight") return PageSides::Tight;
  if (v == "multiple_of_4") return PageSides::MultipleOf4;
  if (v == "power_of_two") return PageSides::PowerOfTwo;
  throw py::value_error(key + " must be 'tight', 'multiple_of_4' or 'power_of_two', got '" + v + "'");
}

PipelineOptions pipeline_options(const py::object& obj) {
  PipelineOptions o;
  if (obj.is_none()) return o;
  if (!py::isinstance<py::dict>(obj)) throw py::value_error("options must be a dict of option name to value");
  // The ranges of addon/atlas_defrag/options.py (python_tests/test_options.py checks both agree).
  for (const auto& [key_obj, value] : obj.cast<py::dict>()) {
    if (!py::isinstance<py::str>(key_obj)) throw py::value_error("option names must be strings");
    const std::string key = key_obj.cast<std::string>();
    if (key == "target_charts") o.aggregate.target_charts = option_value<int>(value, key, "0 (automatic) or >= 1");
    else if (key == "weighting") {
      const std::string w = option_text(value);
      if (w != "uv" && w != "3d") throw py::value_error("weighting must be 'uv' or '3d', got '" + w + "'");
      o.aggregate.weighting = w == "uv" ? Weighting::UV : Weighting::Surface;
    } else if (key == "min_chart_fraction") o.aggregate.min_chart_fraction = option_value<double>(value, key, ">= 0");
    else if (key == "min_normal_coherence") o.aggregate.min_normal_coherence = option_value<double>(value, key, "0..1");
    else if (key == "coherence_free_faces") o.aggregate.coherence_free_faces = option_value<int>(value, key, ">= 0");
    else if (key == "reference_chart_faces")
      o.aggregate.reference_chart_faces = option_value<double>(value, key, "0 (no scaling) or >= 1");
    else if (key == "developable_curvature") o.aggregate.developable_curvature = option_value<double>(value, key, ">= 0");
    else if (key == "max_chart_faces") o.aggregate.max_chart_faces = option_value<int>(value, key, "0 (no cap) or >= 1");
    else if (key == "partial_merges") o.aggregate.partial_merges = bool_option(value, key);
    else if (key == "relief_cuts") o.relief_cuts = option_value<int>(value, key, "0 (split at once) .. 8");
    else if (key == "density_loss_budget")  // percent of the surface, a share in the core
      o.density_loss_budget = option_value<double>(value, key, "0..0.8 (percent of the surface)") / 100;
    else if (key == "refine_min_area_ratio") o.refine.min_area_ratio = option_value<double>(value, key, "0..1");
    else if (key == "packing_cut_seam") o.packing_cut_seam = option_value<double>(value, key, "0 (no cut) .. 10");
    else if (key == "fit_cut_seam") o.fit_cut_seam = option_value<double>(value, key, "0 (never) .. 10");
    else if (key == "padding") o.pack.padding = option_value<int>(value, key, "0..64 texels");
    else if (key == "fixed_page_size") o.pack.fixed_page_size = option_value<int>(value, key, "0 (automatic) or 64..16384 texels");
    else if (key == "max_page_size") o.pack.max_page_size = option_value<int>(value, key, "64..16384 texels");
    else if (key == "density_scale") o.pack.density_scale = option_value<double>(value, key, "0.01..16");
    else if (key == "texel_budget") o.pack.texel_budget = option_value<long long>(value, key, "0 (automatic) or >= 16");
    else if (key == "max_iterations") o.slim.max_iterations = option_value<int>(value, key, ">= 0");
    else if (key == "max_pages") o.pack.max_pages = option_value<int>(value, key, "0 (automatic) or 1..4096");
    else if (key == "square_pages") o.pack.square_pages = bool_option(value, key);
    else if (key == "padding_between_charts") o.pack.padding_between_charts = bool_option(value, key);
    else if (key == "padding_follows_page")
      o.pack.full_padding_side = bool_option(value, key) ? PackOptions{}.full_padding_side : 0;
    else if (key == "texels_at_most_input") o.texels_at_most_input = bool_option(value, key);
    else if (key == "texels_per_unit")
      o.texels_per_unit = option_value<double>(value, key, "0 (density_scale applies) or 0.001..1e9");
    else if (key == "page_sides") o.pack.page_sides = page_sides_option(value, key);
    else throw py::value_error("unknown option '" + key + "'");
  }
  if (o.pack.padding < 0 || o.pack.padding > 64) throw py::value_error("padding must be 0..64 texels");
  if (o.pack.max_page_size < 64 || o.pack.max_page_size > 16384)
    throw py::value_error("max_page_size must be 64..16384 texels");
  if (o.pack.fixed_page_size != 0 && (o.pack.fixed_page_size < 64 || o.pack.fixed_page_size > o.pack.max_page_size))
    throw py::value_error("fixed_page_size must be 0 (automatic) or 64..max_page_size texels");
  if (o.pack.fixed_page_size != 0 && !is_allowed_side(o.pack.fixed_page_size, o.pack.page_sides))
    throw py::value_error("fixed_page_size " + std::to_string(o.pack.fixed_page_size) +
                          " is not a side page_sides allows (a multiple of 4, or a power of two)");
  if (!(o.pack.density_scale >= 0.01 && o.pack.density_scale <= 16))
    throw py::value_error("density_scale must be 0.01..16");
  if (o.pack.max_pages < 0 || o.pack.max_pages > 4096)
    throw py::value_error("max_pages must be 0 (automatic) or 1..4096");
  if (o.texels_per_unit != 0 && !(o.texels_per_unit >= 0.001 && o.texels_per_unit <= 1e9))
    throw py::value_error("texels_per_unit must be 0 (density_scale applies) or 0.001..1e9");
  if (!(o.refine.min_area_ratio >= 0 && o.refine.min_area_ratio <= 1))
    throw py::value_error("refine_min_area_ratio must be in [0, 1] (0: no seam refinement)");
  if (o.relief_cuts < 0 || o.relief_cuts > 8) throw py::value_error("relief_cuts must be 0 (split at once) .. 8");
  if (!(o.density_loss_budget >= 0 && o.density_loss_budget <= 0.008))
    throw py::value_error("density_loss_budget must be 0..0.8 (percent of the surface)");
  if (!(o.packing_cut_seam >= 0 && o.packing_cut_seam <= 10))
    throw py::value_error("packing_cut_seam must be 0 (no cut) .. 10");
  if (!(o.fit_cut_seam >= 0 && o.fit_cut_seam <= 10)) throw py::value_error("fit_cut_seam must be 0 (never) .. 10");
  if (o.aggregate.target_charts < 0) throw py::value_error("target_charts must be 0 (automatic) or >= 1");
  if (!(o.aggregate.min_chart_fraction >= 0)) throw py::value_error("min_chart_fraction must be >= 0");
  if (!(o.aggregate.min_normal_coherence >= 0 && o.aggregate.min_normal_coherence <= 1))
    throw py::value_error("min_normal_coherence must be in [0, 1]");
  if (!(o.aggregate.developable_curvature >= 0))
    throw py::value_error("developable_curvature must be >= 0 (radians; 0: no exemption from min_normal_coherence)");
  if (o.aggregate.coherence_free_faces < 0) throw py::value_error("coherence_free_faces must be >= 0 (0: gate every merge but those of charts of at most 100 faces)");
  if (!(o.aggregate.reference_chart_faces == 0 ||
        (o.aggregate.reference_chart_faces >= 1 && std::isfinite(o.aggregate.reference_chart_faces))))
    throw py::value_error("reference_chart_faces must be 0 (face counts not scaled) or >= 1");
  if (o.aggregate.max_chart_faces < 0) throw py::value_error("max_chart_faces must be >= 0 (0: no cap)");
  if (o.pack.texel_budget < 0) throw py::value_error("texel_budget must be 0 (automatic) or >= 16");
  if (o.slim.max_iterations < 0) throw py::value_error("max_iterations must be >= 0");
  return o;
}

// Per output chart: faces, flattened (else kept), energy before and after SLIM.
py::dict chart_arrays(const std::vector<ChartSummary>& charts) {
  const py::ssize_t n = static_cast<py::ssize_t>(charts.size());
  py::array_t<int> faces(n);
  py::array_t<bool> flattened(n);
  py::array_t<double> before(n), after(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    faces.mutable_at(i) = charts[i].faces;
    flattened.mutable_at(i) = charts[i].flattened;
    before.mutable_at(i) = charts[i].energy_initial;
    after.mutable_at(i) = charts[i].energy_final;
  }
  py::dict d;
  d["faces"] = faces;
  d["flattened"] = flattened;
  d["energy_initial"] = before;
  d["energy_final"] = after;
  return d;
}

py::array_t<double> uv_array(const RowMatrixX2d& uv) {
  py::array_t<double> out({uv.rows() / 3, py::ssize_t(3), py::ssize_t(2)});
  std::copy(uv.data(), uv.data() + uv.size(), out.mutable_data());
  return out;
}

py::array_t<int> int_array(const Eigen::VectorXi& v) {
  py::array_t<int> out(v.size());
  std::copy(v.data(), v.data() + v.size(), out.mutable_data());
  return out;
}

py::array_t<int> sizes_array(const std::vector<PageSize>& pages) {
  py::array_t<int> out({static_cast<py::ssize_t>(pages.size()), py::ssize_t(2)});
  for (size_t p = 0; p < pages.size(); ++p) out.mutable_at(p, 0) = pages[p].width, out.mutable_at(p, 1) = pages[p].height;
  return out;
}

py::dict stops_dict(const AggregationStops& s) {
  py::dict d;
  d["non_manifold"] = s.non_manifold;
  d["not_disk"] = s.not_disk;
  d["normal_coherence"] = s.normal_coherence;
  d["max_chart_faces"] = s.max_chart_faces;
  d["min_chart_fraction"] = s.min_chart_fraction;
  d["feasible"] = s.feasible;
  return d;
}

py::dict report_dict(const PipelineReport& r) {
  py::dict seconds;
  for (const StageTime& t : r.seconds) seconds[py::str(t.stage)] = t.seconds;
  py::dict d;
  d["duplicate_faces"] = r.duplicate_faces;
  d["charts_before"] = r.charts_before;
  d["opposed_winding_edges"] = r.opposed_winding_edges;
  d["charts_aggregated"] = r.charts_aggregated;
  d["aggregate_stops"] = stops_dict(r.aggregate_stops);
  d["refine_faces_moved"] = r.refine_faces_moved;
  d["refine_seam_removed"] = r.refine_seam_removed;
  d["packing_cuts"] = r.packing_cuts;
  d["packing_cut_seam"] = r.packing_cut_seam;
  d["cut_to_fit"] = r.cut_to_fit;
  d["faces_detached"] = r.faces_detached;
  d["charts_after"] = r.charts_after;
  d["charts_solved"] = r.charts_solved;
  for (const FlattenCounter& c : kFlattenCounters) d[c.name] = r.flatten.*c.field;
  d["density_reflattened"] = r.density_reflattened;
  d["largest_chart_faces"] = r.largest_chart_faces;
  d["iteration_over_factorization"] = r.iteration_over_factorization;
  d["seam_before"] = r.seam_before;
  d["seam_after"] = r.seam_after;
  d["texels_before"] = r.texels_before;
  d["texels_after"] = r.texels_after;
  d["packing_efficiency"] = r.packing_efficiency;
  d["scale"] = r.scale;
  d["shrunk"] = r.shrunk;
  d["energy_initial_median"] = r.energy_initial_median;
  d["energy_median"] = r.energy_median;
  d["energy_max"] = r.energy_max;
  d["seconds"] = seconds;
  return d;
}

// A per-face int array (F,) as a vector, or empty for None; `what` names it in errors.
std::vector<int> per_face_ints(const py::object& array, int faces, const char* what) {
  if (array.is_none()) return {};
  const auto a = checked<long long>(array, what, {}, "(F,)");
  if (a.shape(0) != faces) throw py::value_error(std::string(what) + " must hold one value per triangle");
  const Eigen::VectorXi values = int_values(a, what);
  return std::vector<int>(values.data(), values.data() + values.size());
}

py::dict defragment_py(const py::object& positions, const py::object& triangles, const py::object& uvs,
                       const py::object& face_page, const py::object& sizes, const py::object& face_group,
                       const py::object& face_polygon, const py::object& options, const py::object& progress,
                       const py::object& cancel) {
  const Mesh mesh = mesh_from(positions, triangles, uvs, face_page, page_sizes(sizes, "page_sizes"));
  const std::vector<int> groups = per_face_ints(face_group, mesh.face_count(), "face_group");
  const std::vector<int> polygons = per_face_ints(face_polygon, mesh.face_count(), "face_polygon");
  const PipelineOptions opts = pipeline_options(options);
  const RunControl control = control_from(progress, cancel);
  PipelineResult r;
  {
    py::gil_scoped_release release;
    r = defragment(mesh, groups, polygons, opts, control);
  }
  py::dict out;
  out["uvs"] = uv_array(r.corner_uv);
  out["face_page"] = int_array(r.face_page);
  out["page_sizes"] = sizes_array(r.pages);
  out["page_padding"] = py::array_t<int>(r.page_padding.size(), r.page_padding.data());
  out["report"] = report_dict(r.report);
  out["charts"] = chart_arrays(r.charts);
  out["face_chart"] = int_array(r.face_chart);
  return out;
}

py::dict chart_graph_py(const py::object& positions, const py::object& triangles, const py::object& uvs,
                        const py::object& face_page, const py::object& sizes) {
  const Mesh mesh = mesh_from(positions, triangles, uvs, face_page, page_sizes(sizes, "page_sizes"));
  ChartGraph g;
  {
    py::gil_scoped_release release;
    g = build_chart_graph(mesh, build_topology(mesh.triangles, mesh.vertex_count()), {});
  }
  py::dict out;
  out["chart_count"] = g.chart_count();
  out["face_chart"] = py::array_t<int>(g.face_chart.size(), g.face_chart.data());
  out["adjacent_pairs"] = g.adjacency.size();
  out["welded_vertices"] = mesh.vertex_count();
  int mirrored = 0;
  for (const ChartStats& s : g.charts) mirrored += s.mirrored();
  out["mirrored_charts"] = mirrored;
  return out;
}

// A row-major Eigen matrix as a new (rows, cols) numpy array.
template <class Matrix>
py::array rows_array(const Matrix& m) {
  using T = typename Matrix::Scalar;
  return py::array_t<T>({static_cast<py::ssize_t>(m.rows()), static_cast<py::ssize_t>(m.cols())}, m.data());
}

// Names from a file as str, decoded as Python decodes file names: bytes that
// are not UTF-8 (a Latin-1 "Wand_ä") become lone surrogates, so two such
// names stay apart, match an MTL read with errors="surrogateescape" and name
// the file on disk.
py::list file_names(const std::vector<std::string>& names) {
  py::list out;
  for (const std::string& name : names) {
    PyObject* text = PyUnicode_DecodeUTF8(name.data(), static_cast<py::ssize_t>(name.size()), "surrogateescape");
    if (text == nullptr) throw py::error_already_set();
    out.append(py::reinterpret_steal<py::str>(text));
  }
  return out;
}

// A path with a NUL in it names another file to the C library (the part
// before it): refused, as Python's own open() refuses it.
void require_no_nul(const std::string& path) {
  if (path.find('\0') != std::string::npos) throw py::value_error("embedded null character in path");
}

py::dict read_obj_py(const std::string& path) {
  require_no_nul(path);
  obj::ObjFile f;
  {
    py::gil_scoped_release release;
    f = obj::read_obj(path);
  }
  py::dict out;
  out["positions"] = rows_array(f.positions);
  out["texcoords"] = rows_array(f.texcoords);
  out["triangles"] = rows_array(f.triangles);
  out["texcoord_index"] = rows_array(f.texcoord_index);
  out["normals"] = rows_array(f.normals);
  out["normal_index"] = rows_array(f.normal_index);
  out["face_material"] = py::array_t<int>(f.face_material.size(), f.face_material.data());
  out["materials"] = file_names(f.materials);
  out["material_libraries"] = file_names(f.material_libraries);
  out["vertex_colours"] = f.vertex_colours;
  return out;
}

// The corner normals write_obj takes: both None, or normals (N, 3) and
// normal_index (F, 3) with -1 for a corner without one.
obj::CornerNormals corner_normals(const py::object& normals, const py::object& normal_index, py::ssize_t faces) {
  if (normals.is_none() != normal_index.is_none())
    throw py::value_error("write_obj: give normals and normal_index together");
  obj::CornerNormals out;
  if (normals.is_none()) return out;
  const auto n = checked<double>(normals, "normals", {3}, "(N, 3)");
  const auto i = checked<long long>(normal_index, "normal_index", {3}, "(F, 3)");
  if (i.shape(0) != faces) throw py::value_error("write_obj: normal_index must hold one row per face");
  out.normals = to_matrix<RowMatrixX3d>(n, n.shape(0), 3);
  out.normal_index.resize(faces, 3);
  for (py::ssize_t f = 0; f < faces; ++f)
    for (int k = 0; k < 3; ++k) {
      const long long v = i.data()[3 * f + k];
      if (v < -1 || v >= n.shape(0)) throw py::value_error("write_obj: normal_index refers to no normal");
      out.normal_index(f, k) = static_cast<int>(v);
    }
  return out;
}

void write_obj_py(const std::string& path, const std::string& library, const py::object& positions,
                  const py::object& triangles, const py::object& uvs, const py::object& face_material,
                  const std::vector<std::string>& materials, const py::object& normals,
                  const py::object& normal_index) {
  require_no_nul(path);
  const auto p = checked<double>(positions, "positions", {3}, "(V, 3)");
  const RowMatrixX3i faces = triangle_indices(triangles, p.shape(0));
  const auto u = checked<double>(uvs, "uvs", {3, 2}, "(F, 3, 2)");
  const auto m = checked<long long>(face_material, "face_material", {}, "(F,)");
  const RowMatrixX3d points = to_matrix<RowMatrixX3d>(p, p.shape(0), 3);
  const RowMatrixX2d corner_uv = to_matrix<RowMatrixX2d>(u, 3 * u.shape(0), 2);
  const Eigen::VectorXi material = int_values(m, "face_material");
  const obj::CornerNormals shading = corner_normals(normals, normal_index, faces.rows());
  py::gil_scoped_release release;
  obj::write_obj(path, library, points, faces, corner_uv, material, materials, shading);
}

// A flat, contiguous byte buffer, exported for as long as this lives: while
// the native code reads it without the GIL, a bytearray cannot be resized or
// freed under it (Python raises BufferError instead). Destroy it with the GIL held.
struct FlatBytes {
  py::buffer_info info;
  const std::uint8_t* data() const { return static_cast<const std::uint8_t*>(info.ptr); }
  std::size_t size() const { return static_cast<std::size_t>(info.size); }
};

FlatBytes flat_bytes(const py::buffer& buffer, const char* name) {
  py::buffer_info in = buffer.request();
  if (in.itemsize != 1 || in.ndim != 1 || (in.size > 1 && in.strides[0] != 1))
    throw py::value_error(std::string(name) + " must be a contiguous flat buffer of bytes");
  return {std::move(in)};
}

py::array_t<std::uint8_t> png_pixels_py(const py::buffer& idat, int width, int height, int channels) {
  const FlatBytes in = flat_bytes(idat, "idat");
  // Allocated first: a size that fits in memory cannot overflow the row count below.
  py::array_t<std::uint8_t> out({py::ssize_t(height), py::ssize_t(width), py::ssize_t(channels)});
  const std::size_t scanline_bytes = std::size_t(height) * (1 + std::size_t(width) * std::size_t(channels));
  png::check_sizes(scanline_bytes, width, height, channels);
  std::uint8_t* dst = out.mutable_data();
  py::gil_scoped_release release;
  // Not zeroed: inflate fills it, or fails first, and a stream that claims a
  // huge image but ends early then touches (and commits) only what it wrote.
  const std::unique_ptr<std::uint8_t[]> scanlines(new std::uint8_t[scanline_bytes]);
  zlib_stream::inflate(in.data(), in.size(), scanlines.get(), scanline_bytes);
  png::unfilter_rows(scanlines.get(), scanline_bytes, width, height, channels, dst);
  return out;
}

py::array_t<std::uint8_t> zlib_compress_py(const py::buffer& data, int level) {
  const FlatBytes in = flat_bytes(data, "data");
  std::vector<std::uint8_t> bounded;
  {
    py::gil_scoped_release release;
    bounded.resize(zlib_stream::bound(in.size()));
    bounded.resize(zlib_stream::compress(in.data(), in.size(), level, bounded.data()));
  }
  // A stream of its own size: a view into the bound would keep an input-sized
  // allocation alive, which counts in full where memory is not overcommitted.
  py::array_t<std::uint8_t> out(py::ssize_t(bounded.size()));
  std::copy(bounded.begin(), bounded.end(), out.mutable_data());
  return out;
}

py::array_t<std::uint8_t> bytes_from_unit_floats_py(const py::array& values, int kept) {
  if (!py::isinstance<py::array_t<float>>(values))
    throw py::value_error("values must be a float32 array, got dtype " + std::string(py::str(values.dtype())));
  if (values.ndim() < 2 || values.shape(values.ndim() - 1) < 1)
    throw py::value_error("values must be pixels, (..., C) with C >= 1");
  const auto in = py::array_t<float, py::array::c_style>::ensure(values);
  if (!in) throw std::bad_alloc();  // the contiguous copy failed
  const int channels = static_cast<int>(in.shape(in.ndim() - 1));
  if (kept == 0) kept = channels;
  if (kept < 1 || kept > channels)
    throw py::value_error("kept must be 0 or 1 to " + std::to_string(channels) + ", got " + std::to_string(kept));
  std::vector<py::ssize_t> shape(in.shape(), in.shape() + in.ndim());
  const std::size_t pixels = static_cast<std::size_t>(in.size()) / channels;
  auto convert = [&](int keep) {
    shape.back() = keep;
    py::array_t<std::uint8_t> out(shape);
    const float* src = in.data();
    std::uint8_t* dst = out.mutable_data();
    bool filler;
    {
      py::gil_scoped_release release;
      filler = bytes_from_unit_floats(src, pixels, channels, keep, dst);
    }
    return std::make_pair(std::move(out), filler);
  };
  auto [out, filler] = convert(kept);
  return filler ? out : convert(channels).first;
}

// Whether a's elements are T: by equivalence, as numpy compares dtypes (an
// unpickled array may hold an equal dtype object that is not numpy's own).
template <class T>
bool has_dtype(const py::array& a) {
  return py::isinstance<py::array_t<T>>(a);
}

// Images as (H, W, C) arrays, row 0 at v = 0; all of one dtype T. The arrays
// are returned too so their buffers outlive the views.
template <class T>
std::vector<ImageView<T>> image_views(const py::list& images, const char* name, std::vector<py::array>& keep) {
  std::vector<ImageView<T>> views;
  for (size_t i = 0; i < images.size(); ++i) {
    const py::array raw = py::array::ensure(images[i]);
    auto a = raw && has_dtype<T>(raw) ? py::array_t<T, py::array::c_style>::ensure(raw)
                                                        : py::array_t<T, py::array::c_style>();
    if (!a || a.ndim() != 3 || a.shape(2) < 1 || a.shape(2) > 4) {
      std::ostringstream msg;
      msg << name << "[" << i << "] must be an (H, W, C) array with 1 to 4 channels of the same dtype as the others";
      throw py::value_error(msg.str());
    }
    views.push_back({a.data(), static_cast<int>(a.shape(1)), static_cast<int>(a.shape(0)), static_cast<int>(a.shape(2)),
                     static_cast<std::size_t>(a.size())});
    keep.push_back(a);
  }
  return views;
}

bool is_uint8_images(const py::list& images, const char* name) {
  if (images.empty()) throw py::value_error(std::string(name) + " must hold at least one image");
  const py::array first = py::array::ensure(images[0]);
  if (!first) throw py::value_error(std::string(name) + "[0] must be an array");
  if (has_dtype<std::uint8_t>(first)) return true;
  if (has_dtype<float>(first)) return false;
  throw py::value_error(std::string(name) + " must be uint8 or float32 arrays, got " + std::string(py::str(first.dtype())));
}

// Hands the texels to numpy without a copy: the vector moves into a capsule.
template <class T>
py::array_t<T> image_array(Image<T>&& image) {
  auto* texels = new std::vector<T>(std::move(image.texels));
  py::capsule owner(texels, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>({image.height, image.width, image.channels}, texels->data(), owner);
}

// maps[m] is one map's list of old page images, all of one dtype T, named
// names[m] in errors.
template <class T>
py::list bake_typed(LayoutArrays& old_l, const py::list& maps, const std::vector<std::string>& names,
                    const std::vector<bool>& normal_maps, const LayoutArrays& new_l, int padding, bool fit_texels,
                    const RunControl& control, BakeStats& stats) {
  std::vector<py::array> keep;
  std::vector<BakeSource<T>> sources;
  for (size_t m = 0; m < maps.size(); ++m)
    sources.push_back({image_views<T>(maps[m].cast<py::list>(), names[m].c_str(), keep), normal_maps[m]});
  for (const ImageView<T>& v : sources.front().old_pages) old_l.pages.push_back({v.width, v.height});
  std::vector<std::vector<Image<T>>> baked;
  {
    py::gil_scoped_release release;
    baked = bake_maps<T>(old_l.view(), sources, new_l.view(), padding, control, &stats, fit_texels);
  }
  py::list result;
  for (auto& images : baked) {
    py::list pages;
    for (auto& image : images) pages.append(image_array(std::move(image)));
    result.append(pages);
  }
  return result;
}

// Keeps the faces whose new triangle (page and corner UVs) no earlier face
// draws, in both layouts: stacked copies bake their texels once.
void drop_repeated_faces(LayoutArrays& old_l, LayoutArrays& new_l) {
  const std::vector<int> kept = first_of_equal_faces(new_l.corner_uv, new_l.face_page);
  if (static_cast<Eigen::Index>(kept.size()) == new_l.face_page.size()) return;
  for (LayoutArrays* l : {&old_l, &new_l}) {
    RowMatrixX2d uv;
    Eigen::VectorXi page;
    take_face_uvs(l->corner_uv, l->face_page, kept, uv, page);
    l->corner_uv = std::move(uv);
    l->face_page = std::move(page);
  }
}

// dtype of the first image of the first map: every image must share it
// (image_views names the first that does not).
bool is_uint8_maps(const py::list& maps, const std::vector<std::string>& names) {
  if (maps.empty()) throw py::value_error("maps must hold at least one map");
  return is_uint8_images(maps[0].cast<py::list>(), names[0].c_str());
}

// bake_maps, its maps named in errors as names gives.
py::object bake_named_maps(const py::object& old_uvs, const py::object& old_face_page, const py::list& maps,
                           const std::vector<std::string>& names, const py::object& new_uvs,
                           const py::object& new_face_page, const py::object& out_sizes,
                           const py::object& normal_maps, const py::object& padding_value,
                           const py::object& progress, const py::object& cancel, bool with_stats, bool fit_texels) {
  const int padding = option_value<int>(padding_value, "padding", "0..64 texels");
  const Eigen::Index faces = checked<double>(old_uvs, "old_uvs", {3, 2}, "(F, 3, 2)").shape(0);
  LayoutArrays old_l = layout_arrays(old_uvs, old_face_page, faces, "old_uvs", "old_face_page");
  LayoutArrays new_l =
      layout_arrays(new_uvs, new_face_page, faces, "new_uvs", "new_face_page", page_sizes(out_sizes, "out_sizes"));
  if (padding < 0 || padding > 64) throw py::value_error("padding must be 0..64 texels");
  std::vector<bool> normal(maps.size(), false);
  if (!normal_maps.is_none()) {
    normal = normal_maps.cast<std::vector<bool>>();
    if (normal.size() != maps.size()) throw py::value_error("normal_maps must hold one flag per map");
  }
  {
    py::gil_scoped_release release;  // a pass over every face
    drop_repeated_faces(old_l, new_l);
  }
  const RunControl control = control_from(progress, cancel);
  BakeStats stats;
  const py::list baked = is_uint8_maps(maps, names)
                             ? bake_typed<std::uint8_t>(old_l, maps, names, normal, new_l, padding, fit_texels, control,
                                                        stats)
                             : bake_typed<float>(old_l, maps, names, normal, new_l, padding, fit_texels, control,
                                                 stats);
  if (!with_stats) return baked;
  py::dict d;
  d["covered_texels"] = stats.covered_texels;
  d["copied_texels"] = stats.copied_texels;
  d["copied_share"] = stats.covered_texels > 0 ? static_cast<double>(stats.copied_texels) / stats.covered_texels : 0.0;
  return py::make_tuple(baked, d);
}

py::object bake_maps_py(const py::object& old_uvs, const py::object& old_face_page, const py::list& maps,
                        const py::object& new_uvs, const py::object& new_face_page, const py::object& out_sizes,
                        const py::object& normal_maps, const py::object& padding, const py::object& progress,
                        const py::object& cancel, bool with_stats, bool fit_texels) {
  std::vector<std::string> names;
  for (size_t m = 0; m < maps.size(); ++m) names.push_back("maps[" + std::to_string(m) + "]");
  return bake_named_maps(old_uvs, old_face_page, maps, names, new_uvs, new_face_page, out_sizes, normal_maps,
                         padding, progress, cancel, with_stats, fit_texels);
}

py::object bake_py(const py::object& old_uvs, const py::object& old_face_page, const py::list& images,
                   const py::object& new_uvs, const py::object& new_face_page, const py::object& out_sizes,
                   bool normal_map, const py::object& padding, const py::object& progress, const py::object& cancel,
                   bool with_stats, bool fit_texels) {
  py::list maps;
  maps.append(images);
  const py::object baked = bake_named_maps(old_uvs, old_face_page, maps, {"images"}, new_uvs, new_face_page,
                                           out_sizes, py::cast(std::vector<bool>{normal_map}), padding, progress,
                                           cancel, with_stats, fit_texels);
  if (!with_stats) return baked.cast<py::list>()[0];
  const py::tuple pair = baked.cast<py::tuple>();
  return py::make_tuple(pair[0].cast<py::list>()[0], pair[1]);
}

py::dict atlas_dict(const AtlasMeasures& m) {
  py::dict d;
  d["charts"] = m.charts;
  d["seam_ratio"] = m.seam_ratio;
  d["boundary_texels"] = m.boundary_texels;
  d["page_texels"] = m.page_texels;
  d["covered_texels"] = m.covered_texels;
  d["occupancy"] = m.occupancy;
  d["flipped_faces"] = m.flipped_faces;
  d["overlap_texels"] = m.overlap_texels;
  return d;
}

py::dict measure_py(const py::object& positions, const py::object& triangles, const py::object& old_uvs,
                    const py::object& old_face_page, const py::object& old_sizes, const py::object& new_uvs,
                    const py::object& new_face_page, const py::object& new_sizes, bool with_old) {
  const Mesh mesh = mesh_from(positions, triangles, old_uvs, old_face_page, page_sizes(old_sizes, "old_page_sizes"));
  const LayoutArrays new_l = layout_arrays(new_uvs, new_face_page, mesh.face_count(), "new_uvs", "new_face_page",
                                           page_sizes(new_sizes, "new_page_sizes"));
  const UvLayout old_atlas = layout_of(mesh);
  const UvLayout new_atlas = new_l.view();
  AtlasMeasures before, after;
  MapMeasures map;
  {
    py::gil_scoped_release release;
    const MeshTopology topology = build_topology(mesh.triangles, mesh.vertex_count());
    if (with_old) before = measure_atlas(mesh, topology, old_atlas);
    after = measure_atlas(mesh, topology, new_atlas);
    map = measure_map(mesh, old_atlas, new_atlas);
  }
  py::dict m;
  m["density_loss_area_share"] = map.density_loss_area_share;
  m["density_ratio_p5"] = map.density_ratio_p5;
  m["density_ratio_p50"] = map.density_ratio_p50;
  m["density_ratio_p95"] = map.density_ratio_p95;
  m["angle_error_p50"] = map.angle_error_p50;
  m["angle_error_p90"] = map.angle_error_p90;
  m["angle_error_p99"] = map.angle_error_p99;
  py::dict d;
  if (with_old) d["old"] = atlas_dict(before);
  d["new"] = atlas_dict(after);
  d["map"] = m;
  return d;
}

py::dict measure_atlas_py(const py::object& positions, const py::object& triangles, const py::object& uvs,
                          const py::object& face_page, const py::object& sizes) {
  const Mesh mesh = mesh_from(positions, triangles, uvs, face_page, page_sizes(sizes, "page_sizes"));
  AtlasMeasures measures;
  {
    py::gil_scoped_release release;
    measures = measure_atlas(mesh, build_topology(mesh.triangles, mesh.vertex_count()), layout_of(mesh));
  }
  return atlas_dict(measures);
}

std::vector<PageSize> image_sizes(const py::list& images, const char* name) {
  if (images.empty()) throw py::value_error(std::string(name) + " must not be empty");
  std::vector<PageSize> sizes;
  for (const auto& img : images) {
    const py::array a = py::array::ensure(img);
    if (!a || a.ndim() != 3) throw py::value_error(std::string(name) + " must be (H, W, C) arrays");
    sizes.push_back({static_cast<int>(a.shape(1)), static_cast<int>(a.shape(0))});
  }
  return sizes;
}

template <class T>
ColorFidelity compare_typed(const Mesh& mesh, const py::list& old_images, const UvLayout& new_atlas,
                            const py::list& new_images, int samples, unsigned seed, bool borders) {
  std::vector<py::array> keep;
  const auto old_views = image_views<T>(old_images, "old_images", keep);
  const auto new_views = image_views<T>(new_images, "new_images", keep);
  py::gil_scoped_release release;
  return compare_colors<T>(mesh, layout_of(mesh), old_views, new_atlas, new_views, samples, seed, borders);
}

py::dict compare_colors_py(const py::object& positions, const py::object& triangles, const py::object& old_uvs,
                           const py::object& old_face_page, const py::list& old_images, const py::object& new_uvs,
                           const py::object& new_face_page, const py::list& new_images, int samples, unsigned seed,
                           bool borders) {
  constexpr int kMaxSamples = 100'000'000;  // about a minute; far more than any figure needs
  if (samples > kMaxSamples) throw py::value_error("samples must be at most 100,000,000");
  const std::vector<PageSize> old_pages = image_sizes(old_images, "old_images");
  // The split takes old charts from welded vertices; the samples need no weld.
  const Mesh mesh = mesh_from(positions, triangles, old_uvs, old_face_page, old_pages, borders);
  const LayoutArrays new_l = layout_arrays(new_uvs, new_face_page, mesh.face_count(), "new_uvs", "new_face_page",
                                           image_sizes(new_images, "new_images"));
  const UvLayout new_atlas = new_l.view();
  const bool bytes = is_uint8_images(old_images, "old_images");
  if (bytes != is_uint8_images(new_images, "new_images")) throw py::value_error("old and new images must share a dtype");
  const ColorFidelity c =
      bytes ? compare_typed<std::uint8_t>(mesh, old_images, new_atlas, new_images, samples, seed, borders)
            : compare_typed<float>(mesh, old_images, new_atlas, new_images, samples, seed, borders);
  py::dict d;
  d["psnr_db"] = c.psnr_db;
  d["share_off_32"] = c.share_off_32;
  d["samples"] = c.samples;
  d["psnr_clean_db"] = c.psnr_clean_db;
  d["psnr_border_db"] = c.psnr_border_db;
  d["clean_share"] = c.samples > 0 ? static_cast<double>(c.clean_samples) / c.samples : 0.0;
  return d;
}

// Packs charts given in texels, as the pipeline does after flattening.
py::dict pack_charts_py(const py::list& charts, const py::object& options, const py::object& cancel) {
  std::vector<RowMatrixX2d> uv;
  for (size_t c = 0; c < charts.size(); ++c) {
    const std::string name = "charts[" + std::to_string(c) + "]";
    const auto a = checked<double>(charts[c], name.c_str(), {3, 2}, "(F_c, 3, 2)");
    uv.push_back(to_matrix<RowMatrixX2d>(a, 3 * a.shape(0), 2));
    if (!uv.back().allFinite() || (uv.back().size() && uv.back().cwiseAbs().maxCoeff() > kMaxTexelCoordinate))
      throw py::value_error(name + " has a corner that is no finite number or lies more than 2^30 texels from the "
                                   "origin");
  }
  const PackOptions o = pipeline_options(options).pack;
  const RunControl control = control_from(py::none(), cancel);
  PackResult r;
  {
    py::gil_scoped_release release;
    r = pack_charts(uv, o, control);
  }
  py::list placed;
  for (const RowMatrixX2d& p : r.placed_uv) placed.append(uv_array(p));
  py::dict out;
  out["uvs"] = placed;
  out["chart_page"] = py::array_t<int>(r.chart_page.size(), r.chart_page.data());
  out["page_sizes"] = sizes_array(r.pages);
  out["scale"] = r.scale;
  out["shrunk"] = r.shrunk;
  out["efficiency"] = r.efficiency;
  out["padding"] = r.padding;
  return out;
}

}  // namespace

PYBIND11_MODULE(_native, m) {
  m.doc() = "Atlas Defrag native core: chart aggregation, SLIM flattening, packing, baking and metrics.";
  py::register_exception<Cancelled>(m, "Cancelled");
  // A file the module could not write is an OSError with its errno, as
  // Python's own writes raise: callers handle a full disk one way.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const obj::FileError& e) {
      errno = e.error_number;
      PyErr_SetFromErrnoWithFilename(PyExc_OSError, e.path.c_str());
    }
  });

  py::class_<CancelToken>(m, "CancelToken", "Pass to a call; cancel() from any thread stops it early.")
      .def(py::init<>())
      .def("cancel", [](CancelToken& t) { t.flag->store(true); })
      .def_property_readonly("cancelled", [](const CancelToken& t) { return t.flag->load(); });

  m.def("defragment", &defragment_py, py::arg("positions"), py::arg("triangles"), py::arg("uvs"),
        py::arg("face_page"), py::arg("page_sizes"), py::kw_only(), py::arg("face_group") = py::none(),
        py::arg("face_polygon") = py::none(), py::arg("options") = py::none(), py::arg("progress") = py::none(),
        py::arg("cancel") = py::none(),
        R"(Computes a defragmented UV layout.

positions (V,3) float, triangles (F,3) int (quads and n-gons triangulated),
uvs (F,3,2) per-corner UVs in page units, face_page (F,) int (-1: untextured,
UVs pass through), page_sizes (P,2) (width, height) in texels. face_group (F,)
keeps groups apart. face_polygon (F,) int: the polygon each triangle comes
from; the border refinements move a polygon's triangles together or not at all
and the cuts run around polygons, so that each polygon corner keeps one UV.
Returns dict(uvs, face_page, page_sizes, report, charts, face_chart
(output chart per face, -1 untextured)); charts
holds per output chart: faces, flattened (else the input's UVs kept; a lone face's on a point or a line
moved a texel apart), energy_initial
and energy_final (symmetric Dirichlet per unit reference area, 4 = isometric).)");

  m.def("pack_charts", &pack_charts_py, py::arg("charts"), py::kw_only(), py::arg("options") = py::none(),
        py::arg("cancel") = py::none(),
        R"(Packs charts alone: charts is a list of (F_c,3,2) corner arrays in texels (any
placement); options takes the packing keys of defragment's options. Returns
dict(uvs: list of (F_c,3,2) in page units, chart_page, page_sizes, scale, shrunk
(scale below density_scale), efficiency, padding (texels used)).)");

  m.def("chart_graph", &chart_graph_py, py::arg("positions"), py::arg("triangles"), py::arg("uvs"),
        py::arg("face_page"), py::arg("page_sizes"), "The input's UV charts: counts and the chart of each face.");

  m.def("bake", &bake_py, py::arg("old_uvs"), py::arg("old_face_page"), py::arg("images"), py::arg("new_uvs"),
        py::arg("new_face_page"), py::arg("out_sizes"), py::kw_only(), py::arg("normal_map") = false,
        py::arg("padding") = 4, py::arg("progress") = py::none(), py::arg("cancel") = py::none(),
        py::arg("with_stats") = false, py::arg("fit_texels") = false,
        R"(Bakes one map through the new layout.

images: one (H,W,C) uint8 or float32 array per old page, row 0 at v = 0 (Blender's
order). Returns one array per entry of out_sizes (width, height), same dtype.
normal_map re-orients tangent-space XY per face. with_stats: returns (images,
dict(covered_texels, copied_texels, copied_share)), copied texels being taken
unresampled from the old texel they land on (faces moved by whole texels and
quarter turns only). fit_texels: texels fitted by least squares so that the new
page read bilinearly matches the old one read bilinearly, where faces are resampled
near 1:1, for two to three times the time (normal maps, copied texels and minified
faces keep their sampled values); False: each texel samples the old page at its centre.)");

  m.def("bake_maps", &bake_maps_py, py::arg("old_uvs"), py::arg("old_face_page"), py::arg("maps"),
        py::arg("new_uvs"), py::arg("new_face_page"), py::arg("out_sizes"), py::kw_only(),
        py::arg("normal_maps") = py::none(), py::arg("padding") = 4, py::arg("progress") = py::none(),
        py::arg("cancel") = py::none(), py::arg("with_stats") = false, py::arg("fit_texels") = false,
        R"(Bakes several maps of the same pages through the new layout in one pass.

maps: per map, one (H,W,C) uint8 or float32 array per old page (every map one
dtype; each map's images the same sizes as every other map's; channels may
differ). normal_maps: one flag per map (default all False). Returns per map one
array per entry of out_sizes; with_stats as bake, summed over the maps; fit_texels
as bake.)");

  m.def("read_obj", &read_obj_py, py::arg("path"),
        R"(Reads a Wavefront OBJ file: dict(positions (V,3) float64, texcoords (T,2) float64,
triangles (F,3) int32 0-based, texcoord_index (F,3) int32 (-1 on a face without UVs),
normals (N,3) float64, normal_index (F,3) int32 (-1 on a face without normals),
face_material (F,) int32 into materials (-1: none), materials (usemtl names),
material_libraries (mtllib names), vertex_colours (bool: a v line has r g b)). Names
are decoded as file names are (os.fsdecode). Convex polygons are fan-triangulated, others
clipped into ears in their plane. ValueError naming the line on malformed input, OSError
when the file cannot be read.)");

  m.def("write_obj", &write_obj_py, py::arg("path"), py::arg("library"), py::arg("positions"),
        py::arg("triangles"), py::arg("uvs"), py::arg("face_material"), py::arg("materials"),
        py::arg("normals") = py::none(), py::arg("normal_index") = py::none(),
        R"(Writes a Wavefront OBJ file: `mtllib library`, positions (V,3), one vt per face corner
of uvs (F,3,2), the normals (N,3) if given (a face names them through normal_index (F,3)
unless a corner of it has -1), and faces grouped by face_material (F,) in ascending order,
each group after `usemtl materials[m]`. Positions and normals exactly (shortest round
trip), UVs as %.9g.)");

  m.def("png_pixels", &png_pixels_py, py::arg("idat"), py::arg("width"), py::arg("height"),
        py::arg("channels"),
        R"(The pixels of a non-interlaced 8-bit RGB (channels 3) or RGBA (4) PNG from its IDAT
data (the chunks' bytes joined: one zlib stream of height rows of a filter byte and
width * channels bytes, top row first): (height, width, channels) uint8, row 0 at the
BOTTOM, as Blender stores images. ValueError on a broken stream, one holding more or fewer
bytes than the rows, or a bad filter byte.)");

  m.def("zlib_compress", &zlib_compress_py, py::arg("data"), py::arg("level") = 1,
        R"(data (a flat byte buffer) as one zlib stream (RFC 1950), uint8 (n,), at level 1
(the fastest) .. 12 (the smallest; 0 stores the bytes). One thread; the GIL is released,
so several calls run side by side.)");

  m.def("bytes_from_unit_floats", &bytes_from_unit_floats_py, py::arg("values"), py::arg("kept") = 0,
        R"(uint8 pixels of values (float32, (..., C)): v * 255 + 0.5 truncated, clamped to 0-255,
in float32 arithmetic, so b / 255 gives b back. Only the first `kept` channels (0: all)
when the others are filler as Blender fills the channels a file lacks (colour channels
repeating the last kept one, alpha 255), else all C. Runs on all cores.)");

  m.def("measure", &measure_py, py::arg("positions"), py::arg("triangles"), py::arg("old_uvs"),
        py::arg("old_face_page"), py::arg("old_page_sizes"), py::arg("new_uvs"), py::arg("new_face_page"),
        py::arg("new_page_sizes"), py::kw_only(), py::arg("with_old") = true,
        R"(Metrics of the old and new atlases and of the map between them: dict(old, new, map);
with_old=False leaves out "old" (measure_atlas gives it on its own).)");

  m.def("measure_atlas", &measure_atlas_py, py::arg("positions"), py::arg("triangles"), py::arg("uvs"),
        py::arg("face_page"), py::arg("page_sizes"),
        "Metrics of one atlas, as measure gives them for the old or the new one.");

  m.def("compare_colors", &compare_colors_py, py::arg("positions"), py::arg("triangles"), py::arg("old_uvs"),
        py::arg("old_face_page"), py::arg("old_images"), py::arg("new_uvs"), py::arg("new_face_page"),
        py::arg("new_images"), py::kw_only(), py::arg("samples") = 400000, py::arg("seed") = 1,
        py::arg("borders") = true,
        R"(PSNR and share of points off by more than 32/255, on points drawn uniformly by
surface area; also PSNR on clean points (all four bilinear texels of the old atlas
inside the point's own old chart: clean_share of them) and on the border rest, or
NaN for both with borders=False, which saves rastering the old atlas.)");
}
