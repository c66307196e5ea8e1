#include <gtest/gtest.h>

#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <random>
#include <vector>

#include "flatten/pair_cholesky.hpp"
#include "test_meshes.hpp"

namespace atlas {
namespace {

// Upper triangle of a random SPD matrix on a grid's vertex graph, scattered
// by a random vertex order: with `pairs`, two unknowns per vertex and a full
// 2x2 block per coupled pair (the SLIM pattern), else one unknown per vertex.
Eigen::SparseMatrix<double> grid_system(int n, bool pairs, unsigned seed) {
  const Mesh mesh = testing::grid_disk(n);
  const int vertices = static_cast<int>(mesh.positions.rows()), width = pairs ? 2 : 1;
  std::mt19937 random(seed);
  std::vector<int> order(vertices);
  for (int v = 0; v < vertices; ++v) order[v] = v;
  std::shuffle(order.begin(), order.end(), random);
  std::uniform_real_distribution<double> coupling(-1.0, 0.0);
  std::vector<Eigen::Triplet<double>> entries;
  std::vector<double> diagonal(width * vertices, 1e-3);
  auto couple = [&](int a, int b) {
    for (int i = 0; i < width; ++i)
      for (int j = 0; j < width; ++j) {
        const int r = width * order[a] + i, c = width * order[b] + j;
        const double w = coupling(random);
        if (r == c) continue;
        entries.emplace_back(std::min(r, c), std::max(r, c), w);
        diagonal[r] -= w, diagonal[c] -= w;
      }
  };
  for (int f = 0; f < mesh.face_count(); ++f)
    for (int k = 0; k < 3; ++k) couple(mesh.triangles(f, k), mesh.triangles(f, (k + 1) % 3));
  for (int v = 0; v < vertices && pairs; ++v) couple(v, v);  // the vertex's own 2x2 block
  for (int r = 0; r < width * vertices; ++r) entries.emplace_back(r, r, diagonal[r]);
  Eigen::SparseMatrix<double> a(width * vertices, width * vertices);
  a.setFromTriplets(entries.begin(), entries.end());
  a.makeCompressed();
  return a;
}

using EigenLLT = Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Upper, Eigen::NaturalOrdering<int>>;

// ours, factorized from a, solves A x = b to the same bits as Eigen's
// SimplicialLLT in natural order.
void expect_same_solution(const Eigen::SparseMatrix<double>& a, const PairCholesky& ours) {
  const EigenLLT eigen(a);
  ASSERT_EQ(eigen.info(), Eigen::Success);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(a.rows(), -1.0, 2.0);
  const Eigen::VectorXd expected = eigen.solve(b);
  Eigen::VectorXd x;
  ours.solve(b, x);
  for (Eigen::Index i = 0; i < a.rows(); ++i) EXPECT_EQ(x[i], expected[i]) << "row " << i;
}

void expect_same_as_eigen(const Eigen::SparseMatrix<double>& a) {
  PairCholesky ours;
  ours.analyze(a);
  ASSERT_TRUE(ours.factorize(a));
  expect_same_solution(a, ours);
}

TEST(PairCholesky, MatchesEigenBitForBitOnVertexPairs) { expect_same_as_eigen(grid_system(12, true, 1)); }

TEST(PairCholesky, MatchesEigenBitForBitWithoutPairs) { expect_same_as_eigen(grid_system(12, false, 2)); }

TEST(PairCholesky, MatchesEigenAfterRefactorizing) {
  Eigen::SparseMatrix<double> a = grid_system(8, true, 3);
  PairCholesky ours;
  ours.analyze(a);
  ASSERT_TRUE(ours.factorize(a));
  a.coeffs() *= 1.5;  // new values, same pattern
  ASSERT_TRUE(ours.factorize(a));
  expect_same_solution(a, ours);
}

TEST(PairCholesky, RefusesAnIndefiniteMatrixThenFactorizesADefiniteOne) {
  const Eigen::SparseMatrix<double> a = grid_system(6, true, 4);
  PairCholesky ours;
  ours.analyze(a);
  Eigen::SparseMatrix<double> indefinite = a;
  indefinite.coeffRef(5, 5) = -1.0;
  EXPECT_FALSE(ours.factorize(indefinite));
  ASSERT_TRUE(ours.factorize(a));  // nothing left over from the failed attempt
  expect_same_solution(a, ours);
}

}  // namespace
}  // namespace atlas
