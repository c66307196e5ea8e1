#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <random>
#include <vector>

#include "flatten/sparse_cholesky.hpp"
#include "flatten/supernodal_cholesky.hpp"
#include "test_meshes.hpp"

namespace atlas {
namespace {

// Upper triangle of a random SPD matrix with the SLIM pattern (two unknowns
// per vertex, a full 2x2 block per coupled pair) on an n x n grid. Rows in
// grid order fill in much (wide supernodes, dense updates); in a random order
// more still.
Eigen::SparseMatrix<double> grid_system(int n, bool shuffled, unsigned seed) {
  const Mesh mesh = testing::grid_disk(n);
  const int vertices = static_cast<int>(mesh.positions.rows());
  std::mt19937 random(seed);
  std::vector<int> order(vertices);
  for (int v = 0; v < vertices; ++v) order[v] = v;
  if (shuffled) std::shuffle(order.begin(), order.end(), random);
  std::uniform_real_distribution<double> coupling(-1.0, 0.0);
  std::vector<Eigen::Triplet<double>> entries;
  std::vector<double> diagonal(2 * vertices, 1e-3);
  auto couple = [&](int a, int b) {
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) {
        const int r = 2 * order[a] + i, c = 2 * order[b] + j;
        const double w = coupling(random);
        if (r == c) continue;
        entries.emplace_back(std::min(r, c), std::max(r, c), w);
        diagonal[r] -= w, diagonal[c] -= w;
      }
  };
  for (int f = 0; f < mesh.face_count(); ++f)
    for (int k = 0; k < 3; ++k) couple(mesh.triangles(f, k), mesh.triangles(f, (k + 1) % 3));
  for (int v = 0; v < vertices; ++v) couple(v, v);
  for (int r = 0; r < 2 * vertices; ++r) entries.emplace_back(r, r, diagonal[r]);
  Eigen::SparseMatrix<double> a(2 * vertices, 2 * vertices);
  a.setFromTriplets(entries.begin(), entries.end());
  a.makeCompressed();
  return a;
}

// The solution of the factorized solver against Eigen's LDLT, to round-off.
template <class Solver>
void expect_solves(const Eigen::SparseMatrix<double>& a, const Solver& solver) {
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Upper> eigen(a);
  ASSERT_EQ(eigen.info(), Eigen::Success);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(a.rows(), -1.0, 2.0);
  const Eigen::VectorXd expected = eigen.solve(b);
  Eigen::VectorXd x;
  solver.solve(b, x);
  EXPECT_LT((x - expected).norm(), 1e-9 * expected.norm());
}

void expect_factorizes_and_solves(const Eigen::SparseMatrix<double>& a) {
  SupernodalCholesky ours;
  ours.analyze(a);
  ASSERT_TRUE(ours.factorize(a));
  expect_solves(a, ours);
}

TEST(SupernodalCholesky, SolvesASparseSystem) { expect_factorizes_and_solves(grid_system(6, false, 1)); }

// Random order: supernodes wider than the narrow-panel loops and updates
// long enough for dense products.
TEST(SupernodalCholesky, SolvesASystemThatFillsIn) { expect_factorizes_and_solves(grid_system(24, true, 2)); }

TEST(SupernodalCholesky, SolvesAfterRefactorizing) {
  Eigen::SparseMatrix<double> a = grid_system(16, true, 3);
  SupernodalCholesky ours;
  ours.analyze(a);
  ASSERT_TRUE(ours.factorize(a));
  a.coeffs() *= 1.5;  // new values, same pattern
  ASSERT_TRUE(ours.factorize(a));
  expect_solves(a, ours);
}

TEST(SupernodalCholesky, RefusesAnIndefiniteMatrixThenFactorizesADefiniteOne) {
  const Eigen::SparseMatrix<double> a = grid_system(16, true, 4);
  SupernodalCholesky ours;
  ours.analyze(a);
  for (const int row : {5, static_cast<int>(a.rows()) - 1}) {  // in a narrow panel, and in the last, wide one
    Eigen::SparseMatrix<double> indefinite = a;
    indefinite.coeffRef(row, row) = -1.0;
    EXPECT_FALSE(ours.factorize(indefinite)) << "row " << row;
  }
  ASSERT_TRUE(ours.factorize(a));  // nothing left over from the failed attempts
  expect_solves(a, ours);
}

TEST(SparseCholesky, TakesSupernodesOnlyWhereTheFactorFillsIn) {
  const Eigen::SparseMatrix<double> sparse = grid_system(6, false, 5), filled = grid_system(40, false, 6);
  for (const auto* a : {&sparse, &filled}) {
    SparseCholesky ours;
    ours.analyze(*a);
    EXPECT_EQ(ours.supernodal(), a == &filled);
    ASSERT_TRUE(ours.factorize(*a));
    expect_solves(*a, ours);
  }
}

}  // namespace
}  // namespace atlas
