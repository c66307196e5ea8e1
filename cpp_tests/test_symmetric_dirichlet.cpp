// The per-face formulas SLIM's line search and proxy rest on, against finite
// differences of the energy itself.
#include <gtest/gtest.h>

#include "flatten/symmetric_dirichlet.hpp"

namespace atlas {
namespace {

const Eigen::Matrix2d kJ = (Eigen::Matrix2d() << 1.7, 0.4, -0.3, 0.6).finished();  // det 1.14
const Eigen::Matrix2d kD = (Eigen::Matrix2d() << -0.2, 0.9, 0.5, 0.1).finished();

double central_difference(const Eigen::Matrix2d& J, const Eigen::Matrix2d& D) {
  const double h = 1e-6;
  return (symmetric_dirichlet_density(J + h * D) - symmetric_dirichlet_density(J - h * D)) / (2 * h);
}

TEST(SymmetricDirichlet, DensityIsFourAtRotationsAndInfiniteWhenFlipped) {
  const double c = std::cos(0.7), s = std::sin(0.7);
  EXPECT_NEAR(symmetric_dirichlet_density((Eigen::Matrix2d() << c, -s, s, c).finished()), 4.0, 1e-12);
  EXPECT_TRUE(std::isinf(symmetric_dirichlet_density((Eigen::Matrix2d() << 1, 0, 0, -1).finished())));
}

TEST(SymmetricDirichlet, DeterminantIsQuadraticAlongALine) {
  for (const double t : {-1.3, 0.4, 2.5})
    EXPECT_NEAR((kJ + t * kD).determinant(), kJ.determinant() + t * determinant_rate(kJ, kD) + t * t * kD.determinant(),
                1e-12);
}

TEST(SymmetricDirichlet, RateAlongALineMatchesFiniteDifferences) {
  EXPECT_NEAR(symmetric_dirichlet_rate(kJ, kD), central_difference(kJ, kD), 1e-6);
  const Eigen::Matrix2d thin = (Eigen::Matrix2d() << 3.0, 0.0, 0.1, 0.05).finished();
  EXPECT_NEAR(symmetric_dirichlet_rate(thin, kD), central_difference(thin, kD),
              1e-6 * std::abs(central_difference(thin, kD)));
}

// SLIM's weights are chosen so that the proxy |W (J - R)|^2 has the energy's
// gradient at J: d/dt |W (J + t D - R)|^2 = 2 <M (J - R), D> with M = W^2.
TEST(SymmetricDirichlet, ProxyHasTheEnergysGradient) {
  for (const Eigen::Matrix2d& J : {kJ, Eigen::Matrix2d(2 * Eigen::Matrix2d::Identity()),
                                   Eigen::Matrix2d((Eigen::Matrix2d() << 0.3, -0.1, 0.2, 4.0).finished())}) {
    const SlimProxyTarget proxy = slim_proxy_target(J);
    for (const Eigen::Matrix2d& D : {kD, Eigen::Matrix2d(Eigen::Matrix2d::Identity())}) {
      const double proxy_rate = 2 * (proxy.weight * (J - proxy.rotation)).cwiseProduct(D).sum();
      EXPECT_NEAR(proxy_rate, symmetric_dirichlet_rate(J, D), 1e-9 * (1 + std::abs(proxy_rate)));
    }
  }
}

}  // namespace
}  // namespace atlas
