// Covariance hygiene (fsw/covariance.hpp): the repaired Cholesky factors a
// covariance that rounding left a hair short of positive definite, leaves a
// positive definite one exactly as the plain factor does, and refuses an
// indefinite or non-finite one. Each case in float and double.
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <type_traits>

#include "fsw/math/covariance.hpp"

using namespace fsw;

namespace {
template <typename S>
class CovarianceTest : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(CovarianceTest, Scalars);

// Errors almost perfectly correlated (position, velocity and a bias after a
// long coast): rank one plus a diagonal of half an ulp, then one variance
// lowered by 8 ulps, so the exact matrix is indefinite by a few ulps of its
// variances: a hair short of positive definite.
template <typename S>
Eigen::Matrix<S, 3, 3> nearly_singular() {
  const S eps = std::numeric_limits<S>::epsilon();
  const Eigen::Matrix<S, 3, 1> v(S(3), S(2), S(1));
  Eigen::Matrix<S, 3, 3> A = v * v.transpose();
  for (int i = 0; i < 3; ++i) A(i, i) += S(0.5) * eps * A(i, i);
  A(1, 1) *= S(1) - S(8) * eps;
  return A;
}
}  // namespace

TYPED_TEST(CovarianceTest, PositiveDefiniteFactorsUnchanged) {
  using S = TypeParam;
  Eigen::Matrix<S, 3, 3> A;
  A << S(4), S(1), S(0.5), S(1), S(3), S(0.2), S(0.5), S(0.2), S(2);
  Eigen::Matrix<S, 3, 3> L0, L1;
  ASSERT_TRUE(cholesky_lower(A, L0));
  EXPECT_EQ(cholesky_lower_repaired(A, L1), 0);
  EXPECT_TRUE((L0.array() == L1.array()).all());
}

TYPED_TEST(CovarianceTest, RoundingShortOfPositiveDefiniteIsRepairedByARelativeJitter) {
  using S = TypeParam;
  const Eigen::Matrix<S, 3, 3> A = nearly_singular<S>();
  Eigen::Matrix<S, 3, 3> L;
  ASSERT_FALSE(cholesky_lower(A, L));  // the plain factor fails
  const int k = cholesky_lower_repaired(A, L);
  ASSERT_GE(k, 1);
  ASSERT_LE(k, 3);
  // L L^T is A with each variance raised by at most the k-th jitter and the
  // covariances untouched (to the factor's rounding).
  const S rel = S(64 * 3) * std::numeric_limits<S>::epsilon() * std::pow(S(16), S(k - 1));
  const Eigen::Matrix<S, 3, 3> B = L * L.transpose();
  for (int i = 0; i < 3; ++i) {
    EXPECT_GE(B(i, i), A(i, i) * (S(1) - S(8) * std::numeric_limits<S>::epsilon())) << i;
    EXPECT_LE(B(i, i), A(i, i) * (S(1) + S(1.01) * rel)) << i;
    for (int j = 0; j < i; ++j) {
      EXPECT_NEAR(double(B(i, j)), double(A(i, j)),
                  64.0 * double(std::numeric_limits<S>::epsilon()) * std::sqrt(double(A(i, i)) * double(A(j, j))))
          << i << "," << j;
    }
  }
}

TYPED_TEST(CovarianceTest, IndefiniteOrNonFiniteIsRefused) {
  using S = TypeParam;
  Eigen::Matrix<S, 2, 2> A;
  A << S(1), S(10), S(10), S(1);  // correlation 10
  Eigen::Matrix<S, 2, 2> L;
  EXPECT_EQ(cholesky_lower_repaired(A, L), -1);
  A << S(1), S(0), S(0), std::numeric_limits<S>::quiet_NaN();
  EXPECT_EQ(cholesky_lower_repaired(A, L), -1);
  A << S(1), S(0), S(0), S(-1e-3);
  EXPECT_EQ(cholesky_lower_repaired(A, L), -1);
}

