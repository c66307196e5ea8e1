// SLIM (Rabinovich et al. 2017) on the symmetric Dirichlet energy of the map
// from each face's reference triangle to its new UV triangle (thesis 5.3.1, 5.4):
//   E(u) = sum_f A_ref(f) psi(J_f(u)),  psi(J) = s1^2 + s2^2 + s1^-2 + s2^-2.
// Each iteration solves one sparse SPD system whose pattern never changes, so
// the symbolic Cholesky analysis is done once per chart and every iteration
// costs little more than one numeric factorization. (SCAF, the fallback for
// charts whose boundary crosses itself, changes the pattern with its scaffold.)
// A density repair may follow: faces left squeezed to area ratio r = det J_f
// below a floor weigh w_f = factor * floor / r times more, E_w = sum_f w_f
// A_ref(f) psi(J_f), and the solve goes on (SlimOptions::repair_rounds).
#include "flatten/slim.hpp"

#include <Eigen/LU>
#include <Eigen/OrderingMethods>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <vector>

#include "core/corners.hpp"
#include "core/geometry.hpp"
#include "core/segment_crossing.hpp"
#include "flatten/disk_boundary.hpp"
#include "flatten/sparse_cholesky.hpp"
#include "flatten/reference_triangles.hpp"
#include "flatten/scaffold_triangulation.hpp"
#include "flatten/symmetric_dirichlet.hpp"
#include "flatten/tutte_embedding.hpp"

