#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "flatten/flatten_without_overlap.hpp"
#include "flatten/slim.hpp"
#include "test_meshes.hpp"

namespace atlas {
namespace {

using ReferenceMap = std::function<Eigen::Vector2d(const Eigen::Vector2d& xy, int face)>;

// An n x n grid on the unit square whose face f has reference corners map(xy, f).
ChartProblem grid_problem(int n, const ReferenceMap& map) {
  const Mesh mesh = testing::grid_disk(n);
  ChartProblem problem;
  problem.triangles = mesh.triangles;
  problem.positions = mesh.positions;
  problem.reference_uv.resize(3 * mesh.face_count(), 2);
  for (int f = 0; f < mesh.face_count(); ++f)
    for (int k = 0; k < 3; ++k)
      problem.reference_uv.row(3 * f + k) =
          map(mesh.positions.row(mesh.triangles(f, k)).head<2>().transpose(), f).transpose();
  problem.mirrored = Eigen::VectorXi::Zero(mesh.face_count());
  return problem;
}

Eigen::Vector2d face_centroid(const ChartProblem& problem, int f) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (int k = 0; k < 3; ++k) sum += problem.positions.row(problem.triangles(f, k)).head<2>().transpose();
  return sum / 3;
}

Eigen::Matrix2d uv_edges(const ChartSolution& solution, const ChartProblem& problem, int f) {
  const auto corner = [&](int k) -> Eigen::Vector2d { return solution.uv.row(problem.triangles(f, k)).transpose(); };
  Eigen::Matrix2d edges;
  edges << corner(1) - corner(0), corner(2) - corner(0);
  return edges;
}

// Jacobian of the map from the problem's (unmirrored, positive) reference to the result.
Eigen::Matrix2d face_jacobian(const ChartSolution& solution, const ChartProblem& problem, int f) {
  const auto reference = [&](int k) -> Eigen::Vector2d { return problem.reference_uv.row(3 * f + k).transpose(); };
  Eigen::Matrix2d reference_edges;
  reference_edges << reference(1) - reference(0), reference(2) - reference(0);
  return uv_edges(solution, problem, f) * reference_edges.inverse();
}

double uv_area(const ChartSolution& solution, const ChartProblem& problem, int f) {
  return uv_edges(solution, problem, f).determinant() / 2;
}

double total_uv_area(const ChartSolution& solution, const ChartProblem& problem) {
  double area = 0;
  for (int f = 0; f < problem.triangles.rows(); ++f) area += uv_area(solution, problem, f);
  return area;
}

// What every successful solve must satisfy, counted from uv rather than trusted.
void expect_valid(const ChartSolution& solution, const ChartProblem& problem) {
  EXPECT_TRUE(solution.status.ok()) << solution.status.detail;
  ASSERT_EQ(solution.uv.rows(), problem.positions.rows());
  EXPECT_TRUE(solution.uv.allFinite());
  EXPECT_TRUE(std::isfinite(solution.energy_initial));
  EXPECT_TRUE(std::isfinite(solution.energy_final));
  EXPECT_GE(solution.energy_final, 4.0 - 1e-9);
  EXPECT_LE(solution.energy_final, solution.energy_initial);
  EXPECT_EQ(solution.flipped, 0);
  int flipped = 0;
  for (int f = 0; f < problem.triangles.rows(); ++f) flipped += !(uv_area(solution, problem, f) > 0);
  EXPECT_EQ(flipped, 0);
}

SlimOptions tight_options() {
  SlimOptions options;
  options.relative_tolerance = 1e-9;
  options.max_iterations = 400;
  return options;
}

TEST(Slim, IdentityReferenceComesBackIsometric) {
  const ChartProblem problem = grid_problem(12, [](const Eigen::Vector2d& xy, int) { return xy; });
  const ChartSolution solution = parameterize_chart(problem, tight_options(), RunControl());
  expect_valid(solution, problem);
  EXPECT_GT(solution.energy_initial, 4.01);  // the circle boundary is far from the square
  EXPECT_NEAR(solution.energy_final, 4.0, 1e-3);
  EXPECT_GT(solution.iterations, 0);
  for (int f = 0; f < problem.triangles.rows(); ++f) {
    const Eigen::Matrix2d J = face_jacobian(solution, problem, f);
    const Eigen::Vector2d s = Eigen::JacobiSVD<Eigen::Matrix2d>(J).singularValues();
    EXPECT_NEAR(s[0], 1.0, 5e-3) << "face " << f;
    EXPECT_NEAR(s[1], 1.0, 5e-3) << "face " << f;
    EXPECT_GT(J.determinant(), 0) << "face " << f;
  }
}

TEST(Slim, UniformScaleIsRecovered) {
  const ChartProblem problem = grid_problem(10, [](const Eigen::Vector2d& xy, int) { return Eigen::Vector2d(2 * xy); });
  const ChartSolution solution = parameterize_chart(problem, tight_options(), RunControl());
  expect_valid(solution, problem);
  EXPECT_NEAR(total_uv_area(solution, problem), 4.0, 0.04);
  EXPECT_NEAR(solution.energy_final, 4.0, 1e-2);
}

TEST(Slim, DefaultOptionsStopEarlyButStillImprove) {
  const ChartProblem problem = grid_problem(10, [](const Eigen::Vector2d& xy, int) { return Eigen::Vector2d(50 * xy); });
  const ChartSolution solution = parameterize_chart(problem, SlimOptions(), RunControl());
  expect_valid(solution, problem);
  EXPECT_LE(solution.iterations, SlimOptions().max_iterations);
  EXPECT_LT(solution.energy_final, 4.1);
  EXPECT_NEAR(total_uv_area(solution, problem), 2500.0, 50.0);
}

TEST(Slim, MixedResolutionReferenceIsSolvedFlipFree) {
  const ChartProblem problem = grid_problem(12, [](const Eigen::Vector2d& xy, int) { return xy; });
  ChartProblem mixed = problem;
  std::vector<char> coarse(problem.triangles.rows());
  for (int f = 0; f < problem.triangles.rows(); ++f) {
    coarse[f] = face_centroid(problem, f).x() > 0.5;
    if (coarse[f]) mixed.reference_uv.middleRows<3>(3 * f) *= 2;
  }
  const ChartSolution solution = parameterize_chart(mixed, SlimOptions(), RunControl());
  expect_valid(solution, mixed);
  EXPECT_GT(solution.energy_final, 4.0);
  EXPECT_LT(solution.energy_final, solution.energy_initial);
  // The energy follows the references: the 2x half ends up clearly larger.
  double fine_area = 0, coarse_area = 0;
  for (int f = 0; f < mixed.triangles.rows(); ++f) (coarse[f] ? coarse_area : fine_area) += uv_area(solution, mixed, f);
  EXPECT_GT(coarse_area, 2 * fine_area);
}

// The grid lifted into a bump of height h at its centre, each face's
// reference its own 3D triangle laid flat: more surface than a plane holds.
ChartProblem bump(double h) {
  ChartProblem problem = grid_problem(16, [](const Eigen::Vector2d& xy, int) { return xy; });
  for (Eigen::Index v = 0; v < problem.positions.rows(); ++v) {
    const Eigen::Vector2d d = problem.positions.row(v).head<2>().transpose() - Eigen::Vector2d(0.5, 0.5);
    problem.positions(v, 2) = h * std::exp(-d.squaredNorm() / 0.02);
  }
  for (Eigen::Index f = 0; f < problem.triangles.rows(); ++f) {
    const Eigen::Vector3d p0 = problem.positions.row(problem.triangles(f, 0)).transpose();
    const Eigen::Vector3d e1 = problem.positions.row(problem.triangles(f, 1)).transpose() - p0;
    const Eigen::Vector3d e2 = problem.positions.row(problem.triangles(f, 2)).transpose() - p0;
    const Eigen::Vector3d u = e1.normalized();
    problem.reference_uv.row(3 * f) << 0, 0;
    problem.reference_uv.row(3 * f + 1) << e1.norm(), 0;
    problem.reference_uv.row(3 * f + 2) << e2.dot(u), (e2 - e2.dot(u) * u).norm();
  }
  return problem;
}

double reference_area(const ChartProblem& problem, int f) {
  const Eigen::Matrix2d edges =
      problem.reference_uv.middleRows<2>(3 * f + 1).rowwise() - problem.reference_uv.row(3 * f);
  return std::abs(edges.determinant()) / 2;
}

// Reference area of the faces the solution shrinks below half their reference area.
double area_below_half(const ChartSolution& solution, const ChartProblem& problem) {
  double area = 0;
  for (int f = 0; f < problem.triangles.rows(); ++f)
    if (face_jacobian(solution, problem, f).determinant() < 0.5) area += reference_area(problem, f);
  return area;
}

// The global repair alone: the local relaxation after it would lift the
// bump's faces by itself (see below).
SlimOptions without_relaxing(SlimOptions options = SlimOptions()) {
  options.relax.sweeps = 0;
  return options;
}

TEST(Slim, DensityRepairLiftsSqueezedFaces) {
  const ChartProblem problem = bump(0.5);
  SlimOptions none = without_relaxing();
  none.repair_rounds = 0;
  const ChartSolution plain = parameterize_chart(problem, none, RunControl());
  const ChartSolution repaired = parameterize_chart(problem, without_relaxing(), RunControl());
  expect_valid(plain, problem);
  expect_valid(repaired, problem);
  EXPECT_FALSE(plain.density_repaired);
  EXPECT_TRUE(repaired.density_repaired);
  EXPECT_GT(area_below_half(plain, problem), 0);
  EXPECT_LT(area_below_half(repaired, problem), 0.5 * area_below_half(plain, problem));
}

TEST(Slim, DensityRepairSparesChartsThatLoseLittle) {
  const ChartProblem problem = bump(0.3);
  SlimOptions none = without_relaxing(), every = without_relaxing();
  none.repair_rounds = 0;
  every.repair_share = 0;
  const ChartSolution plain = parameterize_chart(problem, none, RunControl());
  const double lost = area_below_half(plain, problem);
  double area = 0;
  for (int f = 0; f < problem.triangles.rows(); ++f) area += reference_area(problem, f);
  ASSERT_GT(lost, 0);
  ASSERT_LT(lost, SlimOptions().repair_share * area);
  EXPECT_FALSE(parameterize_chart(problem, without_relaxing(), RunControl()).density_repaired);
  EXPECT_TRUE(parameterize_chart(problem, every, RunControl()).density_repaired);
}

// What the solve and the global repair leave below half, the local
// relaxation lifts, with the boundary where the solve left it.
TEST(Slim, LocalRelaxationLiftsWhatTheSolveLeftSqueezed) {
  const ChartProblem problem = bump(0.5);
  SlimOptions solve_only = without_relaxing(), relaxing;
  solve_only.repair_rounds = 0, relaxing.repair_rounds = 0;
  const ChartSolution plain = parameterize_chart(problem, solve_only, RunControl());
  const ChartSolution relaxed = parameterize_chart(problem, relaxing, RunControl());
  expect_valid(relaxed, problem);
  ASSERT_GT(area_below_half(plain, problem), 0);
  EXPECT_EQ(area_below_half(relaxed, problem), 0);
  EXPECT_TRUE(relaxed.density_repaired);
  EXPECT_LE(relaxed.energy_final, 1.02 * plain.energy_final);
}

// Solved to convergence, the bump's repair must raise the energy.
TEST(Slim, DensityRepairThatRaisesTheEnergyPastItsBoundIsUndone) {
  const ChartProblem problem = bump(0.5);
  SlimOptions none = without_relaxing(tight_options()), strict = without_relaxing(tight_options());
  none.repair_rounds = 0;
  const ChartSolution plain = parameterize_chart(problem, none, RunControl());
  const ChartSolution repaired = parameterize_chart(problem, without_relaxing(tight_options()), RunControl());
  ASSERT_TRUE(repaired.density_repaired);
  ASSERT_GT(repaired.energy_final, plain.energy_final);
  strict.repair_energy_bound = (plain.energy_final + repaired.energy_final) / 2;
  const ChartSolution undone = parameterize_chart(problem, strict, RunControl());
  EXPECT_FALSE(undone.density_repaired);
  EXPECT_TRUE(undone.uv == plain.uv);
  EXPECT_EQ(undone.energy_final, plain.energy_final);
}

TEST(Slim, SmoothDeformationConverges) {
  const ChartProblem problem = grid_problem(16, [](const Eigen::Vector2d& xy, int) {
    return Eigen::Vector2d(30 * xy.x() + 4 * std::sin(3 * xy.y()), 20 * xy.y() + 3 * xy.x() * xy.x());
  });
  const ChartSolution solution = parameterize_chart(problem, tight_options(), RunControl());
  expect_valid(solution, problem);
  // The reference is itself a flip-free planar map of the grid, so the optimum is exact.
  EXPECT_NEAR(solution.energy_final, 4.0, 1e-2);
}

// A comb of unit squares, each cut into two triangles: a base `base` rows
// high and `fingers` fingers two cells wide and `length` cells long, two
// cells apart. Its reference is the comb itself.
ChartProblem comb(int fingers, int length, int base) {
  const int cells = 4 * fingers - 2, width = cells + 1;
  auto kept = [&](int i, int j) { return j < base || i % 4 < 2; };
  std::vector<int> index((cells + 1) * (base + length + 1), -1);
  std::vector<Eigen::Vector2d> points;
  std::vector<Eigen::Vector3i> faces;
  auto vertex = [&](int i, int j) {
    int& v = index[j * width + i];
    if (v < 0) v = static_cast<int>(points.size()), points.emplace_back(i, j);
    return v;
  };
  for (int j = 0; j < base + length; ++j)
    for (int i = 0; i < cells; ++i)
      if (kept(i, j)) {
        const int a = vertex(i, j), b = vertex(i + 1, j), c = vertex(i + 1, j + 1), d = vertex(i, j + 1);
        faces.emplace_back(a, b, c);
        faces.emplace_back(a, c, d);
      }
  ChartProblem problem;
  problem.positions = RowMatrixX3d::Zero(static_cast<Eigen::Index>(points.size()), 3);
  for (size_t v = 0; v < points.size(); ++v) problem.positions.row(v).head<2>() = points[v];
  problem.triangles.resize(static_cast<Eigen::Index>(faces.size()), 3);
  problem.reference_uv.resize(3 * problem.triangles.rows(), 2);
  for (size_t f = 0; f < faces.size(); ++f) {
    problem.triangles.row(f) = faces[f];
    for (int k = 0; k < 3; ++k) problem.reference_uv.row(3 * f + k) = points[faces[f][k]];
  }
  problem.mirrored = Eigen::VectorXi::Zero(problem.triangles.rows());
  return problem;
}

// The Tutte start squeezes a comb's fingers towards the circle's centre, so
// faces there start nearly degenerate and plain SLIM's steps stay short for
// long; aiming at intermediate references first takes far fewer iterations.
TEST(Slim, ProgressiveReferencesUnfoldACombInFewerIterations) {
  const ChartProblem problem = comb(5, 40, 2);
  SlimOptions options = tight_options();
  options.relative_tolerance = 1e-4;
  SlimOptions plain = options;
  plain.progressive_bound = 0;
  const ChartSolution progressive = parameterize_chart(problem, options, RunControl());
  const ChartSolution direct = parameterize_chart(problem, plain, RunControl());
  expect_valid(progressive, problem);
  expect_valid(direct, problem);
  EXPECT_GT(progressive.energy_initial, 1e3);
  EXPECT_LT(progressive.energy_final, 4.05);
  EXPECT_LT(direct.energy_final, 4.05);
  EXPECT_LT(2 * progressive.iterations, direct.iterations);
}

// A strip whose reference is 1.2 turns of a wide annulus (radii 5 to 10):
// laid out without distortion it covers part of itself twice, and unrolling
// it would cost more than curling it up.
ChartProblem overwound_strip() {
  return grid_problem(24, [](const Eigen::Vector2d& xy, int) {
    const double angle = 2.4 * 3.14159265358979 * xy.x(), radius = 10 - 5 * xy.y();
    return Eigen::Vector2d(radius * std::cos(angle), radius * std::sin(angle));
  });
}

TEST(Slim, PlainSlimLetsAnOverwoundStripCrossItself) {
  SlimOptions options = tight_options();
  options.scaffold_on_crossing = false;
  const ChartProblem problem = overwound_strip();
  const ChartSolution solution = parameterize_chart(problem, options, RunControl());
  expect_valid(solution, problem);
  EXPECT_FALSE(solution.scaffolded);
  EXPECT_TRUE(boundary_self_intersects(problem.triangles, solution.uv));
}

TEST(Slim, ScaffoldKeepsAnOverwoundStripFromCrossingItself) {
  const ChartProblem problem = overwound_strip();
  const ChartSolution solution = parameterize_chart(problem, tight_options(), RunControl());
  expect_valid(solution, problem);
  EXPECT_TRUE(solution.scaffolded);
  EXPECT_FALSE(boundary_self_intersects(problem.triangles, solution.uv));
  // Bent to about one turn instead of 1.2: distorted, but not far off.
  EXPECT_LT(solution.energy_final, 4.5);
}

TEST(Slim, DegenerateReferencesAreRepaired) {
  ChartProblem problem = grid_problem(8, [](const Eigen::Vector2d& xy, int) { return Eigen::Vector2d(10 * xy); });
  problem.reference_uv.middleRows<3>(3 * 0).setConstant(3.0);                 // zero area: one point
  problem.reference_uv.middleRows<3>(3 * 7) << 0, 0, 1, 1, 2, 2;              // collinear
  problem.reference_uv.row(3 * 20 + 2) = problem.reference_uv.row(3 * 20);    // repeated corner
  problem.reference_uv.middleRows<3>(3 * 33) << 0, 0, 1, 0, 0.5, 1e-4;        // sliver, angles ~0.01 degree
  problem.reference_uv.middleRows<3>(3 * 50) << 0, 0, 1e-4, 0, 0, 1e-4;       // well shaped but ~1e-8 of its share
  problem.reference_uv(3 * 60, 0) = std::nan("");                             // not a number
  const ChartSolution solution = parameterize_chart(problem, SlimOptions(), RunControl());
  expect_valid(solution, problem);
  EXPECT_EQ(solution.repaired_references, 6);
  EXPECT_EQ(solution.folded_references, 0);
  EXPECT_LT(solution.energy_final, 4.5);  // repairs follow the chart's texel density, no outliers
}

TEST(Slim, DegenerateReferenceAndDegenerate3DGetAWellShapedTriangle) {
  ChartProblem problem = grid_problem(6, [](const Eigen::Vector2d& xy, int) { return Eigen::Vector2d(10 * xy); });
  problem.positions.setZero();  // every 3D triangle degenerate
  problem.reference_uv.middleRows<3>(3 * 11).setZero();
  const ChartSolution solution = parameterize_chart(problem, SlimOptions(), RunControl());
  expect_valid(solution, problem);
  EXPECT_EQ(solution.repaired_references, 1);
  EXPECT_LT(solution.energy_final, 5.0);
}

TEST(Slim, MirroredChartSolvesLikeUnmirrored) {
  const ReferenceMap plain = [](const Eigen::Vector2d& xy, int) {
    return Eigen::Vector2d(20 * xy.x() + 2 * xy.y() * xy.y(), 25 * xy.y());
  };
  const ChartProblem problem = grid_problem(10, plain);
  ChartProblem mirrored = grid_problem(10, [&](const Eigen::Vector2d& xy, int f) {
    const Eigen::Vector2d r = plain(xy, f);
    return Eigen::Vector2d(-r.x(), r.y());
  });
  mirrored.mirrored.setOnes();
  const ChartSolution a = parameterize_chart(problem, SlimOptions(), RunControl());
  const ChartSolution b = parameterize_chart(mirrored, SlimOptions(), RunControl());
  expect_valid(a, problem);
  expect_valid(b, problem);  // uv is checked against the unmirrored winding
  EXPECT_EQ(b.folded_references, 0);
  EXPECT_EQ(b.iterations, a.iterations);
  EXPECT_NEAR(b.energy_final, a.energy_final, 1e-9);
}

TEST(Slim, FoldedReferenceUsesItsMirrorImage) {
  ChartProblem problem = grid_problem(8, [](const Eigen::Vector2d& xy, int) { return Eigen::Vector2d(10 * xy); });
  problem.reference_uv.middleRows<3>(3 * 9).col(0) *= -1;  // one face folded over in its original chart
  const ChartSolution solution = parameterize_chart(problem, tight_options(), RunControl());
  expect_valid(solution, problem);
  EXPECT_EQ(solution.folded_references, 1);
  EXPECT_EQ(solution.repaired_references, 0);
  EXPECT_NEAR(solution.energy_final, 4.0, 1e-3);  // the mirror image is congruent to the true triangle
}

// 16 original charts of 6 x 6 quads, each with its own rotation, scale,
// mirroring and place in texture space: references do not connect across them.
TEST(Slim, PatchworkOfOriginalChartsIsSolved) {
  ChartProblem problem = grid_problem(24, [](const Eigen::Vector2d& xy, int) { return xy; });
  std::vector<int> chart(problem.triangles.rows());
  double smallest_scale = 1e9, largest_scale = 0;
  int smallest = -1, largest = -1;
  for (int f = 0; f < problem.triangles.rows(); ++f) {
    const Eigen::Vector2d c = face_centroid(problem, f);
    chart[f] = int(c.x() * 4) * 4 + int(c.y() * 4);
    const double angle = 1.3 * chart[f], scale = 40 * std::pow(2.0, std::sin(2.1 * chart[f]));
    const bool mirror = chart[f] % 3 == 0;
    if (scale < smallest_scale) smallest_scale = scale, smallest = chart[f];
    if (scale > largest_scale) largest_scale = scale, largest = chart[f];
    const Eigen::Matrix2d rotation = Eigen::Rotation2Dd(angle).toRotationMatrix();
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector2d r = scale * (rotation * problem.reference_uv.row(3 * f + k).transpose()) +
                          Eigen::Vector2d(100.0 * chart[f], 0);
      if (mirror) r.x() = -r.x();
      problem.reference_uv.row(3 * f + k) = r.transpose();
    }
    problem.mirrored[f] = mirror;
  }
  const ChartSolution solution = parameterize_chart(problem, SlimOptions(), RunControl());
  expect_valid(solution, problem);
  EXPECT_EQ(solution.folded_references, 0);
  EXPECT_LT(solution.energy_final, 0.9 * solution.energy_initial);
  double small_area = 0, large_area = 0;
  for (int f = 0; f < problem.triangles.rows(); ++f) {
    if (chart[f] == smallest) small_area += uv_area(solution, problem, f);
    if (chart[f] == largest) large_area += uv_area(solution, problem, f);
  }
  EXPECT_GT(large_area, 2 * small_area);  // larger original resolution keeps more texels
}

