// The sliding-window Bayes linear regression against an independent batch
// solve of the same window (Householder QR of the prior-augmented data in
// long double), its exactness after millions of add/remove pairs, rejection
// of bad samples, and tracking of a step change in one thruster.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "fsw/thrusters/blr.hpp"

using namespace fsw;

namespace {

// Float build accuracy: a Cholesky solve loses about eps * cond(A) relative
// in theta (Frobenius), and the window sums of 0/1 inputs are exact, so the
// float build is held to kFloatPerCond * cond(A) with kFloatPerCond = eps_f
// (2^-23 = 1.19e-7); measured worst cases reach about a quarter of it.
// Windows of the random-walk autopilot have cond(A) from about 1e2 to 1e4.
// Documented in docs/perf/blr.md.
constexpr double kFloatPerCond = 1.1920929e-7;
// Double build against the long-double batch solve, relative.
constexpr double kDoubleThetaRel = 1e-9;

template <typename Blr>
double cond_information(const Blr& blr) {
  const Eigen::MatrixXd a = blr.information().template cast<double>();
  const Eigen::VectorXd ev = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(a).eigenvalues();
  return ev.maxCoeff() / ev.minCoeff();
}

// Allowed relative theta error of the scalar build S for this window.
template <typename S, typename Blr>
double theta_tol(const Blr& blr) {
  return std::is_same<S, double>::value ? kDoubleThetaRel : kFloatPerCond * cond_information(blr);
}

using Ld = long double;
using MatLd = Eigen::Matrix<Ld, Eigen::Dynamic, Eigen::Dynamic>;

// Batch ridge least squares over the window, solved as the augmented
// least-squares problem [X; sqrt(lambda) I] theta = [Y; 0] by Householder QR.
template <typename Blr>
MatLd batch_theta(const Blr& blr, Ld lambda) {
  constexpr int D = Blr::kInputs;
  constexpr int K = Blr::kOutputs;
  const int n = blr.count();
  MatLd X = MatLd::Zero(n + D, D);
  MatLd Y = MatLd::Zero(n + D, K);
  for (int i = 0; i < n; ++i) {
    X.row(i) = blr.window_x(i).transpose().template cast<Ld>();
    Y.row(i) = blr.window_y(i).transpose().template cast<Ld>();
  }
  for (int d = 0; d < D; ++d) X(n + d, d) = std::sqrt(lambda);
  return X.householderQr().solve(Y);
}

template <typename Blr>
double theta_rel_err(Blr& blr) {
  EXPECT_EQ(blr.refresh_posterior(), BlrStatus::Ok);
  const MatLd ref = batch_theta(blr, Ld(blr.config().prior_precision));
  const MatLd got = blr.theta().template cast<Ld>();
  return double((got - ref).norm() / ref.norm());
}

// Eight thrusters of bench/sim/vehicle.py: 20 mN at the corners of a 0.2 m cube,
// firing along face diagonals; 3 kg, J = diag(0.021, 0.019, 0.020) kg m^2.
// Returns the true weights (9 x 6): row i = [dv (m/s), dw (rad/s)] of valve
// i over one firing interval dt; row 8 (bias) = 0.
Eigen::Matrix<double, 9, 6> thruster_truth(double dt_s) {
  const double s2 = 1.0 / std::sqrt(2.0);
  const double pos[8][3] = {{1, 1, 1},    {1, 1, -1},  {1, -1, 1},  {1, -1, -1},
                            {-1, -1, -1}, {-1, -1, 1}, {-1, 1, -1}, {-1, 1, 1}};
  const double dir[8][3] = {{0, 1, -1}, {1, -1, 0}, {0, -1, -1}, {1, 1, 0},
                            {0, -1, 1}, {-1, 1, 0}, {0, 1, 1},   {-1, -1, 0}};
  const Eigen::Vector3d jdiag(0.021, 0.019, 0.020);
  Eigen::Matrix<double, 9, 6> th = Eigen::Matrix<double, 9, 6>::Zero();
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d r = 0.10 * Eigen::Vector3d(pos[i][0], pos[i][1], pos[i][2]);
    const Eigen::Vector3d f = 0.020 * s2 * Eigen::Vector3d(dir[i][0], dir[i][1], dir[i][2]);
    th.block<1, 3>(i, 0) = (f / 3.0 * dt_s).transpose();
    th.block<1, 3>(i, 3) = (r.cross(f).cwiseQuotient(jdiag) * dt_s).transpose();
  }
  return th;
}