namespace atlas {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Take this fraction of the step at which the first triangle degenerates: the
// energy is infinite there, so the full step would never pass the line search.
constexpr double kSafeStepFraction = 0.8;
// Armijo sufficient decrease: E(x + t d) <= E(x) + kArmijo t dE/dt.
constexpr double kArmijo = 1e-4;
// 2^-30 of a step no longer moves a vertex by anything measurable.
constexpr int kMaxHalvings = 30;

// One face in solver numbering. Unknowns are interleaved, (x, y) of a vertex
// side by side at dof and dof + 1, so each vertex is a 2x2 block.
struct ProxyFace {
  int dof[3];
  double area;                    // weight: the reference area (a scaffold face: its share, see SCAF)
  Eigen::Matrix2d inverse_edges;  // [r1 - r0, r2 - r0]^-1, so J = [u1 - u0, u2 - u0] inverse_edges
  double stiffness[6];            // area g_k.g_l for (k,l) = (0,1), (1,2), (2,0), (0,0), (1,1), (2,2)
  int slot[21];                   // where those 6 blocks go in the matrix values, see assemble_proxy
};

// J = sum_k u_k g_k^T with g_1, g_2 the rows of inverse_edges and g_0 = -g_1 - g_2.
Eigen::Vector2d corner_gradient(const ProxyFace& face, int k) {
  if (k == 0) return -(face.inverse_edges.row(0) + face.inverse_edges.row(1)).transpose();
  return face.inverse_edges.row(k - 1).transpose();
}

Eigen::Matrix2d edge_matrix(const ProxyFace& face, const Eigen::VectorXd& x) {
  Eigen::Matrix2d edges;
  edges << x[face.dof[1]] - x[face.dof[0]], x[face.dof[2]] - x[face.dof[0]],
      x[face.dof[1] + 1] - x[face.dof[0] + 1], x[face.dof[2] + 1] - x[face.dof[0] + 1];
  return edges;
}

Eigen::Matrix2d jacobian(const ProxyFace& face, const Eigen::VectorXd& x) {
  return edge_matrix(face, x) * face.inverse_edges;
}

// The SLIM global step, (H + lambda I) x = b. The pattern is fixed, and only
// the upper triangle is stored, already in fill-reducing order: the solver
// factorizes it in place.
struct ProxySystem {
  Eigen::SparseMatrix<double> matrix;
  std::vector<int> diagonal_slots;
  SparseCholesky solver;
  Eigen::VectorXd rhs, solution;
  double factorize_seconds = 0;  // in numeric factorizations, summed
};

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The vertices joined to each vertex by a face edge, ascending, without
// repeats: those of v are neighbour[start[v] .. start[v + 1]). corner(f, k)
// gives the vertex at corner k of face f; a face's three corners differ.
struct VertexNeighbours {
  std::vector<int> start, neighbour;
};

template <class Corner>
VertexNeighbours vertex_neighbours(size_t face_count, int vertex_count, Corner corner) {
  VertexNeighbours near;
  near.start.assign(vertex_count + 1, 0);
  for (size_t f = 0; f < face_count; ++f)
    for (int k = 0; k < 3; ++k) near.start[corner(f, k) + 1] += 2;
  for (int v = 0; v < vertex_count; ++v) near.start[v + 1] += near.start[v];
  near.neighbour.resize(near.start[vertex_count]);
  std::vector<int> fill(near.start.begin(), near.start.end() - 1);
  for (size_t f = 0; f < face_count; ++f)
    for (int k = 0; k < 3; ++k) {
      const int a = corner(f, k), b = corner(f, (k + 1) % 3);
      near.neighbour[fill[a]++] = b, near.neighbour[fill[b]++] = a;
    }
  // Sorted and deduplicated in place, then packed.
  int kept = 0;
  for (int v = 0; v < vertex_count; ++v) {
    const auto begin = near.neighbour.begin() + near.start[v], end = near.neighbour.begin() + near.start[v + 1];
    std::sort(begin, end);
    near.start[v] = kept;
    kept = static_cast<int>(std::copy(begin, std::unique(begin, end), near.neighbour.begin() + kept) -
                            near.neighbour.begin());
  }
  near.start[vertex_count] = kept;
  near.neighbour.resize(kept);
  return near;
}

// Fill-reducing (AMD) order of the vertex graph: x and y of a vertex always
// couple, so ordering vertices and interleaving costs 4x less than ordering
// the 2n unknowns, for the same fill. Returns the new index of each vertex.
std::vector<int> fill_reducing_order(const RowMatrixX3i& triangles, int vertex_count) {
  const VertexNeighbours near = vertex_neighbours(static_cast<size_t>(triangles.rows()), vertex_count,
                                                  [&](size_t f, int k) { return triangles(f, k); });
  // The graph with its diagonal, built compressed: AMD reads only the pattern.
  Eigen::SparseMatrix<double> graph(vertex_count, vertex_count);
  graph.resizeNonZeros(static_cast<Eigen::Index>(near.neighbour.size()) + vertex_count);
  int* outer = graph.outerIndexPtr();
  int* inner = graph.innerIndexPtr();
  std::fill(graph.valuePtr(), graph.valuePtr() + graph.nonZeros(), 1.0);
  int at = 0;
  for (int v = 0; v < vertex_count; ++v) {
    outer[v] = at;
    const int* begin = near.neighbour.data() + near.start[v];
    const int* end = near.neighbour.data() + near.start[v + 1];
    const int* below = std::lower_bound(begin, end, v);
    at = static_cast<int>(std::copy(begin, below, inner + at) - inner);
    inner[at++] = v;
    at = static_cast<int>(std::copy(below, end, inner + at) - inner);
  }
  outer[vertex_count] = at;
  // Eigen's orderings return P^-1; P sends vertex v to row P(v).
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse;
  Eigen::AMDOrdering<int>()(graph, inverse);
  const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> order = inverse.inverse();
  return std::vector<int>(order.indices().data(), order.indices().data() + vertex_count);
}

// Positions in solver numbering, (x, y) of vertex v at 2 order[v], and back.
Eigen::VectorXd to_solver(const RowMatrixX2d& points, const std::vector<int>& order) {
  Eigen::VectorXd x(2 * points.rows());
  for (Eigen::Index v = 0; v < points.rows(); ++v) x.segment<2>(2 * order[v]) = points.row(v).transpose();
  return x;
}

RowMatrixX2d from_solver(const Eigen::VectorXd& x, const std::vector<int>& order) {
  RowMatrixX2d points(x.size() / 2, 2);
  for (Eigen::Index v = 0; v < points.rows(); ++v) points.row(v) = x.segment<2>(2 * order[v]).transpose();
  return points;
}

// One face of the proxy, weight |W (J - R)|^2, J measured against the
// reference triangle whose edge matrix inverts to inverse_edges, the face
// weighing `weight`; its matrix slots are left as they were.
void set_face_reference(const Eigen::Matrix2d& inverse_edges, double weight, ProxyFace& face) {
  face.area = weight;
  face.inverse_edges = inverse_edges;
  const Eigen::Vector2d g[3] = {corner_gradient(face, 0), corner_gradient(face, 1), corner_gradient(face, 2)};
  for (int e = 0; e < 3; ++e) {
    face.stiffness[e] = weight * g[e].dot(g[(e + 1) % 3]);
    face.stiffness[3 + e] = weight * g[e].squaredNorm();
  }
}

void set_proxy_face(const Eigen::Vector3i& corners, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                    const Eigen::Vector2d& c, double weight, const std::vector<int>& order, ProxyFace& face) {
  for (int k = 0; k < 3; ++k) face.dof[k] = 2 * order[corners[k]];
  Eigen::Matrix2d edges;
  edges << b - a, c - a;
  set_face_reference(edges.inverse(), weight, face);
}

// The chart's faces, each weighted by its reference area.
std::vector<ProxyFace> proxy_faces(const RowMatrixX3i& triangles, const RowMatrixX2d& reference,
                                   const std::vector<int>& order) {
  std::vector<ProxyFace> faces(triangles.rows());
  for (Eigen::Index f = 0; f < triangles.rows(); ++f) {
    const Eigen::Vector2d a = reference.row(3 * f), b = reference.row(3 * f + 1), c = reference.row(3 * f + 2);
    set_proxy_face(triangles.row(f), a, b, c, signed_area(a, b, c), order, faces[f]);
  }
  return faces;
}

// Builds the pattern, records every face's value slots and runs the symbolic
// analysis: all the per-chart work that the iterations then reuse. Vertex w
// (dofs 2w, 2w + 1) couples with its neighbours u < w through full 2x2
// blocks, so the upper triangle's column 2w holds rows 2u, 2u + 1 for each
// such u, ascending, then 2w; column 2w + 1 the same rows, then 2w, 2w + 1.
// Every vertex is on a face (disk_boundary_loop refuses any other).
void prepare_proxy_system(std::vector<ProxyFace>& faces, int dof_count, ProxySystem& system) {
  const int vertex_count = dof_count / 2;
  const VertexNeighbours near =
      vertex_neighbours(faces.size(), vertex_count, [&](size_t f, int k) { return faces[f].dof[k] / 2; });
  std::vector<int> below(vertex_count);  // neighbours below w: the first below[w] of its list
  for (int w = 0; w < vertex_count; ++w)
    below[w] = static_cast<int>(std::lower_bound(near.neighbour.begin() + near.start[w],
                                                 near.neighbour.begin() + near.start[w + 1], w) -
                                (near.neighbour.begin() + near.start[w]));
  std::vector<int> outer(dof_count + 1, 0);
  for (int w = 0; w < vertex_count; ++w) {
    outer[2 * w + 1] = outer[2 * w] + 2 * below[w] + 1;
    outer[2 * w + 2] = outer[2 * w + 1] + 2 * below[w] + 2;
  }
  system.matrix.resize(dof_count, dof_count);
  system.matrix.resizeNonZeros(outer[dof_count]);
  std::copy(outer.begin(), outer.end(), system.matrix.outerIndexPtr());
  int* inner = system.matrix.innerIndexPtr();
  for (int w = 0; w < vertex_count; ++w)
    for (int column = 2 * w; column <= 2 * w + 1; ++column) {
      int at = outer[column];
      for (int j = 0; j < below[w]; ++j) {
        const int u = near.neighbour[near.start[w] + j];
        inner[at++] = 2 * u, inner[at++] = 2 * u + 1;
      }
      for (int row = 2 * w; at < outer[column + 1]; ++row) inner[at++] = row;
    }
  // Slots in the order assemble_proxy writes them: for each edge (k, l) the
  // 2x2 block between the two vertices (the lower dof gives the rows), then
  // for each corner the 3 upper entries of its diagonal block.
  for (ProxyFace& face : faces) {
    int* slot = face.slot;
    for (int e = 0; e < 3; ++e) {
      const int lo = std::min(face.dof[e], face.dof[(e + 1) % 3]), hi = std::max(face.dof[e], face.dof[(e + 1) % 3]);
      const int* list = near.neighbour.data() + near.start[hi / 2];
      const int rank = 2 * static_cast<int>(std::lower_bound(list, list + below[hi / 2], lo / 2) - list);
      const int a = outer[hi] + rank, b = outer[hi + 1] + rank;
      *slot++ = a, *slot++ = b, *slot++ = a + 1, *slot++ = b + 1;
    }
    for (const int d : face.dof) {
      const int a = outer[d] + 2 * below[d / 2], b = outer[d + 1] + 2 * below[d / 2];
      *slot++ = a, *slot++ = b, *slot++ = b + 1;
    }
  }
  system.diagonal_slots.resize(dof_count);
  for (int i = 0; i < dof_count; ++i) system.diagonal_slots[i] = outer[i + 1] - 1;
  system.solver.analyze(system.matrix);
  system.rhs.resize(dof_count);
  system.solution.resize(dof_count);
}

// Local step and assembly. Per face, with R and M = W^2 from slim_proxy_target,
// A |W (J - R)|_F^2 = sum_kl A g_k.g_l u_k^T M u_l - 2 sum_k A u_k^T M R g_k + const,
// so block (k,l) of H is stiffness_kl M and b_k = A M R g_k. M is symmetric, so
// a block and its transpose are equal and either can be stored. The proximal
// term lambda |x - x_k|^2 adds lambda I and lambda x_k: it pins the translation
// the energy does not see.
void assemble_proxy(const std::vector<ProxyFace>& faces, const std::vector<Eigen::Matrix2d>& jacobians,
                    const Eigen::VectorXd& x, double proximal_weight, ProxySystem& system) {
  double* values = system.matrix.valuePtr();
  std::fill(values, values + system.matrix.nonZeros(), 0.0);
  system.rhs = proximal_weight * x;
  for (size_t f = 0; f < faces.size(); ++f) {
    const ProxyFace& face = faces[f];
    const SlimProxyTarget target = slim_proxy_target(jacobians[f]);
    const Eigen::Matrix2d& M = target.weight;
    const int* slot = face.slot;
    for (int e = 0; e < 3; ++e) {
      const double c = face.stiffness[e];
      values[*slot++] += c * M(0, 0), values[*slot++] += c * M(0, 1);
      values[*slot++] += c * M(1, 0), values[*slot++] += c * M(1, 1);
    }
    for (int k = 0; k < 3; ++k) {
      const double c = face.stiffness[3 + k];
      values[*slot++] += c * M(0, 0), values[*slot++] += c * M(0, 1), values[*slot++] += c * M(1, 1);
    }
    const Eigen::Matrix2d target_map = face.area * M * target.rotation;
    for (int k = 0; k < 3; ++k) system.rhs.segment<2>(face.dof[k]) += target_map * corner_gradient(face, k);
  }
  for (int slot : system.diagonal_slots) values[slot] += proximal_weight;
}

// Assembles and factorizes the proxy. Near-degenerate faces get huge SLIM
// weights, and round-off can then break the Cholesky factorization of a large
// chart: each retry strengthens the proximal term (scaled to the mean diagonal),
// which keeps the system definite and only shortens the step.
bool factorize_proxy(const std::vector<ProxyFace>& faces, const std::vector<Eigen::Matrix2d>& jacobians,
                     const Eigen::VectorXd& x, double proximal_weight, ProxySystem& system) {
  for (int attempt = 0; attempt < 4; ++attempt) {
    assemble_proxy(faces, jacobians, x, proximal_weight, system);
    const auto start = std::chrono::steady_clock::now();
    const bool factorized = system.solver.factorize(system.matrix);
    system.factorize_seconds += seconds_since(start);
    if (factorized) return true;
    double diagonal = 0;
    for (int slot : system.diagonal_slots) diagonal += system.matrix.valuePtr()[slot];
    proximal_weight = std::max(100 * proximal_weight, 1e-6 * diagonal / system.diagonal_slots.size());
  }
  return false;
}

// energy + sum_f A_f psi(J_f) over faces [begin, end), summed in order; +inf
// as soon as one face flips or degenerates.
double partial_energy(const std::vector<ProxyFace>& faces, size_t begin, size_t end, const Eigen::VectorXd& x,
                      double energy) {
  for (size_t f = begin; f < end; ++f) {
    energy += faces[f].area * symmetric_dirichlet_density(jacobian(faces[f], x));
    if (!(energy < kInfinity)) return kInfinity;
  }
  return energy;
}

double total_energy(const std::vector<ProxyFace>& faces, const Eigen::VectorXd& x) {
  return partial_energy(faces, 0, faces.size(), x, 0);
}

// Smallest t > 0 with a t^2 + b t + c = 0, for c > 0 (+inf if none), using
// the cancellation-free form of the roots.
double first_positive_root(double a, double b, double c) {
  if (a >= 0 && b >= 0) return kInfinity;  // every term is positive for t > 0
  if (a == 0) return b < 0 ? -c / b : kInfinity;
  const double discriminant = b * b - 4 * a * c;
  if (discriminant < 0) return kInfinity;
  const double q = -0.5 * (b + std::copysign(std::sqrt(discriminant), b));
  double t = kInfinity;
  for (const double root : {q / a, c / q})
    if (root > 0) t = std::min(t, root);
  return t;
}

// J_f at x for every face.
std::vector<Eigen::Matrix2d> face_jacobians(const std::vector<ProxyFace>& faces, const Eigen::VectorXd& x) {
  std::vector<Eigen::Matrix2d> jacobians(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) jacobians[f] = jacobian(faces[f], x);
  return jacobians;
}

// J is linear in the positions, so along x + t d each face's Jacobian is
// J + t dJ with dJ = J_f(d): the line search needs neither x nor d again.
struct SearchLine {
  std::vector<Eigen::Matrix2d> moves;  // dJ per face
  double slope = 0;                    // dE/dt at t = 0, sum_f A_f psi'(J_f; dJ_f)
  double max_step = kInfinity;         // first t at which some triangle degenerates
};

// A face degenerates where det(J + t dJ), a quadratic in t, first reaches 0
// (Smith and Schaefer 2015).
SearchLine search_line(const std::vector<ProxyFace>& faces, const std::vector<Eigen::Matrix2d>& jacobians,
                       const Eigen::VectorXd& d) {
  SearchLine line;
  line.moves.resize(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    const Eigen::Matrix2d& J = jacobians[f];
    const Eigen::Matrix2d dJ = jacobian(faces[f], d);
    line.moves[f] = dJ;
    line.slope += faces[f].area * symmetric_dirichlet_rate(J, dJ);
    line.max_step =
        std::min(line.max_step, first_positive_root(dJ.determinant(), determinant_rate(J, dJ), J.determinant()));
  }
  return line;
}

// E(x + t d) = sum_f A_f psi(J_f + t dJ_f); +inf as soon as one face flips.
double energy_along(const std::vector<ProxyFace>& faces, const std::vector<Eigen::Matrix2d>& jacobians,
                    const SearchLine& line, double t) {
  double energy = 0;
  for (size_t f = 0; f < faces.size(); ++f) {
    energy += faces[f].area * symmetric_dirichlet_density(jacobians[f] + t * line.moves[f]);
    if (!(energy < kInfinity)) return kInfinity;
  }
  return energy;
}

int flipped_faces(const std::vector<ProxyFace>& faces, const Eigen::VectorXd& x) {
  int count = 0;
  for (const ProxyFace& face : faces) count += !(edge_matrix(face, x).determinant() > 0);
  return count;
}

SolveStatus input_problem(const ChartProblem& problem) {
  std::ostringstream msg;
  const Eigen::Index face_count = problem.triangles.rows();
  if (problem.reference_uv.rows() != 3 * face_count)
    msg << "reference_uv must hold 3 rows per face: expected " << 3 * face_count << ", got "
        << problem.reference_uv.rows();
  else if (problem.mirrored.size() != face_count)
    msg << "mirrored must hold one entry per face: expected " << face_count << ", got " << problem.mirrored.size();
  else
    return {};
  return solve_failed(SolveFailure::bad_input, msg.str());
}

// Armijo backtracking, E(x + t d) <= E(x) + kArmijo t dE/dt, halving t from
// the largest safe flip-free step. Returns t and sets energy to E(x + t d),
// or returns 0 if no step passed (the energy is flat at double precision).
double backtracking_line_search(const std::vector<ProxyFace>& faces, const std::vector<Eigen::Matrix2d>& jacobians,
                                const SearchLine& line, double& energy) {
  double step = std::min(1.0, kSafeStepFraction * line.max_step);
  for (int halving = 0; halving <= kMaxHalvings; ++halving, step /= 2) {
    const double trial_energy = energy_along(faces, jacobians, line, step);
    if (trial_energy <= energy + kArmijo * step * line.slope) {
      energy = trial_energy;
      return step;
    }
  }
  return 0;
}

// One SLIM iteration from x: proxy solve, then the flip-free Armijo line
// search. Each face's Jacobian is evaluated once: the assembly, the slope, the
// largest step and every trial read J and dJ, not the positions, so little
// besides the factorization grows with the chart (the benchmark reports the
// ratio). status says whether the solve broke down; moved is false when no
// step was taken (no descent direction or no acceptable step: converged at
// double precision), else x and energy hold the new iterate.
struct SlimStep {
  SolveStatus status;
  bool moved = false;
};

SlimStep slim_step(const std::vector<ProxyFace>& faces, const SlimOptions& options, ProxySystem& system,
                   Eigen::VectorXd& x, double& energy) {
  const std::vector<Eigen::Matrix2d> jacobians = face_jacobians(faces, x);
  // The line search kept J + t dJ flip-free; x itself is checked against
  // round-off before anything is built on it.
  if (std::any_of(jacobians.begin(), jacobians.end(), [](const Eigen::Matrix2d& J) { return !(J.determinant() > 0); }))
    return {solve_failed(SolveFailure::round_off, "SLIM: a step flipped a face in round-off")};
  if (!factorize_proxy(faces, jacobians, x, options.proximal_weight, system))
    return {solve_failed(SolveFailure::system, "SLIM: proxy system is not positive definite")};
  system.solver.solve(system.rhs, system.solution);
  const Eigen::VectorXd direction = system.solution - x;
  if (!direction.allFinite()) return {solve_failed(SolveFailure::system, "SLIM: proxy solve produced non-finite values")};
  const SearchLine line = search_line(faces, jacobians, direction);
  if (!(line.slope < 0)) return {};
  const double step = backtracking_line_search(faces, jacobians, line, energy);
  if (step == 0) return {};
  x += step * direction;
  return {{}, true};
}

// Progressive references (after Liu et al. 2018, "Progressive
// Parameterizations"). From a Tutte start a few faces are nearly degenerate,
// their SLIM weights dwarf the rest, and every step stops where one of them
// would flip. So the solve first aims at intermediate references: with
// J = U S V^T the map from a face's reference to its current triangle, the
// intermediate reference is V S^(1-t) V^T applied to the reference, so the map
// from it is U S^t V^T. One t in (0, 1] serves every face: the largest with
// psi(S^t) <= bound on all of them. As the map improves t grows, and at t = 1
// the references are the real ones.

// The t in (0, upper] with psi(diag(s1, s2)^t) <= bound, largest, for a face:
// psi(S^t) = 2 cosh(t a) + 2 cosh(t b), a = 2 ln s1, b = 2 ln s2, grows with
// t, and Newton from above comes down to the root without overshooting (psi
// is convex in t). A face within the bound at upper keeps upper.
double exponent_at_bound(double s1, double s2, double bound, double upper) {
  const double a = 2 * std::log(s1), b = 2 * std::log(s2);
  double t = upper;
  for (int k = 0; k < 50; ++k) {
    const double value = 2 * std::cosh(t * a) + 2 * std::cosh(t * b) - bound;
    const double rate = 2 * a * std::sinh(t * a) + 2 * b * std::sinh(t * b);
    if (!(rate > 0) || value < 1e-6 * bound) break;
    t -= value / rate;
  }
  return std::clamp(t, 0.0, upper);
}

// The largest t with psi(S_f^t) <= bound on every face (1 when all are within).
double progressive_exponent(const std::vector<Eigen::Matrix2d>& jacobians, double bound) {
  double t = 1;
  for (const Eigen::Matrix2d& J : jacobians)
    if (symmetric_dirichlet_density(J) > bound) {
      const SimilaritySplit s = similarity_split(J);
      t = exponent_at_bound(s.largest(), s.smallest(), bound, t);
    }
  return t;
}

// Each face of `intermediate` gets its intermediate reference for exponent t,
// from the real one in `faces`: inverse_edges V S^(t-1) V^T, where
// V S^(t-1) V^T = (J^T J)^((t-1)/2) = alpha I + beta J^T J for the eigenvalues
// l1, l2 of J^T J, beta = (f(l1) - f(l2)) / (l1 - l2), alpha = f(l1) - beta l1.
void set_intermediate_references(const std::vector<ProxyFace>& faces, const std::vector<Eigen::Matrix2d>& jacobians,
                                 double t, std::vector<ProxyFace>& intermediate) {
  for (size_t f = 0; f < faces.size(); ++f) {
    const Eigen::Matrix2d& J = jacobians[f];
    const SimilaritySplit s = similarity_split(J);
    const double s1 = s.largest(), s2 = s.smallest();
    const double l1 = s1 * s1, l2 = s2 * s2;
    const double f1 = std::pow(s1, t - 1), f2 = std::pow(s2, t - 1);
    const double beta = l1 - l2 > 1e-12 * l1 ? (f1 - f2) / (l1 - l2) : 0;
    const double alpha = f1 - beta * l1;
    const Eigen::Matrix2d root = alpha * Eigen::Matrix2d::Identity() + beta * J.transpose() * J;
    set_face_reference(faces[f].inverse_edges * root, faces[f].area, intermediate[f]);
  }
}

// Whether the boundary loop (the dof of each loop vertex, in order) crosses itself at x.
bool loop_crosses(const std::vector<int>& loop_dofs, const Eigen::VectorXd& x) {
  const int n = static_cast<int>(loop_dofs.size());
  std::vector<Eigen::Vector2d> points(n);
  std::vector<Segment> segments(n);
  for (int i = 0; i < n; ++i) points[i] = x.segment<2>(loop_dofs[i]), segments[i] = {i, (i + 1) % n};
  return first_crossing(points, segments).has_value();
}

// The progressive stage of a solve: faces aim at intermediate references
// while on. It ends at t = 1, or when it stalls short of it: some face of the
// best map then exceeds the bound, and the real references take over. The
// first iterations may not stall it: from a Tutte start t and the energy can
// stand still for a while before the worst faces open up, and ending the
// stage there leaves charts that lose density (measured on the shared scans).
constexpr int kMinProgressiveIterations = 15;
struct ProgressiveStage {
  bool on = false;
  double t = 1, t_before = 0;
  std::vector<ProxyFace> intermediate;
};

// One SLIM step from x towards the references the stage gives (the
// intermediate ones while stage.on stays true); energy is the real energy,
// before and after.
SlimStep progressive_step(const std::vector<ProxyFace>& faces, const SlimOptions& options, ProxySystem& system,
                          ProgressiveStage& stage, Eigen::VectorXd& x, double& energy) {
  stage.t = 1;
  if (stage.on) {
    const std::vector<Eigen::Matrix2d> jacobians = face_jacobians(faces, x);
    stage.t = progressive_exponent(jacobians, options.progressive_bound);
    stage.on = stage.t < 1;
    if (stage.on) set_intermediate_references(faces, jacobians, stage.t, stage.intermediate);
  }
  if (!stage.on) return slim_step(faces, options, system, x, energy);
  double intermediate_energy = total_energy(stage.intermediate, x);
  const SlimStep step = slim_step(stage.intermediate, options, system, x, intermediate_energy);
  energy = total_energy(faces, x);
  return step;
}

// Whether the solve is done after an iteration that took the energy from
// before to after; ends a stalled progressive stage.
bool converged(double before, double after, int iterations, const SlimOptions& options, ProgressiveStage& stage) {
  const double decrease = (before - after) / before;
  if (!stage.on) return decrease < options.relative_tolerance;
  const bool stalled = std::abs(decrease) < options.relative_tolerance &&
                       stage.t < (1 + options.relative_tolerance) * stage.t_before;
  if (iterations >= kMinProgressiveIterations && stalled) stage.on = false;
  stage.t_before = stage.t;
  return false;
}

// Minimizes E from x (flip-free, in solver numbering, with E(x) = energy),
// keeping x flip-free.
// system holds the pattern of faces (prepare_proxy_system), reused across calls.
// With a loop given, a step after which the boundary crosses itself is undone
// and crossed is set: the caller goes on with a scaffold. Returns why it
// stopped early, if it did; x is the last accepted iterate either way.
SolveStatus minimize_energy(std::vector<ProxyFace>& faces, ProxySystem& system, const std::vector<int>& loop_dofs,
                            const SlimOptions& options, const RunControl& control, Eigen::VectorXd& x,
                            double energy, ChartSolution& solution, bool& crossed) {
  Eigen::VectorXd previous;
  ProgressiveStage stage;
  stage.on = options.progressive_bound > 0;
  if (stage.on) stage.intermediate = faces;
  for (int iterations = 0; iterations < options.max_iterations;) {
    control.throw_if_cancelled();
    if (!loop_dofs.empty()) previous = x;
    const double energy_before = energy;
    const auto start = std::chrono::steady_clock::now();
    const double factorized_before = system.factorize_seconds;
    const SlimStep step = progressive_step(faces, options, system, stage, x, energy);
    solution.iteration_seconds += seconds_since(start);
    solution.factorize_seconds += system.factorize_seconds - factorized_before;
    if (!step.status.ok()) return step.status;
    if (!step.moved) {
      if (!stage.on) return {};
      stage.on = false;  // the intermediate problem is solved: on to the real one
      continue;
    }
    if (!loop_dofs.empty() && loop_crosses(loop_dofs, x)) {
      x.swap(previous);
      crossed = true;
      return {};
    }
    ++iterations, ++solution.iterations;
    if (converged(energy_before, energy, iterations, options, stage)) return {};
  }
  return {};
}

// The chart and its scaffold as one problem. Scaffold triangles take their
// current shape as reference, so they pull nowhere but resist being squashed,
// without bound as they degenerate. As in SCAF each weighs the same, a share
// of the chart's energy, so thin ones near the boundary stiffen first; an area
// weight would make exactly those the weakest.
constexpr double kScaffoldWeight = 1e-2;
constexpr double kScaffoldMargin = 1.0;
// The free space is triangulated again every few iterations, not every one:
// in between the old scaffold stays valid (the line search keeps it
// flip-free), and the ordering and symbolic analysis are reused.
constexpr int kRemeshEvery = 8;
// SCAF's steps are short, so it stops at 0.3 of SLIM's relative tolerance;
// a tenth bought few charts for much more time (bench/README.md).
constexpr double kScaffoldToleranceFactor = 0.3;

// Rewrites the scaffold faces (those after the chart's, in `faces`) with their
// current shape as reference and the given weight each; slots stay.
void reset_scaffold_faces(const RowMatrixX3i& all, const RowMatrixX2d& points, double weight,
                          const std::vector<int>& order, Eigen::Index chart_faces, std::vector<ProxyFace>& faces) {
  for (Eigen::Index t = chart_faces; t < all.rows(); ++t)
    set_proxy_face(all.row(t), points.row(all(t, 0)), points.row(all(t, 1)), points.row(all(t, 2)), weight, order,
                   faces[t]);
}

// SCAF (Jiang et al. 2017): SLIM iterations on the chart plus a scaffold of
// the free space around it, so the boundary never crosses itself. uv (chart
// vertices, flip-free, boundary not crossing) is updated in place.
SolveStatus minimize_with_scaffold(const RowMatrixX3i& triangles, const RowMatrixX2d& reference,
                                   const std::vector<ProxyFace>& chart_faces, const std::vector<int>& chart_order,
                                   const std::vector<int>& loop, const SlimOptions& options,
                                   const RunControl& control, RowMatrixX2d& uv, ChartSolution& solution) {
  const int n = static_cast<int>(uv.rows());
  // The chart's faces come first in `faces`, with the chart's references, so
  // the chart's energy is also the first part of the sum over all faces.
  const size_t chart_face_count = static_cast<size_t>(triangles.rows());
  double energy_before = total_energy(chart_faces, to_solver(uv, chart_order));
  RowMatrixX2d points(n + 4, 2);
  RowMatrixX3i all;
  std::vector<int> order;
  std::vector<ProxyFace> faces;
  std::optional<ProxySystem> system;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    control.throw_if_cancelled();
    Scaffold scaffold;
    // A rebuild that finds no ear (round-off, where the boundary nearly
    // touches itself) keeps the old scaffold: the line search kept it valid.
    const bool remesh = iteration % kRemeshEvery == 0 && triangulate_scaffold(uv, loop, kScaffoldMargin, scaffold);
    if (iteration == 0 && !remesh)
      return solve_failed(SolveFailure::scaffold, "SCAF: no scaffold around the starting boundary");
    if (remesh) {
      points << uv, scaffold.box_corners;
      all.resize(triangles.rows() + scaffold.triangles.rows(), 3);
      all << triangles, scaffold.triangles;
      order = fill_reducing_order(all, n + 4);
      faces = proxy_faces(triangles, reference, order);
      for (size_t f = 0; f < chart_face_count; ++f)  // the weights the density repair gave
        set_face_reference(faces[f].inverse_edges, chart_faces[f].area, faces[f]);
      faces.resize(all.rows());
    }
    const double weight = kScaffoldWeight * energy_before / static_cast<double>(all.rows() - triangles.rows());
    reset_scaffold_faces(all, points, weight, order, triangles.rows(), faces);
    if (remesh) {
      system.emplace();
      prepare_proxy_system(faces, 2 * (n + 4), *system);  // the pattern needs every face's corners
    }
    Eigen::VectorXd x = to_solver(points, order);
    double energy = partial_energy(faces, chart_face_count, faces.size(), x, energy_before);
    // A system that breaks down (scaffold slivers) ends the solve; uv, the
    // last accepted iterate, is valid all the same.
    if (!slim_step(faces, options, *system, x, energy).moved) return {};
    points = from_solver(x, order);
    uv = points.topRows(n);
    ++solution.iterations;
    const double energy_after = partial_energy(faces, 0, chart_face_count, x, 0);
    const double decrease = (energy_before - energy_after) / energy_before;
    energy_before = energy_after;
    if (decrease >= 0 && decrease < kScaffoldToleranceFactor * options.relative_tolerance) return {};
  }
  return {};
}

