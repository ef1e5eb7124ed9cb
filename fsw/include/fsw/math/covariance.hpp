// Covariance hygiene, in one place: symmetrise, bound the diagonal, and
// Cholesky with failure reporting. Every estimator conditions its covariance
// through condition_covariance() after each step and factors through
// factor() / cholesky_lower(), so a failure is always detected the same way.
// Real-time core: fixed-size Eigen only, no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/QR>
#include <cmath>
#include <limits>

namespace fsw {

// P <- (P + P^T) / 2.
template <typename S, int N>
inline void symmetrize(Eigen::Matrix<S, N, N>& P) {
  for (int i = 0; i < N; ++i) {
    for (int j = i + 1; j < N; ++j) {
      const S m = S(0.5) * (P(i, j) + P(j, i));
      P(i, j) = m;
      P(j, i) = m;
    }
  }
}

// Keeps every variance inside [var_min(i), var_max(i)] without breaking
// positive definiteness: a variance below its floor is raised (adding a
// non-negative diagonal term), one above its ceiling is scaled down together
// with its row and column (a congruence D P D, which keeps correlations).
template <typename S, int N>
inline void bound_diagonal(Eigen::Matrix<S, N, N>& P, const Eigen::Matrix<S, N, 1>& var_min,
                           const Eigen::Matrix<S, N, 1>& var_max) {
  for (int i = 0; i < N; ++i) {
    if (P(i, i) < var_min(i)) {
      P(i, i) = var_min(i);
    } else if (P(i, i) > var_max(i)) {
      const S s = std::sqrt(var_max(i) / P(i, i));
      P.row(i) *= s;
      P.col(i) *= s;
      P(i, i) = var_max(i);
    }
  }
}

// The hygiene applied after every predict and update. Returns false (P then
// unspecified) when a variance is not positive or not finite: that is a
// numerical breakdown to report, not something to paper over with the floor.
template <typename S, int N>
inline bool condition_covariance(Eigen::Matrix<S, N, N>& P, const Eigen::Matrix<S, N, 1>& var_min,
                                 const Eigen::Matrix<S, N, 1>& var_max) {
  for (int i = 0; i < N; ++i) {
    if (!(P(i, i) > S(0)) || !std::isfinite(P(i, i))) return false;
  }
  symmetrize(P);
  bound_diagonal(P, var_min, var_max);
  return true;
}

// Factors A = L L^T. Returns false when A is not (numerically) positive
// definite or holds a non-finite value; Eigen's LLT alone lets NaN through.
template <typename S, int N>
inline bool factor(const Eigen::Matrix<S, N, N>& A, Eigen::LLT<Eigen::Matrix<S, N, N>>& llt) {
  if (!A.allFinite()) return false;
  llt.compute(A);
  if (llt.info() != Eigen::Success) return false;
  const auto& LL = llt.matrixLLT();
  for (int i = 0; i < N; ++i) {
    const S d = LL(i, i);
    if (!(d > S(0)) || !std::isfinite(d)) return false;
  }
  return true;
}

// Lower Cholesky factor L of A = L L^T; false (L unspecified) on failure.
template <typename S, int N>
inline bool cholesky_lower(const Eigen::Matrix<S, N, N>& A, Eigen::Matrix<S, N, N>& L) {
  Eigen::LLT<Eigen::Matrix<S, N, N>> llt;
  if (!factor(A, llt)) return false;
  L = llt.matrixL();
  return true;
}

// Lower Cholesky factor of a covariance that rounding may have left a hair
// short of positive definite: in float, after long stretches without a
// measurement, the correlations of position, velocity and the biases
// approach 1 and the last pivot falls below the rounding of the others. On
// failure the factor is retried with each variance raised by a relative
// jitter, 64 N eps, then 16 and 256 times that (float, N = 15: 1.1e-4,
// 1.8e-3, 2.9e-2), a statistically negligible inflation that only a breakdown
// pays. Returns 0 when A factored as it was, k = 1..3 when the k-th jitter
// was needed, -1 when none factored or A is not finite (L unspecified).
template <typename S, int N>
inline int cholesky_lower_repaired(const Eigen::Matrix<S, N, N>& A, Eigen::Matrix<S, N, N>& L) {
  if (cholesky_lower(A, L)) return 0;
  if (!A.allFinite()) return -1;
  S rel = S(64 * N) * std::numeric_limits<S>::epsilon();
  for (int k = 1; k <= 3; ++k) {  // bounded: three retries
    Eigen::Matrix<S, N, N> B = A;
    for (int i = 0; i < N; ++i) B(i, i) += rel * std::abs(A(i, i));
    if (cholesky_lower(B, L)) return k;
    rel *= S(16);
  }
  return -1;
}

// log det(A) from a successful factorisation.
template <typename S, int N>
inline S log_det(const Eigen::LLT<Eigen::Matrix<S, N, N>>& llt) {
  S acc = S(0);
  for (int i = 0; i < N; ++i) acc += std::log(llt.matrixLLT()(i, i));
  return S(2) * acc;
}

// The lower Cholesky factor L of A = B^T B taken from the rows of B (a
// Householder QR of B; A itself is never formed). Forming A squares B's
// spread: in float a 20 m prior against 10 um image noise (condition 1e8 >
// 1 / eps) rounds A's small directions away and A stops factoring, while
// the QR keeps them to B's own rounding. Returns false when B is not finite
// or not of full column rank (a pivot within rounding of zero).
template <typename S, int R, int N>
inline bool cholesky_from_rows(const Eigen::Matrix<S, R, N>& B, Eigen::Matrix<S, N, N>& L) {
  static_assert(R >= N, "at least as many rows as columns");
  if (!B.allFinite()) return false;
  const Eigen::HouseholderQR<Eigen::Matrix<S, R, N>> qr(B);
  L = qr.matrixQR().template topRows<N>().template triangularView<Eigen::Upper>().transpose();
  // A pivot at the QR's own rounding (R eps |B|) is a rank deficiency.
  const S tol = S(R) * std::numeric_limits<S>::epsilon() * B.cwiseAbs().maxCoeff();
  for (int i = 0; i < N; ++i) {
    if (L(i, i) < S(0)) L.col(i) = -L.col(i);  // a row of Q^T B may come out negated
    if (!(L(i, i) > tol) || !std::isfinite(L(i, i))) return false;
  }
  return true;
}

// log det(L L^T) for a lower factor with a positive diagonal.
template <typename S, int N>
inline S log_det_lower(const Eigen::Matrix<S, N, N>& L) {
  S acc = S(0);
  for (int i = 0; i < N; ++i) acc += std::log(L(i, i));
  return S(2) * acc;
}

// X <- (L L^T)^-1 X.
template <typename S, int N, int C>
inline void solve_lower_llt(const Eigen::Matrix<S, N, N>& L, Eigen::Matrix<S, N, C>& X) {
  L.template triangularView<Eigen::Lower>().solveInPlace(X);
  L.transpose().template triangularView<Eigen::Upper>().solveInPlace(X);
}

}  // namespace fsw