// Random-walk autopilot: one randomly chosen valve toggles per interval.
struct Autopilot {
  std::uint8_t mask = 0;
  std::uint8_t next(std::mt19937_64& rng) {
    mask ^= std::uint8_t(1u << (rng() % 8));
    return mask;
  }
};

template <typename S>
using Blr9 = ThrusterBlr<S, 30>;

}  // namespace

template <typename S>
class BlrTyped : public ::testing::Test {};
using Scalars = ::testing::Types<double, float>;
TYPED_TEST_SUITE(BlrTyped, Scalars);

TEST(BlrFeatures, ValveMaskLayoutIsValvesThenBiasThenPairs) {
  const auto x = ValveFeatures<double, true>::from_mask(0b10000101);  // valves 0, 2, 7
  ASSERT_EQ(x.size(), 37);
  EXPECT_EQ(x(0), 1.0);
  EXPECT_EQ(x(1), 0.0);
  EXPECT_EQ(x(2), 1.0);
  EXPECT_EQ(x(7), 1.0);
  EXPECT_EQ(x(8), 1.0);  // bias
  // pairs (0,1), (0,2), ... ; (0,2) is index 9 + 1, (2,7) follows (0,*) 7 + (1,*) 6 + 4
  EXPECT_EQ(x(9), 0.0);
  EXPECT_EQ(x(10), 1.0);
  EXPECT_EQ(x(9 + 7 + 6 + 4), 1.0);
  EXPECT_EQ(x.tail(28).sum(), 3.0);  // C(3,2) open pairs
}

TYPED_TEST(BlrTyped, MatchesBatchSolveWhileTheWindowFills) {
  using S = TypeParam;
  Blr9<S> blr;
  std::mt19937_64 rng(1);
  std::normal_distribution<double> nd;
  Autopilot ap;
  const auto th = thruster_truth(0.2);
  double worst = 0;
  for (int k = 0; k < 30; ++k) {
    const auto x = ValveFeatures<double>::from_mask(ap.next(rng));
    Eigen::Matrix<double, 6, 1> y = th.transpose() * x;
    for (int j = 0; j < 6; ++j) y(j) += 1e-4 * nd(rng);
    ASSERT_TRUE(blr.add(x.cast<S>(), y.cast<S>()).entered);
    worst = std::max(worst, theta_rel_err(blr) / theta_tol<S>(blr));
  }
  EXPECT_EQ(blr.count(), 30);
  ::testing::Test::RecordProperty("worst_err_over_tol", std::to_string(worst));
  EXPECT_LT(worst, 1.0);
}

TYPED_TEST(BlrTyped, ExplicitRemovalsMatchBatchSolve) {
  using S = TypeParam;
  Blr9<S> blr;
  std::mt19937_64 rng(2);
  std::normal_distribution<double> nd;
  Autopilot ap;
  double worst = 0;
  int removed = 0;
  for (int k = 0; k < 2000; ++k) {
    const auto x = ValveFeatures<double>::from_mask(ap.next(rng));
    Eigen::Matrix<double, 6, 1> y;
    for (int j = 0; j < 6; ++j) y(j) = nd(rng);
    blr.add(x.cast<S>(), y.cast<S>());
    // Shrink the window at random, sometimes to a handful of samples.
    if (rng() % 7 == 0) {
      const int drop = int(rng() % 25);
      for (int i = 0; i < drop && blr.count() > 12; ++i) {
        ASSERT_EQ(blr.remove_oldest(), BlrStatus::Ok);
        ++removed;
      }
    }
    if (k % 50 == 0) worst = std::max(worst, theta_rel_err(blr) / theta_tol<S>(blr));
  }
  EXPECT_GT(removed, 1000);
  ::testing::Test::RecordProperty("worst_err_over_tol", std::to_string(worst));
  EXPECT_LT(worst, 1.0);
}