// One chart's solve as the first solve and the density repair share it: a
// chart that went into its scaffold goes on inside one.
struct ChartSolve {
  ChartSolve(const RowMatrixX3i& t, const RowMatrixX2d& r, const std::vector<int>& o)
      : triangles(t), reference(r), order(o) {}
  const RowMatrixX3i& triangles;
  const RowMatrixX2d& reference;  // 3F x 2, the repaired reference corners
  const std::vector<int>& order;
  std::vector<int> loop, loop_dofs;  // the boundary loop's vertices, and their dofs
  std::vector<ProxyFace> faces;
  ProxySystem system;
  Eigen::VectorXd x;
};

// Minimizes from s.x: plain SLIM until the boundary would cross itself, SCAF
// from then on. s.x is the last accepted iterate whatever the status.
SolveStatus solve_from(ChartSolve& s, const SlimOptions& options, const RunControl& control,
                       ChartSolution& solution) {
  bool crossed = false;
  SolveStatus status;
  if (!solution.scaffolded)
    status = minimize_energy(s.faces, s.system, options.scaffold_on_crossing ? s.loop_dofs : std::vector<int>(),
                             options, control, s.x, total_energy(s.faces, s.x), solution, crossed);
  if (!status.ok() || !(crossed || solution.scaffolded)) return status;
  solution.scaffolded = true;
  RowMatrixX2d uv = from_solver(s.x, s.order);
  status = minimize_with_scaffold(s.triangles, s.reference, s.faces, s.order, s.loop, options, control, uv, solution);
  s.x = to_solver(uv, s.order);
  return status;
}