TEST(Slim, ConcurrentCallsMatchSerialOnes) {
  std::vector<ChartProblem> problems;
  for (int i = 0; i < 6; ++i)
    problems.push_back(grid_problem(6 + 2 * i, [i](const Eigen::Vector2d& xy, int) {
      return Eigen::Vector2d(10 * xy.x() + i * xy.y() * xy.y(), (5 + i) * xy.y());
    }));
  std::vector<ChartSolution> serial, parallel(problems.size());
  for (const ChartProblem& problem : problems) serial.push_back(parameterize_chart(problem, SlimOptions(), RunControl()));
  const RunControl control;
#pragma omp parallel for num_threads(2) schedule(dynamic)
  for (int i = 0; i < static_cast<int>(problems.size()); ++i)
    parallel[i] = parameterize_chart(problems[i], SlimOptions(), control);
  for (size_t i = 0; i < problems.size(); ++i) {
    expect_valid(parallel[i], problems[i]);
    EXPECT_EQ(parallel[i].iterations, serial[i].iterations);
    EXPECT_EQ(parallel[i].uv, serial[i].uv);  // deterministic, no shared state
  }
}

TEST(Slim, CancelledControlThrows) {
  const ChartProblem problem = grid_problem(6, [](const Eigen::Vector2d& xy, int) { return xy; });
  RunControl control;
  control.cancel();
  EXPECT_THROW(parameterize_chart(problem, SlimOptions(), control), Cancelled);
}

