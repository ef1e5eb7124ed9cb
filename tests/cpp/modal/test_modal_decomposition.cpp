// Modal decomposition (eqs. 2-4) against an independent dense least-squares
// solve of the same points (Eigen dynamic QR, test side only), and its
// off-nominal statuses.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "fsw/modal/modal_decomposition.hpp"

using namespace fsw;

namespace {
constexpr int kM = 3;

template <typename S>
struct Case {
  Eigen::MatrixXd phi;  // n x M
  Eigen::VectorXd z, var, a_true;
  std::vector<S> phi_rm, z_s, var_s;  // row-major copies in S
};

// Smooth mode-like shapes on random points of [0, 1], a true amplitude vector
// and per-point noise of varying variance.
template <typename S>
Case<S> make_case(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  Case<S> c;
  c.phi.resize(n, kM);
  c.z.resize(n);
  c.var.resize(n);
  c.a_true = Eigen::Vector3d(0.7, -0.3, 0.2);
  for (int k = 0; k < n; ++k) {
    const double x = u(rng);
    for (int i = 0; i < kM; ++i) c.phi(k, i) = std::sin((i + 1) * M_PI * x);
    c.var(k) = 1e-4 * (1.0 + 3.0 * u(rng));
    c.z(k) = c.phi.row(k).dot(c.a_true) + std::sqrt(c.var(k)) * g(rng);
  }
  for (int k = 0; k < n; ++k) {
    for (int i = 0; i < kM; ++i) c.phi_rm.push_back(S(c.phi(k, i)));
    c.z_s.push_back(S(c.z(k)));
    c.var_s.push_back(S(c.var(k)));
  }
  return c;
}

template <typename S>
struct DecompTol;
template <>
struct DecompTol<double> {
  static constexpr double rel = 1e-10;
};
template <>
struct DecompTol<float> {
  static constexpr double rel = 2e-4;
};
}  // namespace

template <typename S>
class ModalDecompositionTest : public ::testing::Test {};
using Scalars = ::testing::Types<double, float>;
TYPED_TEST_SUITE(ModalDecompositionTest, Scalars);

TYPED_TEST(ModalDecompositionTest, CoarseEstimateMatchesDenseLeastSquares) {
  using S = TypeParam;
  const auto c = make_case<S>(100, 1);  // 100 points: more than three chunks of 32
  ModalDecompositionConfig<S> cfg;
  cfg.sigma_e_m = S(0.01);
  ModalDecomposition<S, kM> d(cfg);
  EXPECT_EQ(d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 100), 100);
  ModalDecompositionRecord<S, kM> r;
  ASSERT_EQ(d.solve(r), ModalStatus::Ok);
  // Independent solve (in double, from the values the filter saw).
  Eigen::MatrixXd phi(100, kM);
  Eigen::VectorXd z(100);
  for (int k = 0; k < 100; ++k) {
    for (int i = 0; i < kM; ++i) phi(k, i) = double(c.phi_rm[k * kM + i]);
    z(k) = double(c.z_s[k]);
  }
  const Eigen::VectorXd a_ls = phi.colPivHouseholderQr().solve(z);
  const Eigen::MatrixXd cov_ls = 1e-4 * (phi.transpose() * phi).inverse();  // eq. 4b
  for (int i = 0; i < kM; ++i) EXPECT_NEAR(double(r.a_coarse(i)), a_ls(i), DecompTol<S>::rel * 10);
  EXPECT_LT((r.cov_a.template cast<double>() - cov_ls).norm() / cov_ls.norm(), DecompTol<S>::rel * 10);
  EXPECT_FALSE(r.per_point_variance);
  EXPECT_EQ(r.n_used, 100);
  // Residual variance RSS / (n - M).
  const double rss = (z - phi * a_ls).squaredNorm();
  const double res_tol = std::is_same<S, float>::value ? 5e-6 : 1e-12;
  EXPECT_NEAR(double(r.sigma2_residual_m2), rss / (100 - kM), res_tol);
  // Condition number from the eigenvalues of Phi^T Phi.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(phi.transpose() * phi);
  const double cond = es.eigenvalues()(kM - 1) / es.eigenvalues()(0);
  EXPECT_NEAR(double(r.condition_number), cond, cond * DecompTol<S>::rel * 10);
}