// Reference area of the faces that x shrinks below `floor` of it (faces
// weighted by their reference area).
double area_below(const std::vector<ProxyFace>& faces, double floor, const Eigen::VectorXd& x) {
  double area = 0;
  for (const ProxyFace& face : faces)
    if (jacobian(face, x).determinant() < floor) area += face.area;
  return area;
}

// Each face with area ratio r = det J < floor weighs factor * floor / r times
// more than it did, and at most kMaxRepairWeight times its unweighted
// weight: a sliver's ratio can be tiny, and its weight must not swamp the
// system.
constexpr double kMaxRepairWeight = 1e4;
void weigh_compressed(double floor, double factor, const Eigen::VectorXd& x, const std::vector<ProxyFace>& unweighted,
                      std::vector<ProxyFace>& faces) {
  for (size_t f = 0; f < faces.size(); ++f)
    if (const double r = jacobian(faces[f], x).determinant(); r > 0 && r < floor)
      set_face_reference(faces[f].inverse_edges,
                         std::min(factor * floor / r * faces[f].area, kMaxRepairWeight * unweighted[f].area), faces[f]);
}

// Whether x leaves the chart unusable: a face flipped in round-off, or the
// boundary crossing itself (what the caller refuses a chart for).
bool unusable(const ChartSolve& s, const std::vector<ProxyFace>& faces) {
  return flipped_faces(faces, s.x) > 0 || loop_crosses(s.loop_dofs, s.x);
}