ChartProblem problem_from_mesh(const Mesh& mesh) {
  ChartProblem problem;
  problem.triangles = mesh.triangles;
  problem.positions = mesh.positions;
  problem.reference_uv = mesh.corner_uv * 1000.0;
  problem.mirrored = Eigen::VectorXi::Zero(mesh.face_count());
  return problem;
}

void expect_failure_without_nan(const ChartProblem& problem, const std::string& reason,
                                SolveFailure kind = SolveFailure::not_disk) {
  const ChartSolution solution = parameterize_chart(problem, SlimOptions(), RunControl());
  EXPECT_EQ(solution.status.failure, kind) << solution.status.detail;
  EXPECT_NE(solution.status.detail.find(reason), std::string::npos) << "failure: '" << solution.status.detail << "'";
  EXPECT_TRUE(solution.uv.allFinite());
  EXPECT_TRUE(std::isfinite(solution.energy_initial));
  EXPECT_TRUE(std::isfinite(solution.energy_final));
}

TEST(Slim, NonDiskChartsReportFailure) {
  expect_failure_without_nan(problem_from_mesh(testing::annulus(2, 12, 12)), "more than one boundary loop");
  expect_failure_without_nan(problem_from_mesh(testing::nonmanifold_fin()), "more than two faces");
  expect_failure_without_nan(problem_from_mesh(testing::torus(8, 6, 8)), "no boundary");
  ChartProblem flipped_face = grid_problem(4, [](const Eigen::Vector2d& xy, int) { return xy; });
  std::swap(flipped_face.triangles(3, 0), flipped_face.triangles(3, 1));  // inconsistent winding
  expect_failure_without_nan(flipped_face, "opposite orientation");
  ChartProblem two_disks = grid_problem(2, [](const Eigen::Vector2d& xy, int) { return xy; });
  two_disks.triangles.conservativeResize(two_disks.triangles.rows() + 1, 3);
  two_disks.positions.conservativeResize(two_disks.positions.rows() + 3, 3);
  two_disks.positions.bottomRows<3>() << 5, 0, 0, 6, 0, 0, 5, 1, 0;
  two_disks.triangles.bottomRows<1>() << 9, 10, 11;
  two_disks.reference_uv.conservativeResize(two_disks.reference_uv.rows() + 3, 2);
  two_disks.reference_uv.bottomRows<3>() << 0, 0, 1, 0, 0, 1;
  two_disks.mirrored.setZero(two_disks.triangles.rows());
  expect_failure_without_nan(two_disks, "more than one boundary loop");
  ChartProblem bow_tie;  // two triangles sharing only vertex 0
  bow_tie.triangles.resize(2, 3);
  bow_tie.triangles << 0, 1, 2, 0, 3, 4;
  bow_tie.positions.resize(5, 3);
  bow_tie.positions << 0, 0, 0, 1, 0, 0, 1, 1, 0, -1, 0, 0, -1, -1, 0;
  bow_tie.reference_uv.resize(6, 2);
  bow_tie.reference_uv << 0, 0, 1, 0, 1, 1, 0, 0, -1, 0, -1, -1;
  bow_tie.mirrored.setZero(2);
  expect_failure_without_nan(bow_tie, "boundary touches itself");
}

TEST(Slim, MalformedProblemsReportFailure) {
  ChartProblem problem = grid_problem(3, [](const Eigen::Vector2d& xy, int) { return xy; });
  ChartProblem short_reference = problem;
  short_reference.reference_uv.conservativeResize(5, 2);
  expect_failure_without_nan(short_reference, "reference_uv", SolveFailure::bad_input);
  ChartProblem short_mirrored = problem;
  short_mirrored.mirrored.resize(1);
  expect_failure_without_nan(short_mirrored, "mirrored", SolveFailure::bad_input);
  ChartProblem bad_index = problem;
  bad_index.triangles(2, 1) = 1000;
  expect_failure_without_nan(bad_index, "out of range", SolveFailure::bad_input);
  ChartProblem unused_vertex = problem;
  unused_vertex.positions.conservativeResize(problem.positions.rows() + 1, 3);
  unused_vertex.positions.bottomRows<1>().setZero();
  expect_failure_without_nan(unused_vertex, "no face uses vertex");
  expect_failure_without_nan(ChartProblem(), "no faces");
}

}  // namespace
}  // namespace atlas
