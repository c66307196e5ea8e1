// The symmetric Dirichlet energy of one face's Jacobian J (the 2x2 linear map
// from the reference triangle to the new UV triangle), and the SLIM proxy that
// stands in for it in the global step (Rabinovich et al. 2017). Inline: these
// run once per face per line-search trial, in the innermost loops of the solver.
#pragma once
#include <Eigen/Core>
#include <Eigen/LU>  // determinant()
#include <cmath>
#include <limits>

namespace atlas {

// psi(J) = s1^2 + s2^2 + s1^-2 + s2^-2 = |J|_F^2 + |J^-1|_F^2 = |J|_F^2 (1 + 1 / det(J)^2),
// since for 2x2 matrices |J^-1|_F = |J|_F / |det J|. Its minimum, 4, is at rotations.
// +inf for flipped or singular J: the barrier that keeps the map injective.
inline double symmetric_dirichlet_density(const Eigen::Matrix2d& J) {
  const double det = J.determinant();
  if (!(det > 0)) return std::numeric_limits<double>::infinity();
  return J.squaredNorm() * (1 + 1 / (det * det));
}

// det(J + t D) = det J + t determinant_rate(J, D) + t^2 det D for 2x2 matrices.
inline double determinant_rate(const Eigen::Matrix2d& J, const Eigen::Matrix2d& D) {
  return J(0, 0) * D(1, 1) + D(0, 0) * J(1, 1) - J(0, 1) * D(1, 0) - D(0, 1) * J(1, 0);
}

// d/dt psi(J + t D) at t = 0, for J with positive determinant a. With
// n = |J|_F^2, psi = n (1 + a^-2) and n' = 2 <J, D>: psi' = n' (1 + a^-2) - 2 n a' a^-3.
// The line search's slope, without forming the 2x2 gradient of psi.
inline double symmetric_dirichlet_rate(const Eigen::Matrix2d& J, const Eigen::Matrix2d& D) {
  const double a = J.determinant(), inverse_a = 1 / a;
  const double n_rate = 2 * J.cwiseProduct(D).sum();
  return inverse_a * inverse_a * (n_rate * (a * a + 1) - 2 * J.squaredNorm() * determinant_rate(J, D) * inverse_a);
}

// SLIM replaces psi near J_k by the quadratic |W (J - R)|_F^2, where R is the
// rotation closest to J_k and W = U diag(w1, w2) U^T (J_k = U diag(s1, s2) V^T)
// with w_i^2 = psi'(s_i) / (2 (s_i - 1)), so both have the same gradient at J_k.
// For symmetric Dirichlet psi'(s) = 2 (s - s^-3), hence
//   w^2 = (s - s^-3) / (s - 1) = (s + 1)(s^2 + 1) / s^3,
// written without the removable singularity at s = 1 (where w^2 = 4).
struct SlimProxyTarget {
  Eigen::Matrix2d rotation;  // R
  Eigen::Matrix2d weight;    // W^2 = U diag(w1^2, w2^2) U^T, symmetric positive definite
};

inline double slim_weight_squared(double s) { return (s + 1) * (s * s + 1) / (s * s * s); }

// Closed-form signed SVD of J = [a b; c d], for det(J) > 0. Split J into a
// similarity and an anti-similarity,
//   J = [E -H; H E] + [F G; G -F],  E = (a+d)/2, F = (a-d)/2, G = (c+b)/2, H = (c-b)/2,
// then with Q = |(E, H)|, P = |(F, G)|: s1 = Q + P, s2 = Q - P, the closest
// rotation is [E -H; H E] / Q, and U is the rotation by phi with
// 2 phi = atan2(G, F) + atan2(H, E), so cos 2phi = (FE - GH) / (PQ), sin 2phi = (GE + FH) / (PQ).
// U diag(p, q) U^T = (p+q)/2 I + (p-q)/2 [cos 2phi, sin 2phi; sin 2phi, -cos 2phi].
struct SimilaritySplit {
  double E, F, G, H, Q, P;
  double largest() const { return Q + P; }   // s1
  double smallest() const { return Q - P; }  // s2
};

inline SimilaritySplit similarity_split(const Eigen::Matrix2d& J) {
  SimilaritySplit split;
  split.E = (J(0, 0) + J(1, 1)) / 2, split.F = (J(0, 0) - J(1, 1)) / 2;
  split.G = (J(1, 0) + J(0, 1)) / 2, split.H = (J(1, 0) - J(0, 1)) / 2;
  split.Q = std::sqrt(split.E * split.E + split.H * split.H);
  split.P = std::sqrt(split.F * split.F + split.G * split.G);
  return split;
}

inline SlimProxyTarget slim_proxy_target(const Eigen::Matrix2d& J) {
  const auto [E, F, G, H, Q, P] = similarity_split(J);
  SlimProxyTarget target;
  target.rotation << E / Q, -H / Q, H / Q, E / Q;
  const double p = slim_weight_squared(Q + P), q = slim_weight_squared(Q - P);
  target.weight = (p + q) / 2 * Eigen::Matrix2d::Identity();
  // A conformal J (P = 0) has equal weights and any U; skip the 0/0.
  if (P > 1e-12 * Q) {
    const double scale = (p - q) / (2 * P * Q);
    const double c = scale * (F * E - G * H), s = scale * (G * E + F * H);
    target.weight(0, 0) += c;
    target.weight(1, 1) -= c;
    target.weight(0, 1) = target.weight(1, 0) = s;
  }
  return target;
}

}  // namespace atlas