// Density repair (SlimOptions::repair_rounds). A round that fails, leaves
// more area below half, leaves x unusable or raises the energy past
// repair_energy_bound (and past the start) is undone and ends the repair.
// Returns whether a repair was kept; s.faces end unweighted. reference_area:
// the sum of the faces' (unweighted) areas.
bool repair_density(ChartSolve& s, double reference_area, const SlimOptions& options, const RunControl& control,
                    ChartSolution& solution) {
  double lost = area_below(s.faces, kDensityFloor, s.x);
  const double start_energy = total_energy(s.faces, s.x);
  // A chart already past the bound is left alone: the repair raises the
  // energy of a solved chart, so it would be undone.
  if (!(options.repair_floor > 0 && options.repair_factor > 0) || !(lost > options.repair_share * reference_area) ||
      start_energy > options.repair_energy_bound * reference_area)
    return false;
  SlimOptions continued = options;
  continued.progressive_bound = 0;  // x is near the optimum already
  const std::vector<ProxyFace> unweighted = s.faces;
  const Eigen::VectorXd start = s.x;
  for (int round = 0; round < options.repair_rounds && lost > 0; ++round) {
    weigh_compressed(options.repair_floor, options.repair_factor, s.x, unweighted, s.faces);
    const Eigen::VectorXd kept = s.x;
    const bool kept_scaffolded = solution.scaffolded;
    const bool ok = solve_from(s, continued, control, solution).ok();
    const double now_lost = area_below(unweighted, kDensityFloor, s.x), energy = total_energy(unweighted, s.x);
    if (!ok || now_lost > lost || unusable(s, unweighted) ||
        (energy > start_energy && energy > options.repair_energy_bound * reference_area)) {
      s.x = kept, solution.scaffolded = kept_scaffolded;
      break;
    }
    lost = now_lost;
  }
  s.faces = unweighted;
  return s.x != start;
}

}  // namespace