TYPED_TEST(ModalDecompositionTest, PerPointVarianceCovarianceMatchesSandwichFormula) {
  using S = TypeParam;
  const auto c = make_case<S>(70, 2);
  ModalDecomposition<S, kM> d;
  d.add_points(c.phi_rm.data(), c.z_s.data(), c.var_s.data(), 70);
  ModalDecompositionRecord<S, kM> r;
  ASSERT_EQ(d.solve(r), ModalStatus::Ok);
  EXPECT_TRUE(r.per_point_variance);
  Eigen::MatrixXd phi(70, kM);
  Eigen::VectorXd var(70);
  for (int k = 0; k < 70; ++k) {
    for (int i = 0; i < kM; ++i) phi(k, i) = double(c.phi_rm[k * kM + i]);
    var(k) = double(c.var_s[k]);
  }
  const Eigen::MatrixXd mi = (phi.transpose() * phi).inverse();
  const Eigen::MatrixXd cov = mi * phi.transpose() * var.asDiagonal() * phi * mi;  // eq. 4a
  EXPECT_LT((r.cov_a.template cast<double>() - cov).norm() / cov.norm(), DecompTol<S>::rel * 10);
}

TYPED_TEST(ModalDecompositionTest, EstimateIsUnbiasedOverNoiseDraws) {
  using S = TypeParam;
  // Mean of A~ over 200 noise draws is within 4 standard errors of the truth.
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d sd = Eigen::Vector3d::Zero();
  const int draws = 200;
  for (int t = 0; t < draws; ++t) {
    const auto c = make_case<S>(60, 100 + t);
    ModalDecomposition<S, kM> d;
    d.add_points(c.phi_rm.data(), c.z_s.data(), c.var_s.data(), 60);
    ModalDecompositionRecord<S, kM> r;
    ASSERT_EQ(d.solve(r), ModalStatus::Ok);
    sum += r.a_coarse.template cast<double>();
    sd += r.cov_a.diagonal().template cast<double>().cwiseSqrt();
  }
  const Eigen::Vector3d mean = sum / draws;
  const Eigen::Vector3d se = sd / draws / std::sqrt(double(draws));
  const Eigen::Vector3d a_true(0.7, -0.3, 0.2);
  for (int i = 0; i < kM; ++i) EXPECT_LT(std::abs(mean(i) - a_true(i)), 4 * se(i));
}

TYPED_TEST(ModalDecompositionTest, NanPointsAreSkippedAndCounted) {
  using S = TypeParam;
  auto c = make_case<S>(50, 3);
  ModalDecomposition<S, kM> clean;
  clean.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 40);
  c.z_s[40] = std::numeric_limits<S>::quiet_NaN();
  c.phi_rm[41 * kM + 1] = std::numeric_limits<S>::infinity();
  for (int k = 42; k < 50; ++k) c.z_s[k] = std::numeric_limits<S>::quiet_NaN();
  ModalDecomposition<S, kM> d;
  EXPECT_EQ(d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 50), 40);
  ModalDecompositionRecord<S, kM> r, r_clean;
  ASSERT_EQ(d.solve(r), ModalStatus::Ok);
  ASSERT_EQ(clean.solve(r_clean), ModalStatus::Ok);
  EXPECT_EQ(r.n_nonfinite, 10);
  EXPECT_EQ(r.n_used, 40);
  EXPECT_EQ(r.a_coarse, r_clean.a_coarse);  // the skipped points left no trace
}

TYPED_TEST(ModalDecompositionTest, TooFewPointsGivesStatusAndNoEstimate) {
  using S = TypeParam;
  const auto c = make_case<S>(10, 4);
  ModalDecomposition<S, kM> d;
  d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, kM);  // M points: need M + 1
  ModalDecompositionRecord<S, kM> r;
  EXPECT_EQ(d.solve(r), ModalStatus::TooFewPoints);
  EXPECT_EQ(r.a_coarse, (Eigen::Matrix<S, kM, 1>::Zero()));
  EXPECT_FALSE(r.ok());
}

TYPED_TEST(ModalDecompositionTest, MinPointsConfigRaisesTheThreshold) {
  using S = TypeParam;
  const auto c = make_case<S>(30, 5);
  ModalDecompositionConfig<S> cfg;
  cfg.min_points = 31;
  ModalDecomposition<S, kM> d(cfg);
  d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 30);
  ModalDecompositionRecord<S, kM> r;
  EXPECT_EQ(d.solve(r), ModalStatus::TooFewPoints);
}