// cholesky_from_rows: the factor of B^T B from B's rows equals the plain
// Cholesky factor where that one is accurate, and survives where forming
// B^T B loses the small directions: a 4 x 2 spread of 1e4 over a unit noise
// floor (condition 1e8, beyond float's 1 / eps = 1.7e7).
TYPED_TEST(CovarianceTest, FactorFromRowsMatchesCholeskyAndKeepsSmallDirections) {
  using S = TypeParam;
  Eigen::Matrix<S, 5, 3> B;
  B << S(2), S(0.5), S(-1), S(0.3), S(1), S(0.2), S(-0.4), S(0.1), S(3), S(1), S(1), S(1), S(0.5), S(-2), S(0.7);
  Eigen::Matrix<S, 3, 3> L, Lref;
  ASSERT_TRUE(cholesky_from_rows(B, L));
  ASSERT_TRUE(cholesky_lower(Eigen::Matrix<S, 3, 3>(B.transpose() * B), Lref));
  EXPECT_LT((L - Lref).cwiseAbs().maxCoeff(), S(50) * std::numeric_limits<S>::epsilon());
  EXPECT_NEAR(log_det_lower(L), std::log((B.transpose() * B).determinant()), S(1e-4));

  // Innovation-covariance shape: two wide columns of a prior's spread (one
  // image direction seen almost alike by both) over R^1/2 = I.
  Eigen::Matrix<double, 4, 2> Wd;
  Wd << 1e4, 1e4 * (1.0 + 1e-4), -1e4, -1e4, 1.0, 0.0, 0.0, 1.0;
  const Eigen::Matrix<S, 4, 2> W = Wd.cast<S>();
  const double det_exact = (Wd.transpose() * Wd).determinant();  // about 5e8: condition about 1e8
  Eigen::Matrix<S, 2, 2> Lw;
  ASSERT_TRUE(cholesky_from_rows(W, Lw));
  EXPECT_NEAR(std::exp(double(log_det_lower(Lw))) / det_exact, 1.0, 1e-2);
  if constexpr (std::is_same_v<S, float>) {
    // Formed in float, W^T W has lost its determinant to rounding.
    const Eigen::Matrix<S, 2, 2> A = W.transpose() * W;
    const double det_formed = double(A(0, 0)) * double(A(1, 1)) - double(A(0, 1)) * double(A(1, 0));
    EXPECT_GT(std::abs(det_formed / det_exact - 1.0), 0.5);
  }
  Eigen::Matrix<S, 4, 2> bad = W;
  bad(0, 0) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_FALSE(cholesky_from_rows(bad, Lw));
  Eigen::Matrix<S, 4, 2> rank1 = Eigen::Matrix<S, 4, 2>::Zero();
  rank1.col(0) << S(1), S(2), S(3), S(4);
  rank1.col(1) = S(2) * rank1.col(0);
  EXPECT_FALSE(cholesky_from_rows(rank1, Lw));
}

// The hygiene after every step: a variance below its floor is raised to it,
// one above its ceiling is brought down to it with its row and column (the
// correlations kept), the result is symmetric; a variance that is not
// positive or not finite is a breakdown, refused rather than floored.
TYPED_TEST(CovarianceTest, ConditioningBoundsTheVariancesAndKeepsCorrelations) {
  using S = TypeParam;
  using M3 = Eigen::Matrix<S, 3, 3>;
  using V3 = Eigen::Matrix<S, 3, 1>;
  M3 P;
  P << S(1e-12), S(0), S(0),    //
      S(0), S(4), S(3.0001),    // row 1 not yet symmetric
      S(0), S(2.9999), S(9e6);  // variance above its ceiling
  const V3 var_min(S(1e-6), S(1e-6), S(1e-6));
  const V3 var_max(S(1e3), S(1e3), S(1e2));
  const double corr12 = 3.0 / std::sqrt(4.0 * 9e6);
  ASSERT_TRUE(condition_covariance(P, var_min, var_max));
  EXPECT_EQ(P(0, 0), var_min(0));  // raised to the floor
  EXPECT_EQ(P(1, 1), S(4));        // inside its bounds: untouched
  EXPECT_EQ(P(2, 2), var_max(2));  // scaled down to the ceiling
  EXPECT_TRUE((P - P.transpose()).isZero(S(0)));
  EXPECT_NEAR(double(P(1, 2)) / std::sqrt(double(P(1, 1)) * double(P(2, 2))), corr12, 1e-5);
  M3 L;
  EXPECT_TRUE(cholesky_lower(P, L));

  for (const S bad : {S(0), S(-1), std::numeric_limits<S>::quiet_NaN(), std::numeric_limits<S>::infinity()}) {
    M3 Q = M3::Identity();
    Q(1, 1) = bad;
    EXPECT_FALSE(condition_covariance(Q, var_min, var_max)) << double(bad);
  }
}

// The factor's helpers: (L L^T)^-1 X by two triangular solves, and log det
// from a factor or from Eigen's LLT, against the determinant.
TYPED_TEST(CovarianceTest, SolveAndLogDetFromTheFactor) {
  using S = TypeParam;
  Eigen::Matrix<S, 3, 3> A;
  A << S(4), S(1), S(0.5), S(1), S(3), S(0.2), S(0.5), S(0.2), S(2);
  Eigen::LLT<Eigen::Matrix<S, 3, 3>> llt;
  ASSERT_TRUE(factor(A, llt));
  Eigen::Matrix<S, 3, 3> L;
  ASSERT_TRUE(cholesky_lower(A, L));
  Eigen::Matrix<S, 3, 2> X;
  X << S(1), S(-2), S(0.5), S(3), S(-1), S(0.25);
  const Eigen::Matrix<S, 3, 2> B = X;
  solve_lower_llt(L, X);
  EXPECT_LT((A * X - B).cwiseAbs().maxCoeff(), S(64) * std::numeric_limits<S>::epsilon());
  const double logdet = std::log(double(A.determinant()));
  EXPECT_NEAR(double(log_det(llt)), logdet, 1e-5);
  EXPECT_NEAR(double(log_det_lower(L)), logdet, 1e-5);
  // factor() refuses a non-finite matrix (Eigen's LLT alone lets NaN through).
  A(2, 2) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_FALSE(factor(A, llt));
}