ChartSolution parameterize_chart(const ChartProblem& problem, const SlimOptions& options,
                                 const RunControl& control) {
  control.throw_if_cancelled();
  const int vertex_count = static_cast<int>(problem.positions.rows());
  ChartSolution solution;
  solution.uv = RowMatrixX2d::Zero(vertex_count, 2);
  std::vector<int> boundary_corners;
  solution.status = input_problem(problem);
  if (solution.status.ok()) solution.status = disk_boundary_loop(problem.triangles, vertex_count, boundary_corners);
  if (!solution.status.ok()) return solution;

  const ReferenceTriangles reference = repaired_reference_triangles(problem.triangles, problem.positions,
                                                                    problem.reference_uv, problem.mirrored);
  solution.folded_references = reference.folded;
  solution.repaired_references = reference.repaired;
  RowMatrixX2d initial;
  solution.status = mean_value_embedding(problem.triangles, reference.corners, boundary_corners, vertex_count, initial);
  if (!solution.status.ok()) return solution;

  const std::vector<int> order = fill_reducing_order(problem.triangles, vertex_count);
  std::vector<ProxyFace> faces = proxy_faces(problem.triangles, reference.corners, order);
  double reference_area = 0;
  for (const ProxyFace& face : faces) reference_area += face.area;
  Eigen::VectorXd x = to_solver(initial, order);

  const double initial_energy = total_energy(faces, x);
  if (initial_energy < kInfinity) {
    solution.energy_initial = initial_energy / reference_area;
    ChartSolve s(problem.triangles, reference.corners, order);
    for (int c : boundary_corners) s.loop.push_back(corner_vertex(problem.triangles, c));
    for (int v : s.loop) s.loop_dofs.push_back(2 * order[v]);
    s.faces = std::move(faces);
    s.x = std::move(x);
    prepare_proxy_system(s.faces, static_cast<int>(s.x.size()), s.system);
    solution.status = solve_from(s, options, control, solution);
    if (solution.status.ok())
      solution.density_repaired = repair_density(s, reference_area, options, control, solution);
    faces = std::move(s.faces);
    x = std::move(s.x);
    if (solution.status.ok()) {
      RowMatrixX2d uv = from_solver(x, order);
      if (relax_squeezed_faces(problem.triangles, reference.corners, options.relax, uv))
        x = to_solver(uv, order), solution.density_repaired = true;
    }
    solution.energy_final = total_energy(faces, x) / reference_area;
  } else {
    std::ostringstream msg;
    msg << "initial embedding is not flip-free (" << flipped_faces(faces, x) << " faces)";
    solution.status = solve_failed(SolveFailure::embedding, msg.str());
  }
  solution.flipped = flipped_faces(faces, x);
  solution.uv = from_solver(x, order);
  return solution;
}

}  // namespace atlas