TEST(BlrDouble, ExactAfterTenMillionAddRemovePairs) {
  // Each add to the full window is one add/remove pair. Samples come from a
  // table of 4096 draws with outputs spanning six orders of magnitude, picked
  // by an xorshift generator (cheap enough for 1e7 pairs in about a second).
  constexpr int kTable = 4096;
  Eigen::MatrixXd xt(9, kTable), yt(6, kTable);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> nd;
  Autopilot ap;
  for (int i = 0; i < kTable; ++i) {
    xt.col(i) = ValveFeatures<double>::from_mask(ap.next(rng));
    const double scale = std::pow(10.0, -3.0 + 6.0 * double(rng() % 1000) / 1000.0);
    for (int j = 0; j < 6; ++j) yt(j, i) = scale * nd(rng);
  }
  Blr9<double> blr;
  std::uint64_t s = 0x9E3779B97F4A7C15ull;
  const auto t0 = std::chrono::steady_clock::now();
  constexpr long kPairs = 10'000'000;
  for (long k = 0; k < kPairs + 30; ++k) {
    s ^= s << 13;
    s ^= s >> 7;
    s ^= s << 17;
    const int i = int(s % kTable);
    blr.add(Eigen::Matrix<double, 9, 1>(xt.col(i)), Eigen::Matrix<double, 6, 1>(yt.col(i)));
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  RecordProperty("seconds", std::to_string(secs));
  EXPECT_GT(blr.refresh_count(), std::uint64_t(kPairs / 31));
  EXPECT_LT(theta_rel_err(blr), kDoubleThetaRel);
}

TEST(BlrDouble, ExactAfterHugeSamplesLeaveTheWindow) {
  // Outputs of 1e8 pass through the window, then only outputs of 1e-3 stay:
  // plain running sums would keep ~1e8 * 1e-16 of residue, 1e-5 relative.
  Blr9<double> blr;
  std::mt19937_64 rng(4);
  std::normal_distribution<double> nd;
  Autopilot ap;
  for (int k = 0; k < 200; ++k) {
    const double scale = k < 100 ? 1e8 : 1e-3;
    Eigen::Matrix<double, 6, 1> y;
    for (int j = 0; j < 6; ++j) y(j) = scale * nd(rng);
    blr.add(ValveFeatures<double>::from_mask(ap.next(rng)), y);
  }
  EXPECT_LT(theta_rel_err(blr), kDoubleThetaRel);
}

TYPED_TEST(BlrTyped, RejectsNanSampleAndKeepsTheWindow) {
  using S = TypeParam;
  Blr9<S> blr;
  std::mt19937_64 rng(5);
  Autopilot ap;
  for (int k = 0; k < 40; ++k) {
    Eigen::Matrix<S, 6, 1> y = Eigen::Matrix<S, 6, 1>::Constant(S(k % 5));
    blr.add(ValveFeatures<S>::from_mask(ap.next(rng)), y);
  }
  ASSERT_EQ(blr.refresh_posterior(), BlrStatus::Ok);
  const auto theta_before = blr.theta();
  const auto oldest_before = blr.window_x(0);
  Eigen::Matrix<S, 6, 1> y_nan = Eigen::Matrix<S, 6, 1>::Zero();
  y_nan(3) = std::numeric_limits<S>::quiet_NaN();
  const auto rec = blr.add(ValveFeatures<S>::from_mask(7), y_nan);
  EXPECT_EQ(rec.status, BlrStatus::BadInput);
  EXPECT_FALSE(rec.entered);
  EXPECT_FALSE(rec.evicted);
  EXPECT_EQ(blr.count(), 30);
  EXPECT_EQ(blr.window_x(0), oldest_before);
  ASSERT_EQ(blr.refresh_posterior(), BlrStatus::Ok);
  EXPECT_EQ(blr.theta(), theta_before);
  for (int i = 0; i < blr.count(); ++i) EXPECT_TRUE(blr.window_y(i).allFinite());
}

TYPED_TEST(BlrTyped, RejectsInfiniteInput) {
  using S = TypeParam;
  Blr9<S> blr;
  auto x = ValveFeatures<S>::from_mask(3);
  x(0) = std::numeric_limits<S>::infinity();
  const auto rec = blr.add(x, Eigen::Matrix<S, 6, 1>::Ones());
  EXPECT_EQ(rec.status, BlrStatus::BadInput);
  EXPECT_EQ(blr.count(), 0);
}

TYPED_TEST(BlrTyped, PredictRejectsNanInput) {
  using S = TypeParam;
  Blr9<S> blr;
  auto x = ValveFeatures<S>::from_mask(3);
  x(8) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_EQ(blr.predict(x).status, BlrStatus::BadInput);
}

TYPED_TEST(BlrTyped, RemoveFromEmptyWindowIsReported) {
  Blr9<TypeParam> blr;
  EXPECT_EQ(blr.remove_oldest(), BlrStatus::BadInput);
  EXPECT_EQ(blr.count(), 0);
}

TYPED_TEST(BlrTyped, EmptyWindowPredictsPriorMeanZero) {
  using S = TypeParam;
  Blr9<S> blr;
  const auto p = blr.predict(ValveFeatures<S>::from_mask(0xFF));
  EXPECT_EQ(p.status, BlrStatus::Ok);
  EXPECT_EQ(p.mean, (Eigen::Matrix<S, 6, 1>::Zero()));
  // A = lambda I: leverage = |x|^2 / lambda = 9 / 1e-3.
  EXPECT_NEAR(double(p.leverage), 9.0 / 1e-3, 9.0 / 1e-3 * 1e-6);
}

TYPED_TEST(BlrTyped, ZeroPriorWithRankDeficientWindowIsNotPosDef) {
  using S = TypeParam;
  BlrConfig<S, 6> cfg;
  cfg.prior_precision = S(0);
  Blr9<S> blr(cfg);
  // Valve 0 only: inputs span two of nine directions.
  for (int k = 0; k < 10; ++k) blr.add(ValveFeatures<S>::from_mask(k % 2), Eigen::Matrix<S, 6, 1>::Constant(S(k % 2)));
  const auto p = blr.predict(ValveFeatures<S>::from_mask(1));
  EXPECT_EQ(p.status, BlrStatus::NotPosDef);
  EXPECT_TRUE(std::isinf(double(p.variance(0))));
}

TEST(BlrDouble, PredictiveMeanAndVarianceMatchTheBatchPosterior) {
  Blr9<double> blr;
  std::mt19937_64 rng(6);
  std::normal_distribution<double> nd;
  Autopilot ap;
  const auto th = thruster_truth(0.2);
  for (int k = 0; k < 77; ++k) {
    const auto x = ValveFeatures<double>::from_mask(ap.next(rng));
    Eigen::Matrix<double, 6, 1> y = th.transpose() * x;
    for (int j = 0; j < 6; ++j) y(j) += 2e-4 * nd(rng);
    blr.add(x, y);
  }
  // Independent: A, B and the residual from the window in long double.
  const int n = blr.count();
  MatLd X(n, 9), Y(n, 6);
  for (int i = 0; i < n; ++i) {
    X.row(i) = blr.window_x(i).transpose().cast<Ld>();
    Y.row(i) = blr.window_y(i).transpose().cast<Ld>();
  }
  const Ld lambda = 1e-3L;
  const MatLd A = X.transpose() * X + lambda * MatLd::Identity(9, 9);
  const MatLd theta = A.ldlt().solve(X.transpose() * Y);
  const MatLd resid = Y - X * theta;
  const auto xq = ValveFeatures<double>::from_mask(0b01100110);
  const Eigen::Matrix<Ld, 9, 1> xl = xq.cast<Ld>();
  const Ld lev = xl.dot(A.ldlt().solve(xl));
  const auto p = blr.predict(xq);
  ASSERT_EQ(p.status, BlrStatus::Ok);
  EXPECT_NEAR(double(p.leverage), double(lev), 1e-12);
  for (int k = 0; k < 6; ++k) {
    // s_k^2 = (|r_k|^2 + lambda |theta_k|^2) / (n - D)
    const Ld s2 = (resid.col(k).squaredNorm() + lambda * theta.col(k).squaredNorm()) / (n - 9);
    const Ld mean = theta.col(k).dot(xl);
    EXPECT_NEAR(p.mean(k), double(mean), 1e-9 * std::abs(double(mean)) + 1e-15);
    EXPECT_NEAR(p.variance(k), double(s2 * (1 + lev)), 1e-6 * double(s2 * (1 + lev)));
  }
}

TEST(BlrFloat, FloatBuildWithinDocumentedToleranceOfDouble) {
  Blr9<double> bd;
  Blr9<float> bf;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> nd;
  Autopilot ap;
  const auto th = thruster_truth(0.2);
  double worst = 0;
  for (int k = 0; k < 5000; ++k) {
    const auto x = ValveFeatures<double>::from_mask(ap.next(rng));
    Eigen::Matrix<double, 6, 1> y = th.transpose() * x;
    for (int j = 0; j < 6; ++j) y(j) *= 1.0 + 0.15 * nd(rng);
    bd.add(x, y);
    bf.add(x.cast<float>(), y.cast<float>());
    if (k % 10 == 9) {
      ASSERT_EQ(bd.refresh_posterior(), BlrStatus::Ok);
      ASSERT_EQ(bf.refresh_posterior(), BlrStatus::Ok);
      const double rel = (bf.theta().cast<double>() - bd.theta()).norm() / bd.theta().norm();
      worst = std::max(worst, rel / (kFloatPerCond * cond_information(bd)));
    }
  }
  RecordProperty("worst_err_over_tol", std::to_string(worst));
  EXPECT_LT(worst, 1.0);
}

TEST(BlrDouble, TracksThirtyPercentThrusterDropWithinOneWindow) {
  // Thruster 3 loses 30 % of its thrust at sample 300 (15 % noise on every
  // output). The prediction error of the learned model against the truth
  // (linear part, RMS over all 256 valve configurations) is measured on the
  // mean model over 1000 seeded runs, which removes the window's estimation
  // noise and leaves the error the step causes. It must be back at its
  // pre-step level W = 30 samples after the step (the window then holds only
  // post-step samples) and well above it half a window after the step. The
  // per-run RMS error must also be back at its pre-step level after W.
  constexpr int kRuns = 1000, kStep = 300, kEnd = kStep + 60, W = 30;
  const double dt = 0.2;
  const auto th0 = thruster_truth(dt);
  auto th1 = th0;
  th1.row(3) *= 0.7;
  // M = mean over configurations of x x^T, so RMS error = sqrt(trace(E^T M E)).
  Eigen::Matrix<double, 9, 9> M = Eigen::Matrix<double, 9, 9>::Zero();
  for (int m = 0; m < 256; ++m) {
    const auto x = ValveFeatures<double>::from_mask(std::uint8_t(m));
    M += x * x.transpose() / 256.0;
  }
  auto rms = [&M](const Eigen::Matrix<double, 9, 3>& e) { return std::sqrt((e.transpose() * M * e).trace()); };
  std::vector<Eigen::Matrix<double, 9, 3>> mean_theta(kEnd, Eigen::Matrix<double, 9, 3>::Zero());
  Eigen::VectorXd run_err = Eigen::VectorXd::Zero(kEnd);
  std::mt19937_64 rng(8);
  std::normal_distribution<double> nd;
  for (int r = 0; r < kRuns; ++r) {
    Blr9<double> blr;
    Autopilot ap;
    for (int k = 0; k < kEnd; ++k) {
      const auto& th = k < kStep ? th0 : th1;
      const auto x = ValveFeatures<double>::from_mask(ap.next(rng));
      Eigen::Matrix<double, 6, 1> y = th.transpose() * x;
      for (int j = 0; j < 6; ++j) y(j) *= 1.0 + 0.15 * nd(rng);
      blr.add(x, y);
      ASSERT_EQ(blr.refresh_posterior(), BlrStatus::Ok);
      mean_theta[k] += blr.theta().leftCols<3>() / kRuns;
      run_err(k) += rms(blr.theta().leftCols<3>() - th.leftCols<3>()) / kRuns;
    }
  }
  Eigen::VectorXd mean_err(kEnd);
  for (int k = 0; k < kEnd; ++k) mean_err(k) = rms(mean_theta[k] - (k < kStep ? th0 : th1).leftCols<3>());
  const double before = mean_err.segment(kStep - 100, 100).mean();
  const double half = mean_err(kStep + W / 2 - 1);
  const double after = mean_err.segment(kStep + W - 1, 10).mean();
  const double run_before = run_err.segment(kStep - 100, 100).mean();
  const double run_after = run_err.segment(kStep + W - 1, 10).mean();
  RecordProperty("mean_model_before", std::to_string(before));
  RecordProperty("mean_model_half_window", std::to_string(half));
  RecordProperty("mean_model_after_window", std::to_string(after));
  RecordProperty("per_run_before", std::to_string(run_before));
  RecordProperty("per_run_after_window", std::to_string(run_after));
  EXPECT_GT(half, 3.0 * before);
  EXPECT_LT(after, 1.2 * before);
  EXPECT_LT(run_after, 1.05 * run_before);
}

// A negative or NaN prior precision is taken as 0 and a negative, NaN or
// infinite noise variance as 1; the window's sums are reported as entered
// (B = sum x y^T), full() once W samples are in, and the shadow
// accumulator's refreshes are counted as samples leave the window.
TYPED_TEST(BlrTyped, ConfigurationIsSanitisedAndTheWindowSumsAreReported) {
  using S = TypeParam;
  BlrConfig<S, 6> bad;
  bad.prior_precision = S(-1);
  bad.noise_var << S(-1), std::numeric_limits<S>::quiet_NaN(), std::numeric_limits<S>::infinity(), S(0), S(2), S(3);
  const Blr9<S> sane(bad);
  EXPECT_EQ(sane.config().prior_precision, S(0));
  EXPECT_EQ(sane.config().noise_var, (Eigen::Matrix<S, 6, 1>() << 1, 1, 1, 0, 2, 3).finished());
  EXPECT_EQ(sane.noise_var(), sane.config().noise_var);  // before any refresh: the configured ones
  bad.prior_precision = std::numeric_limits<S>::quiet_NaN();
  EXPECT_EQ(Blr9<S>(bad).config().prior_precision, S(0));

  Blr9<S> blr;
  typename Blr9<S>::MatB B = Blr9<S>::MatB::Zero();
  for (int k = 0; k < 30; ++k) {
    EXPECT_FALSE(blr.full());
    const auto x = ValveFeatures<S>::from_mask(std::uint8_t(k * 37 + 1));
    const Eigen::Matrix<S, 6, 1> y = Eigen::Matrix<S, 6, 1>::Constant(S(k % 5));
    ASSERT_TRUE(blr.add(x, y).entered);
    B += x * y.transpose();
  }
  EXPECT_TRUE(blr.full());
  EXPECT_EQ(blr.information_vectors(), B);  // small integers: exact
  EXPECT_EQ(blr.refresh_count(), 0u);
  for (int k = 0; k < 60; ++k) blr.add(ValveFeatures<S>::from_mask(std::uint8_t(k)), Eigen::Matrix<S, 6, 1>::Ones());
  // Every sample older than an epoch leaves within one window: two windows
  // of adds after the first fill give at least one refresh.
  EXPECT_GE(blr.refresh_count(), 1u);
  EXPECT_EQ(blr.count(), 30);
  ASSERT_EQ(blr.refresh_posterior(), BlrStatus::Ok);
  EXPECT_TRUE((blr.noise_var().array() >= S(0)).all());
}