TYPED_TEST(ModalDecompositionTest, SpatiallyAliasedSampleSpaceIsIllConditioned) {
  using S = TypeParam;
  // Samples only at x = 1/4 and 3/4 (and their repeats): sin(pi x) and
  // sin(3 pi x) take proportional values there (ratio +-1 after sign), so
  // modes 1 and 3 are aliased: M_Y is singular.
  ModalDecomposition<S, kM> d;
  for (int k = 0; k < 40; ++k) {
    const double x = (k % 2) ? 0.25 : 0.75;
    const S phi[kM] = {S(std::sin(M_PI * x)), S(std::sin(2 * M_PI * x)), S(std::sin(3 * M_PI * x))};
    d.add_point(phi, S(0.1));
  }
  ModalDecompositionRecord<S, kM> r;
  EXPECT_EQ(d.solve(r), ModalStatus::IllConditioned);
  EXPECT_GT(r.condition_number, d.config().max_condition);
  EXPECT_EQ(r.a_coarse, (Eigen::Matrix<S, kM, 1>::Zero()));
}

TYPED_TEST(ModalDecompositionTest, MixedVarianceInputIsBadInput) {
  using S = TypeParam;
  const auto c = make_case<S>(20, 6);
  ModalDecomposition<S, kM> d;
  d.add_points(c.phi_rm.data(), c.z_s.data(), c.var_s.data(), 10);
  d.add_points(c.phi_rm.data() + 10 * kM, c.z_s.data() + 10, nullptr, 10);
  ModalDecompositionRecord<S, kM> r;
  EXPECT_EQ(d.solve(r), ModalStatus::BadInput);
}

TYPED_TEST(ModalDecompositionTest, NonPositiveVarianceSkipsThePoint) {
  using S = TypeParam;
  auto c = make_case<S>(20, 7);
  c.var_s[3] = S(0);
  c.var_s[4] = std::numeric_limits<S>::quiet_NaN();
  ModalDecomposition<S, kM> d;
  EXPECT_EQ(d.add_points(c.phi_rm.data(), c.z_s.data(), c.var_s.data(), 20), 18);
  ModalDecompositionRecord<S, kM> r;
  EXPECT_EQ(d.solve(r), ModalStatus::Ok);
  EXPECT_EQ(r.n_bad_variance, 2);
}

TYPED_TEST(ModalDecompositionTest, ResetStartsANewImage) {
  using S = TypeParam;
  const auto c = make_case<S>(40, 8);
  ModalDecomposition<S, kM> d, fresh;
  d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 25);
  d.reset();
  d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 40);
  fresh.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 40);
  ModalDecompositionRecord<S, kM> r1, r2;
  ASSERT_EQ(d.solve(r1), ModalStatus::Ok);
  ASSERT_EQ(fresh.solve(r2), ModalStatus::Ok);
  EXPECT_EQ(r1.a_coarse, r2.a_coarse);
}

// A new configuration applies from the next solve; the running counts
// follow the points entered.
TYPED_TEST(ModalDecompositionTest, SetConfigAppliesToTheNextSolveAndCountsFollowThePoints) {
  using S = TypeParam;
  auto c = make_case<S>(30, 6);
  c.z_s[3] = std::numeric_limits<S>::quiet_NaN();
  ModalDecomposition<S, kM> d;
  d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 30);
  EXPECT_EQ(d.n_used(), 29);
  EXPECT_EQ(d.n_nonfinite(), 1);
  ModalDecompositionConfig<S> cfg;
  cfg.min_points = 30;
  d.set_config(cfg);
  EXPECT_EQ(d.config().min_points, 30);
  ModalDecompositionRecord<S, kM> r;
  EXPECT_EQ(d.solve(r), ModalStatus::TooFewPoints);
  d.set_config(ModalDecompositionConfig<S>());
  EXPECT_EQ(d.solve(r), ModalStatus::Ok);
  EXPECT_EQ(r.n_used, 29);
}

// Deflections at the largest finite value (each one accepted) overflow the
// accumulated sums: the solution is not finite, and the image is refused as
// ill-conditioned with no estimate rather than passed on.
TYPED_TEST(ModalDecompositionTest, OverflowingDeflectionsAreIllConditionedWithNoEstimate) {
  using S = TypeParam;
  auto c = make_case<S>(40, 7);
  for (auto& z : c.z_s) z = std::numeric_limits<S>::max();
  ModalDecomposition<S, kM> d;
  ASSERT_EQ(d.add_points(c.phi_rm.data(), c.z_s.data(), nullptr, 40), 40);
  ModalDecompositionRecord<S, kM> r;
  EXPECT_EQ(d.solve(r), ModalStatus::IllConditioned);
  EXPECT_EQ(r.a_coarse, (Eigen::Matrix<S, kM, 1>::Zero()));
  EXPECT_EQ(r.cov_a, (Eigen::Matrix<S, kM, kM>::Zero()));
  EXPECT_FALSE(r.ok());
}
