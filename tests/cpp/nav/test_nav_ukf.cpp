// Navigation UKF (fsw/nav_ukf.hpp): physical statements about the filter,
// each checked in float and double. Truth is integrated inside the test with
// the closed-form CW step and the exact attitude step, in double.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "fsw/math/covariance.hpp"
#include "fsw/nav/nav_ukf.hpp"
#include "tolerances.hpp"

using namespace fsw;

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kPosSigma = 0.0375;  // 5 % of 0.75 m [m]
constexpr double kAttSigma = 0.01;    // [rad]

template <typename S>
NavConfig<S> test_config() {
  NavConfig<S> c;
  c.accel_sigma_mps2 = S(1.7e-3);
  c.gyro_sigma_rps = S(0.005);
  return c;
}

template <typename S, bool B>
typename NavUkf<S, B>::Cov initial_cov() {
  typename NavUkf<S, B>::Cov P = NavUkf<S, B>::Cov::Zero();
  for (int i = 0; i < 3; ++i) {
    P(i, i) = S(0.05 * 0.05);
    P(3 + i, 3 + i) = S(0.01 * 0.01);
    P(6 + i, 6 + i) = S(0.05 * 0.05);
  }
  if constexpr (B) {
    for (int i = 9; i < 12; ++i) P(i, i) = S(1e-3 * 1e-3);
    for (int i = 12; i < 15; ++i) P(i, i) = S(1e-3 * 1e-3);
  }
  return P;
}

template <typename S>
Eigen::Matrix<S, 6, 6> pose_R() {
  Eigen::Matrix<S, 6, 6> R = Eigen::Matrix<S, 6, 6>::Zero();
  for (int i = 0; i < 3; ++i) {
    R(i, i) = S(kPosSigma * kPosSigma);
    R(3 + i, 3 + i) = S(kAttSigma * kAttSigma);
  }
  return R;
}

template <typename S, bool B = false>
NavUkf<S, B> make_filter(double t0 = 0.0) {
  NavUkf<S, B> f(test_config<S>());
  typename NavUkf<S, B>::State x;
  x.r_hill_m = Vec3<S>(S(0.75), S(0), S(0));
  x.q_hb = normalized(Quat<S>(S(0.9), S(0.1), S(-0.2), S(0.3)));
  EXPECT_TRUE(f.init(t0, x, initial_cov<S, B>()).ok());
  return f;
}

// The filter's current state and covariance as raw bytes, to prove
// "untouched" bit for bit.
template <typename F>
bool same_bits(const F& a, const F& b) {
  const auto sa = a.state().stored();
  const auto sb = b.state().stored();
  return a.t_s() == b.t_s() && std::memcmp(sa.data(), sb.data(), sizeof(sa)) == 0 &&
         std::memcmp(a.P().data(), b.P().data(), sizeof(a.P())) == 0;
}

template <typename S, int N>
bool is_pos_def(const Eigen::Matrix<S, N, N>& P) {
  Eigen::Matrix<S, N, N> L;
  return cholesky_lower(P, L);
}

// Upper quantile of chi-square(k), Wilson-Hilferty; accurate to < 0.5 % for k >= 100.
double chi2_quantile(double k, double z) {
  const double h = 2.0 / (9.0 * k);
  const double c = 1.0 - h + z * std::sqrt(h);
  return k * c * c * c;
}

}  // namespace

template <typename S>
class NavUkfTest : public ::testing::Test {};
using Scalars = ::testing::Types<float, double>;
TYPED_TEST_SUITE(NavUkfTest, Scalars);

TYPED_TEST(NavUkfTest, CovarianceGrowsWithoutMeasurements) {
  using S = TypeParam;
  auto f = make_filter<S>();
  const Vec3<S> a(S(1e-3), S(0), S(-2e-3));
  const Vec3<S> w(S(0.01), S(0.02), S(-0.01));
  for (int k = 1; k <= 50; ++k) {
    const auto P0 = f.P();
    ASSERT_TRUE(f.predict(0.1 * k, a, w).ok());
    EXPECT_GT(f.P().trace(), P0.trace()) << "step " << k;
    for (int i = 0; i < 9; ++i) EXPECT_GE(f.P()(i, i), P0(i, i)) << "step " << k << " index " << i;
  }
}

TYPED_TEST(NavUkfTest, PoseUpdateShrinksCovariance) {
  using S = TypeParam;
  auto f = make_filter<S>();
  for (int k = 1; k <= 10; ++k) ASSERT_TRUE(f.predict(0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto P0 = f.P();
  const auto rec = f.update_pose(1.0, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  ASSERT_EQ(rec.status, StepStatus::Ok);
  EXPECT_TRUE(rec.fused);
  EXPECT_LT(f.P().trace(), S(0.5) * P0.trace());
  for (int i = 0; i < 9; ++i) EXPECT_LT(f.P()(i, i), P0(i, i)) << "index " << i;
  // P0 - P1 = K S K^T is positive semidefinite.
  const Eigen::Matrix<S, 9, 9> dP = P0 - f.P();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<S, 9, 9>> es(dP);
  EXPECT_GE(es.eigenvalues().minCoeff(), -S(1e-6) * P0.norm());
  // A zero innovation: NIS zero, log-likelihood = -log det(2 pi S) / 2.
  EXPECT_NEAR(double(rec.nis), 0.0, 1e-6);
  const double logdet = std::log(double(rec.innovation_cov.determinant()));
  EXPECT_NEAR(double(rec.log_likelihood), -0.5 * (6.0 * std::log(2.0 * M_PI) + logdet), 1e-3);
}

TYPED_TEST(NavUkfTest, NisAndLikelihoodMatchInnovation) {
  using S = TypeParam;
  auto f = make_filter<S>();
  for (int k = 1; k <= 10; ++k) ASSERT_TRUE(f.predict(0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const Vec3<S> dr(S(0.02), S(-0.03), S(0.01));
  const Vec3<S> dth(S(0.01), S(0.0), S(-0.02));
  const Vec3<S> r_meas = f.state().r_hill_m + dr;
  const Quat<S> q_meas = boxplus(f.state().q_hb, dth);
  const auto rec = f.update_pose(1.0, r_meas, q_meas, pose_R<S>());
  ASSERT_EQ(rec.status, StepStatus::Ok);
  EXPECT_NEAR(double(rec.innovation(0)), double(dr(0)), 1e-5);
  EXPECT_NEAR(double(rec.innovation(5)), double(dth(2)), 1e-5);
  const Eigen::Matrix<double, 6, 1> y = rec.innovation.template cast<double>();
  const Eigen::Matrix<double, 6, 6> Sm = rec.innovation_cov.template cast<double>();
  const double nis = y.dot(Sm.inverse() * y);
  EXPECT_NEAR(double(rec.nis), nis, 1e-3 * nis);
  const double ll = -0.5 * (nis + std::log((2.0 * M_PI * Sm).determinant()));
  EXPECT_NEAR(double(rec.log_likelihood), ll, 1e-3 * std::abs(ll));
}

TYPED_TEST(NavUkfTest, NonFiniteInputGivesBadInputAndLeavesStateUntouched) {
  using S = TypeParam;
  auto f = make_filter<S>();
  for (int k = 1; k <= 5; ++k) ASSERT_TRUE(f.predict(0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto ref = f;
  const S bads[2] = {S(kNan), S(kInf)};
  const Vec3<S> a(S(1e-3), S(0), S(0));
  const Vec3<S> w(S(0.01), S(0), S(0));
  for (const S bad : bads) {
    EXPECT_EQ(f.predict(double(bad), a, w).status, StepStatus::BadInput);
    for (int i = 0; i < 3; ++i) {
      Vec3<S> ab = a, wb = w;
      ab(i) = bad;
      wb(i) = bad;
      EXPECT_EQ(f.predict(0.6, ab, w).status, StepStatus::BadInput);
      EXPECT_EQ(f.predict(0.6, a, wb).status, StepStatus::BadInput);
    }
    const Vec3<S> r = f.state().r_hill_m;
    const Quat<S> q = f.state().q_hb;
    EXPECT_EQ(f.update_pose(double(bad), r, q, pose_R<S>()).status, StepStatus::BadInput);
    for (int i = 0; i < 3; ++i) {
      Vec3<S> rb = r;
      rb(i) = bad;
      EXPECT_EQ(f.update_pose(0.5, rb, q, pose_R<S>()).status, StepStatus::BadInput);
    }
    for (int i = 0; i < 4; ++i) {
      Quat<S> qb = q;
      qb.coeffs()(i) = bad;
      EXPECT_EQ(f.update_pose(0.5, r, qb, pose_R<S>()).status, StepStatus::BadInput);
    }
    for (int i = 0; i < 6; ++i) {
      for (int j = 0; j < 6; ++j) {
        auto R = pose_R<S>();
        R(i, j) = bad;
        const auto rec = f.update_pose(0.5, r, q, R);
        EXPECT_EQ(rec.status, StepStatus::BadInput);
        EXPECT_EQ(rec.detail, StepDetail::NonFinite);
        EXPECT_FALSE(rec.fused);
      }
    }
    typename NavUkf<S>::State x = f.state();
    x.v_hill_mps(1) = bad;
    EXPECT_EQ(f.init(1.0, x, initial_cov<S, false>()).status, StepStatus::BadInput);
    auto P = initial_cov<S, false>();
    P(4, 2) = bad;
    EXPECT_EQ(f.init(1.0, f.state(), P).status, StepStatus::BadInput);
    EXPECT_EQ(f.init(double(bad), f.state(), initial_cov<S, false>()).status, StepStatus::BadInput);
  }
  EXPECT_TRUE(same_bits(f, ref));
  // And the filter still works.
  EXPECT_TRUE(f.predict(0.6, a, w).ok());
}

TYPED_TEST(NavUkfTest, NonUnitQuaternionPoseIsBadInput) {
  using S = TypeParam;
  auto f = make_filter<S>();
  const auto ref = f;
  Quat<S> q = f.state().q_hb;
  q.coeffs() *= S(1.1);
  const auto rec = f.update_pose(0.0, f.state().r_hill_m, q, pose_R<S>());
  EXPECT_EQ(rec.status, StepStatus::BadInput);
  EXPECT_EQ(rec.detail, StepDetail::NonUnitQuaternion);
  EXPECT_TRUE(same_bits(f, ref));
}

TYPED_TEST(NavUkfTest, OneMetreOutlierPoseIsGated) {
  using S = TypeParam;
  auto f = make_filter<S>();
  // Converge first so that P is at its operating size.
  for (int s = 1; s <= 10; ++s) {
    for (int k = 1; k <= 10; ++k)
      ASSERT_TRUE(f.predict(double(s - 1) + 0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
    ASSERT_TRUE(f.update_pose(double(s), f.state().r_hill_m, f.state().q_hb, pose_R<S>()).ok());
  }
  for (int k = 1; k <= 10; ++k) ASSERT_TRUE(f.predict(10.0 + 0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto ref = f;
  const Vec3<S> r_out = f.state().r_hill_m + Vec3<S>(S(0), S(1), S(0));
  const auto rec = f.update_pose(11.0, r_out, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(rec.status, StepStatus::Gated);
  EXPECT_FALSE(rec.fused);
  EXPECT_GT(rec.nis, f.config().gate_chi2);
  EXPECT_NEAR(double(rec.innovation(1)), 1.0, 1e-4);
  EXPECT_TRUE(same_bits(f, ref));
  // The same pose is fused when gating is disabled.
  NavConfig<S> c = f.config();
  c.gate_chi2 = S(0);
  NavUkf<S> g(c);
  ASSERT_TRUE(g.init(0.0, ref.state(), ref.P()).ok());
  EXPECT_EQ(g.update_pose(0.0, r_out, ref.state().q_hb, pose_R<S>()).status, StepStatus::Ok);
}

TYPED_TEST(NavUkfTest, LostImuTickIsBridgedAndAPoseCapturedAtItFuses) {
  // The IMU sample of t = 0.5 s is lost: the sample of 0.6 s arrives with a
  // 0.2 s step. The filter holds it over both ticks and stores both. With
  // the gap noise off, that equals the sample given at 0.5 and 0.6; with it
  // on (the default), the bridged tick adds covariance. A pose captured at
  // 0.5 s (the missed tick) lands on a stored tick and is fused.
  using S = TypeParam;
  auto cfg_no_gap = test_config<S>();
  cfg_no_gap.gap_accel_sigma_mps2 = S(0);
  cfg_no_gap.gap_gyro_sigma_rps = S(0);
  typename NavUkf<S>::State x;
  x.r_hill_m = Vec3<S>(S(0.75), S(0), S(0));
  x.q_hb = normalized(Quat<S>(S(0.9), S(0.1), S(-0.2), S(0.3)));
  NavUkf<S> lost(cfg_no_gap), both(cfg_no_gap), gap(test_config<S>());
  ASSERT_TRUE(lost.init(0.0, x, initial_cov<S, false>()).ok());
  ASSERT_TRUE(both.init(0.0, x, initial_cov<S, false>()).ok());
  ASSERT_TRUE(gap.init(0.0, x, initial_cov<S, false>()).ok());
  const Vec3<S> a(S(1e-3), S(-2e-3), S(5e-4));
  const Vec3<S> w(S(0.01), S(0.02), S(-0.01));
  for (int k = 1; k <= 4; ++k) {
    ASSERT_TRUE(lost.predict(0.1 * k, a, w).ok());
    ASSERT_TRUE(both.predict(0.1 * k, a, w).ok());
    ASSERT_TRUE(gap.predict(0.1 * k, a, w).ok());
  }
  ASSERT_TRUE(lost.predict(0.6, a, w).ok());
  ASSERT_TRUE(gap.predict(0.6, a, w).ok());
  ASSERT_TRUE(both.predict(0.5, a, w).ok());
  ASSERT_TRUE(both.predict(0.6, a, w).ok());
  const double tol = std::is_same<S, double>::value ? 1e-12 : 1e-6;
  const Eigen::Matrix<double, 10, 1> d = (lost.state().stored() - both.state().stored()).template cast<double>();
  EXPECT_LT(d.cwiseAbs().maxCoeff(), tol);
  EXPECT_LT((lost.P() - both.P()).cwiseAbs().maxCoeff(), S(tol));
  for (int i = 0; i < 9; ++i) EXPECT_GT(gap.P()(i, i), both.P()(i, i)) << i;

  for (NavUkf<S>* f : {&lost, &gap}) {
    const Vec3<S> r_meas = f->state().r_hill_m + Vec3<S>(S(0.02), S(0), S(0));
    const auto rec = f->update_pose(0.5, r_meas, f->state().q_hb, pose_R<S>());
    EXPECT_EQ(rec.status, StepStatus::Ok) << to_string(rec.detail);
    EXPECT_TRUE(rec.fused);
    EXPECT_DOUBLE_EQ(f->t_s(), 0.6);
  }
}

TYPED_TEST(NavUkfTest, LongImuOutageIsCoastedThroughAndAPoseAfterItFuses) {
  // 20 s without IMU samples (200 ticks, more than the history holds): the
  // next sample carries the filter across, the covariance grows by the gap
  // noise, and the filter takes the next pose (a filter that refused such
  // a step would stay stuck until a reset).
  using S = TypeParam;
  auto f = make_filter<S>();
  const Vec3<S> a(S(1e-3), S(0), S(0)), w(S(0), S(0), S(0.0011));
  ASSERT_TRUE(f.predict(0.1, a, w).ok());
  const S var_before = f.P()(3, 3);
  const auto rec = f.predict(20.1, a, w);
  ASSERT_EQ(rec.status, StepStatus::Ok) << to_string(rec.detail);
  EXPECT_DOUBLE_EQ(f.t_s(), 20.1);
  // At least the gap noise of the 199 bridged ticks: (sigma_gap dt)^2 each.
  const S g = f.config().gap_accel_sigma_mps2 * S(0.1);
  EXPECT_GT(f.P()(3, 3), var_before + S(199) * g * g);
  EXPECT_TRUE(is_pos_def(f.P()));
  const auto up = f.update_pose(20.1, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(up.status, StepStatus::Ok) << to_string(up.detail);
  EXPECT_TRUE(up.fused);
  // A pose captured inside the outage, within the stored last ticks.
  ASSERT_TRUE(f.predict(20.2, a, w).ok());
  const auto late = f.update_pose(19.9, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(late.detail, StepDetail::OutOfSequence);  // older than the pose just fused
}

TYPED_TEST(NavUkfTest, DelayedPoseEqualsOnTimePoseAndReplay) {
  using S = TypeParam;
  auto on_time = make_filter<S>();
  auto delayed = make_filter<S>();
  std::mt19937_64 rng(7);
  std::normal_distribution<double> nd(0.0, 1.0);
  auto imu = [&](int k) {
    (void)k;
    return std::make_pair(Vec3<S>(S(2e-3 * nd(rng)), S(2e-3 * nd(rng)), S(2e-3 * nd(rng))),
                          Vec3<S>(S(0.01 + 0.005 * nd(rng)), S(0.005 * nd(rng)), S(0.005 * nd(rng))));
  };
  std::pair<Vec3<S>, Vec3<S>> u[30];
  for (int k = 0; k < 30; ++k) u[k] = imu(k);
  for (int k = 1; k <= 10; ++k) {
    ASSERT_TRUE(on_time.predict(0.1 * k, u[k - 1].first, u[k - 1].second).ok());
    ASSERT_TRUE(delayed.predict(0.1 * k, u[k - 1].first, u[k - 1].second).ok());
  }
  const Vec3<S> r_meas = on_time.state().r_hill_m + Vec3<S>(S(0.03), S(-0.02), S(0.01));
  const Quat<S> q_meas = boxplus(on_time.state().q_hb, Vec3<S>(S(0.01), S(-0.005), S(0.0)));
  ASSERT_TRUE(on_time.update_pose(1.0, r_meas, q_meas, pose_R<S>()).ok());
  for (int k = 11; k <= 15; ++k) {
    ASSERT_TRUE(on_time.predict(0.1 * k, u[k - 1].first, u[k - 1].second).ok());
    ASSERT_TRUE(delayed.predict(0.1 * k, u[k - 1].first, u[k - 1].second).ok());
  }
  // Delivered 0.5 s after capture.
  const auto rec = delayed.update_pose(1.0, r_meas, q_meas, pose_R<S>());
  ASSERT_EQ(rec.status, StepStatus::Ok);
  EXPECT_TRUE(rec.fused);
  EXPECT_DOUBLE_EQ(delayed.t_s(), 1.5);
  const double tol = std::is_same<S, double>::value ? 1e-9 : 1e-5;
  const Eigen::Matrix<double, 10, 1> d = (delayed.state().stored() - on_time.state().stored()).template cast<double>();
  EXPECT_LT(d.cwiseAbs().maxCoeff(), tol);
  EXPECT_LT((delayed.P() - on_time.P()).template cast<double>().cwiseAbs().maxCoeff(), tol);
  // The delayed pose changed the estimate (it was not ignored).
  auto ignored = make_filter<S>();
  for (int k = 1; k <= 15; ++k) ASSERT_TRUE(ignored.predict(0.1 * k, u[k - 1].first, u[k - 1].second).ok());
  EXPECT_GT((ignored.state().r_hill_m - delayed.state().r_hill_m).norm(), S(1e-3));
  // Later predicts continue identically from the corrected history.
  for (int k = 16; k <= 20; ++k) {
    ASSERT_TRUE(on_time.predict(0.1 * k, u[k - 1].first, u[k - 1].second).ok());
    ASSERT_TRUE(delayed.predict(0.1 * k, u[k - 1].first, u[k - 1].second).ok());
  }
  EXPECT_LT((delayed.state().stored() - on_time.state().stored()).template cast<double>().cwiseAbs().maxCoeff(), tol);
}

TYPED_TEST(NavUkfTest, PoseOlderThanMaxDelayIsRejectedUntouched) {
  using S = TypeParam;
  auto f = make_filter<S>();
  for (int k = 1; k <= 20; ++k) ASSERT_TRUE(f.predict(0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto ref = f;
  const auto rec = f.update_pose(1.4, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(rec.status, StepStatus::BadInput);
  EXPECT_EQ(rec.detail, StepDetail::TooOld);
  EXPECT_TRUE(same_bits(f, ref));
}

TYPED_TEST(NavUkfTest, PoseOlderThanHistoryIsRejectedUntouched) {
  using S = TypeParam;
  NavConfig<S> c = test_config<S>();
  c.max_delay_s = 1.4;  // 15 ticks + 1: fits the 16-tick history
  NavUkf<S> f(c);
  ASSERT_TRUE(f.config_ok());
  typename NavUkf<S>::State x;
  ASSERT_TRUE(f.init(0.0, x, initial_cov<S, false>()).ok());
  // Predict steps of 0.05 s: 1.4 s back is now beyond the 16 stored ticks.
  for (int k = 1; k <= 40; ++k) ASSERT_TRUE(f.predict(0.05 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto ref = f;
  const auto rec = f.update_pose(2.0 - 1.0, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(rec.status, StepStatus::BadInput);
  EXPECT_EQ(rec.detail, StepDetail::TooOld);
  EXPECT_TRUE(same_bits(f, ref));
  // A config whose max_delay_s cannot fit the history is refused.
  c.max_delay_s = 2.0;
  NavUkf<S> g(c);
  EXPECT_FALSE(g.config_ok());
  EXPECT_EQ(g.init(0.0, x, initial_cov<S, false>()).detail, StepDetail::BadConfig);
}

TYPED_TEST(NavUkfTest, CaptureTimeBetweenTicksOrInFutureIsRejected) {
  using S = TypeParam;
  auto f = make_filter<S>();
  for (int k = 1; k <= 5; ++k) ASSERT_TRUE(f.predict(0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto ref = f;
  auto rec = f.update_pose(0.35, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(rec.status, StepStatus::BadInput);
  EXPECT_EQ(rec.detail, StepDetail::OffTick);
  rec = f.update_pose(0.6, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(rec.status, StepStatus::BadInput);
  EXPECT_EQ(rec.detail, StepDetail::FromFuture);
  EXPECT_TRUE(same_bits(f, ref));
  // Within time_tol_s of a tick is on the tick.
  EXPECT_TRUE(f.update_pose(0.3 + 0.5e-3, f.state().r_hill_m, f.state().q_hb, pose_R<S>()).ok());
  // Earlier than the last fused capture: out of sequence.
  rec = f.update_pose(0.2, f.state().r_hill_m, f.state().q_hb, pose_R<S>());
  EXPECT_EQ(rec.detail, StepDetail::OutOfSequence);
}

TYPED_TEST(NavUkfTest, ReacquireRejectsBadPosesAndLeavesTheStateUntouched) {
  using S = TypeParam;
  NavUkf<S, false> f(test_config<S>());
  const Vec3<S> r(S(0.1), S(-0.7), S(0));
  const Quat<S> q = Quat<S>::Identity();
  EXPECT_EQ(f.reacquire(0.0, r, q, pose_R<S>()).detail, StepDetail::NotInitialized);
  ASSERT_TRUE(f.init(0.0, typename NavUkf<S, false>::State(), initial_cov<S, false>()).ok());
  for (int k = 1; k <= 10; ++k) ASSERT_TRUE(f.predict(0.1 * k, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto x0 = f.state();
  const auto P0 = f.P();
  Vec3<S> r_nan = r;
  r_nan.x() = std::numeric_limits<S>::quiet_NaN();
  EXPECT_EQ(f.reacquire(1.0, r_nan, q, pose_R<S>()).detail, StepDetail::NonFinite);
  EXPECT_EQ(f.reacquire(1.0, r, Quat<S>(S(1.1), S(0), S(0), S(0)), pose_R<S>()).detail, StepDetail::NonUnitQuaternion);
  EXPECT_EQ(f.reacquire(1.5, r, q, pose_R<S>()).detail, StepDetail::FromFuture);
  EXPECT_EQ(f.reacquire(1.0 - f.config().max_delay_s - 0.05, r, q, pose_R<S>()).detail, StepDetail::TooOld);
  typename NavUkf<S, false>::MeasCov R_bad = pose_R<S>();
  R_bad(0, 0) = S(-1);
  EXPECT_EQ(f.reacquire(1.0, r, q, R_bad).status, StepStatus::NotPosDef);
  EXPECT_EQ(f.state().r_hill_m, x0.r_hill_m);
  EXPECT_EQ(f.P(), P0);
  EXPECT_EQ(f.t_s(), 1.0);
  // A pose 0.2 s old is taken as of now; the filter's time does not go back.
  ASSERT_TRUE(f.reacquire(0.8, r, q, pose_R<S>()).ok());
  EXPECT_EQ(f.t_s(), 1.0);
  EXPECT_EQ(f.state().r_hill_m, r);
  EXPECT_EQ(f.history_count(), 1);
}

TYPED_TEST(NavUkfTest, PredictTimeNotIncreasingIsRejected) {
  using S = TypeParam;
  auto f = make_filter<S>();
  ASSERT_TRUE(f.predict(0.1, Vec3<S>::Zero(), Vec3<S>::Zero()).ok());
  const auto ref = f;
  EXPECT_EQ(f.predict(0.1, Vec3<S>::Zero(), Vec3<S>::Zero()).detail, StepDetail::TimeNotIncreasing);
  EXPECT_EQ(f.predict(0.0, Vec3<S>::Zero(), Vec3<S>::Zero()).detail, StepDetail::TimeNotIncreasing);
  // Off the IMU grid and longer than max_dt_s; on the grid but longer than max_gap_s.
  EXPECT_EQ(f.predict(5.05, Vec3<S>::Zero(), Vec3<S>::Zero()).detail, StepDetail::StepTooLong);
  EXPECT_EQ(f.predict(60.2, Vec3<S>::Zero(), Vec3<S>::Zero()).detail, StepDetail::StepTooLong);
  EXPECT_TRUE(same_bits(f, ref));
  NavUkf<S> g(test_config<S>());
  EXPECT_EQ(g.predict(0.1, Vec3<S>::Zero(), Vec3<S>::Zero()).detail, StepDetail::NotInitialized);
}

TYPED_TEST(NavUkfTest, NonPosDefCovarianceGivesNotPosDefUntouched) {
  using S = TypeParam;
  auto f = make_filter<S>();
  const auto ref = f;
  auto P = initial_cov<S, false>();
  P(0, 1) = P(1, 0) = S(10) * P(0, 0);  // correlation 10: indefinite
  const auto rec = f.init(1.0, f.state(), P);
  EXPECT_EQ(rec.status, StepStatus::NotPosDef);
  EXPECT_TRUE(same_bits(f, ref));
}

TYPED_TEST(NavUkfTest, NonPosDefInnovationCovarianceGivesNotPosDefUntouched) {
  using S = TypeParam;
  auto f = make_filter<S>();
  const auto ref = f;
  Eigen::Matrix<S, 6, 6> R = pose_R<S>();
  R(0, 0) = S(-1);  // S = P_zz + R indefinite
  const auto rec = f.update_pose(0.0, f.state().r_hill_m, f.state().q_hb, R);
  EXPECT_EQ(rec.status, StepStatus::NotPosDef);
  EXPECT_EQ(rec.detail, StepDetail::InnovationCholesky);
  EXPECT_FALSE(rec.fused);
  EXPECT_TRUE(same_bits(f, ref));
}

TYPED_TEST(NavUkfTest, CovarianceStaysPositiveDefiniteOver24Hours) {
  // 864000 predicts at 10 Hz, 86400 pose updates at 1 Hz. Lightweight truth:
  // the inspector at rest at the host's centre of mass (a CW equilibrium),
  // inertially fixed, so q_hb(t) = Exp(-n t z) q0; noisy IMU and pose.
  using S = TypeParam;
  auto f = make_filter<S>();
  const double n = double(f.config().n_radps);
  const Quat<double> q0 = normalized(Quat<double>(0.9, 0.1, -0.2, 0.3));
  std::mt19937_64 rng(2024);
  std::normal_distribution<double> nd(0.0, 1.0);
  typename NavUkf<S>::State x;
  x.q_hb = q0.cast<S>();
  ASSERT_TRUE(f.init(0.0, x, initial_cov<S, false>()).ok());
  const double sa = double(f.config().accel_sigma_mps2), sg = double(f.config().gyro_sigma_rps);
  long not_ok = 0, gated = 0;
  double max_pos_err = 0.0;
  for (long s = 1; s <= 86400; ++s) {
    for (int k = 1; k <= 10; ++k) {
      const double t = double(s - 1) + 0.1 * k;
      const Vec3<S> a(S(sa * nd(rng)), S(sa * nd(rng)), S(sa * nd(rng)));
      const Vec3<S> w(S(sg * nd(rng)), S(sg * nd(rng)), S(sg * nd(rng)));
      if (!f.predict(t, a, w).ok()) ++not_ok;
    }
    const double t = double(s);
    const Quat<double> q_true = exp(Vec3<double>(0, 0, -n * t)) * q0;
    const Vec3<double> r_meas(kPosSigma * nd(rng), kPosSigma * nd(rng), kPosSigma * nd(rng));
    const Quat<double> q_meas =
        boxplus(q_true, Vec3<double>(kAttSigma * nd(rng), kAttSigma * nd(rng), kAttSigma * nd(rng)));
    const auto rec = f.update_pose(t, r_meas.cast<S>(), q_meas.cast<S>(), pose_R<S>());
    if (rec.status == StepStatus::Gated) {
      ++gated;
    } else if (!rec.ok()) {
      ++not_ok;
    }
    if (s % 3600 == 0) {
      ASSERT_TRUE(is_pos_def(f.P())) << "hour " << s / 3600;
      ASSERT_TRUE((f.P() - f.P().transpose()).isZero(S(0))) << "hour " << s / 3600;
    }
    max_pos_err = std::max(max_pos_err, double(f.state().r_hill_m.norm()));
  }
  EXPECT_EQ(not_ok, 0);
  EXPECT_LT(gated, 200);  // p = 0.001 of 86400 is ~86
  EXPECT_DOUBLE_EQ(f.t_s(), 86400.0);
  EXPECT_TRUE(is_pos_def(f.P()));
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<S, 9, 9>> es(f.P());
  EXPECT_GT(es.eigenvalues().minCoeff(), S(0));
  EXPECT_LT(max_pos_err, 0.5);
  const Quat<double> q_end = exp(Vec3<double>(0, 0, -n * 86400.0)) * q0;
  EXPECT_LT(boxminus(q_end, f.state().q_hb.template cast<double>()).norm(), 0.05);
}

TYPED_TEST(NavUkfTest, NeesAndNisInsideChiSquareBands) {
  // Natural CW motion (no thrust), constant body rate, IMU samples with
  // white noise held over each step, noisy poses at 1 Hz: the filter's own
  // noise model. Average NEES (9 dof) over runs at each pose time, then over
  // time, must lie in the two-sided 95 % band of chi2(9 R) / R; likewise NIS.
  using S = TypeParam;
  constexpr int kRuns = 40;
  constexpr int kSeconds = 30;
  const NavConfig<S> cfg = test_config<S>();
  const double n = double(cfg.n_radps), dt = 0.1;
  const double sa = double(cfg.accel_sigma_mps2), sg = double(cfg.gyro_sigma_rps);
  const Mat6<double> phi = cw_stm(n, dt);
  const Quat<double> hill = hill_frame_step(n, dt);
  const Vec3<double> w_true(0.01, -0.02, 0.015);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> nd(0.0, 1.0);
  const auto P0 = initial_cov<S, false>();
  const Eigen::Matrix<double, 9, 9> L0 = P0.template cast<double>().llt().matrixL();
  double nees_sum[kSeconds] = {0};
  double nis_sum[kSeconds] = {0};
  for (int run = 0; run < kRuns; ++run) {
    NavUkf<S> f(cfg);
    typename NavUkf<S>::State x;
    x.r_hill_m = Vec3<S>(S(0.75), S(0.1), S(-0.05));
    x.v_hill_mps = Vec3<S>(S(0), S(-2.0 * n * 0.75), S(0));
    x.q_hb = normalized(Quat<S>(S(0.9), S(0.1), S(-0.2), S(0.3)));
    ASSERT_TRUE(f.init(0.0, x, P0).ok());
    Eigen::Matrix<double, 9, 1> z0;
    for (int i = 0; i < 9; ++i) z0(i) = nd(rng);
    const Eigen::Matrix<double, 9, 1> e0 = L0 * z0;
    Vec6<double> rv;
    rv << x.r_hill_m.template cast<double>() + e0.head<3>(), x.v_hill_mps.template cast<double>() + e0.segment<3>(3);
    Quat<double> q = boxplus(x.q_hb.template cast<double>(), Vec3<double>(e0.tail<3>()));
    for (int s = 1; s <= kSeconds; ++s) {
      for (int k = 1; k <= 10; ++k) {
        rv = phi * rv;
        q = propagate_attitude(q, w_true, dt, hill);
        const Vec3<S> a(S(sa * nd(rng)), S(sa * nd(rng)), S(sa * nd(rng)));
        const Vec3<S> w = (w_true + sg * Vec3<double>(nd(rng), nd(rng), nd(rng))).cast<S>();
        ASSERT_TRUE(f.predict(double(s - 1) + 0.1 * k, a, w).ok());
      }
      const Vec3<double> r_meas = rv.head<3>() + kPosSigma * Vec3<double>(nd(rng), nd(rng), nd(rng));
      const Quat<double> q_meas = boxplus(q, Vec3<double>(kAttSigma * Vec3<double>(nd(rng), nd(rng), nd(rng))));
      const auto rec = f.update_pose(double(s), r_meas.cast<S>(), q_meas.cast<S>(), pose_R<S>());
      ASSERT_NE(rec.status, StepStatus::NotPosDef);
      ASSERT_NE(rec.status, StepStatus::BadInput);
      nis_sum[s - 1] += double(rec.nis);
      Eigen::Matrix<double, 9, 1> e;
      e << rv.head<3>() - f.state().r_hill_m.template cast<double>(),
          rv.tail<3>() - f.state().v_hill_mps.template cast<double>(),
          boxminus(q, f.state().q_hb.template cast<double>());
      const Eigen::Matrix<double, 9, 9> P = f.P().template cast<double>();
      nees_sum[s - 1] += e.dot(P.llt().solve(e));
    }
  }
  double nees = 0.0, nis = 0.0;
  for (int s = 0; s < kSeconds; ++s) {
    nees += nees_sum[s] / kRuns;
    nis += nis_sum[s] / kRuns;
  }
  nees /= kSeconds;
  nis /= kSeconds;
  const double z = 1.959964;
  EXPECT_GT(nees, chi2_quantile(9.0 * kRuns, -z) / kRuns);
  EXPECT_LT(nees, chi2_quantile(9.0 * kRuns, z) / kRuns);
  EXPECT_GT(nis, chi2_quantile(6.0 * kRuns, -z) / kRuns);
  EXPECT_LT(nis, chi2_quantile(6.0 * kRuns, z) / kRuns);
}

// ---------------------------------------------------------------------------
// 15-state filter (gyro and accelerometer biases).

template <typename S>
class NavUkfBiasTest : public ::testing::Test {};
TYPED_TEST_SUITE(NavUkfBiasTest, Scalars);

TYPED_TEST(NavUkfBiasTest, LayoutSizes) {
  using S = TypeParam;
  EXPECT_EQ((NavUkf<S, true>::kN), 15);
  EXPECT_EQ((NavUkf<S, false>::kN), 9);
  EXPECT_EQ(NavLayout<true>::kStoredSize, 16);
  EXPECT_EQ(NavLayout<false>::kStoredSize, 10);
  EXPECT_EQ(NavLayout<true>::kDAccelBias.index, 12);
}

TYPED_TEST(NavUkfBiasTest, EstimatesAConstantGyroBias) {
  // Inspector at rest, inertially fixed; the gyro reads a constant bias.
  // Attitude poses make the bias observable: the estimate converges to it.
  using S = TypeParam;
  NavConfig<S> c = test_config<S>();
  c.gyro_sigma_rps = S(0.001);
  NavUkf<S, true> f(c);
  const double n = double(c.n_radps);
  const Quat<double> q0 = normalized(Quat<double>(0.9, 0.1, -0.2, 0.3));
  typename NavUkf<S, true>::State x;
  x.q_hb = q0.cast<S>();
  auto P0 = initial_cov<S, true>();
  for (int i = 9; i < 12; ++i) P0(i, i) = S(0.01 * 0.01);
  ASSERT_TRUE(f.init(0.0, x, P0).ok());
  const Vec3<S> bias(S(0.004), S(-0.003), S(0.002));
  for (int s = 1; s <= 120; ++s) {
    const auto P_before = f.P();
    for (int k = 1; k <= 10; ++k) ASSERT_TRUE(f.predict(double(s - 1) + 0.1 * k, Vec3<S>::Zero(), bias).ok());
    EXPECT_GT(f.P().trace(), P_before.trace());
    const Quat<double> q_true = exp(Vec3<double>(0, 0, -n * s)) * q0;
    ASSERT_TRUE(f.update_pose(double(s), Vec3<S>::Zero(), q_true.cast<S>(), pose_R<S>()).ok());
  }
  EXPECT_LT((f.state().gyro_bias_rps - bias).norm(), S(2e-4));
  EXPECT_TRUE(is_pos_def(f.P()));
}

TYPED_TEST(NavUkfBiasTest, AnHourWithoutPosesStaysOkAndAReacquiredFilterReconverges) {
  // 36000 predicts with IMU noise only (the inspector at rest at the host's
  // centre of mass, inertially fixed), then 5 minutes of 1 Hz poses. In
  // float the covariance of a long coast used to fail its Cholesky after
  // 1076 s (position, velocity and bias errors correlated to within
  // rounding) and every later step was refused; the repaired factor
  // (cholesky_lower_repaired) keeps the filter running.
  using S = TypeParam;
  NavUkf<S, true> f(test_config<S>());
  const double n = double(f.config().n_radps);
  const Quat<double> q0 = normalized(Quat<double>(0.9, 0.1, -0.2, 0.3));
  typename NavUkf<S, true>::State x;
  x.q_hb = q0.cast<S>();
  ASSERT_TRUE(f.init(0.0, x, initial_cov<S, true>()).ok());
  std::mt19937_64 rng(7);
  std::normal_distribution<double> nd(0.0, 1.0);
  const double sa = double(f.config().accel_sigma_mps2), sg = double(f.config().gyro_sigma_rps);
  long not_ok = 0, repaired = 0;
  auto imu_second = [&](long s) {
    for (int k = 1; k <= 10; ++k) {
      const Vec3<S> a(S(sa * nd(rng)), S(sa * nd(rng)), S(sa * nd(rng)));
      const Vec3<S> w(S(sg * nd(rng)), S(sg * nd(rng)), S(sg * nd(rng)));
      const auto rec = f.predict(double(s - 1) + 0.1 * k, a, w);
      if (!rec.ok()) ++not_ok;
      if (rec.detail == StepDetail::CovarianceRepaired) ++repaired;
    }
  };
  for (long s = 1; s <= 3600; ++s) imu_second(s);
  EXPECT_EQ(not_ok, 0);
  EXPECT_TRUE(is_pos_def(f.P()));
  EXPECT_GT(f.P()(0, 0), S(1e3));  // an hour of coasting: position unknown to kilometres
  // Poses return. After an hour the attitude variance sits at its ceiling
  // (1 rad^2) and the position's is kilometres: a pose is not a small
  // correction any more (in float the update would shrink the position
  // variance by 1e11, below its resolution, and is refused with the state
  // untouched). The recovery is a re-acquisition from the first pose
  // (reacquire: position and attitude from the pose, the coasted velocity
  // and bias variances kept); then every pose fuses.
  {
    const long s = 3601;
    imu_second(s);
    const Quat<double> q_true = exp(Vec3<double>(0, 0, -n * double(s))) * q0;
    const Vec3<double> r_meas(kPosSigma * nd(rng), kPosSigma * nd(rng), kPosSigma * nd(rng));
    const Quat<double> q_meas =
        boxplus(q_true, Vec3<double>(kAttSigma * nd(rng), kAttSigma * nd(rng), kAttSigma * nd(rng)));
    const auto v_var = f.P().diagonal().template segment<3>(3).eval();
    const auto bias_var = f.P().diagonal().template tail<6>().eval();
    ASSERT_TRUE(f.reacquire(double(s), r_meas.cast<S>(), q_meas.cast<S>(), pose_R<S>()).ok());
    EXPECT_EQ(f.state().r_hill_m, r_meas.cast<S>());
    EXPECT_EQ(f.P().diagonal().template head<3>(), pose_R<S>().diagonal().template head<3>());
    EXPECT_EQ(f.P().diagonal().template segment<3>(6), pose_R<S>().diagonal().template tail<3>());
    EXPECT_EQ(f.P().diagonal().template segment<3>(3), v_var);
    EXPECT_EQ(f.P().diagonal().template tail<6>(), bias_var);
    EXPECT_EQ((f.P().template block<3, 12>(0, 3).cwiseAbs().maxCoeff()), S(0));
  }
  long fused = 0;
  for (long s = 3602; s <= 3900; ++s) {
    imu_second(s);
    const Quat<double> q_true = exp(Vec3<double>(0, 0, -n * double(s))) * q0;
    const Vec3<double> r_meas(kPosSigma * nd(rng), kPosSigma * nd(rng), kPosSigma * nd(rng));
    const Quat<double> q_meas =
        boxplus(q_true, Vec3<double>(kAttSigma * nd(rng), kAttSigma * nd(rng), kAttSigma * nd(rng)));
    const auto rec = f.update_pose(double(s), r_meas.cast<S>(), q_meas.cast<S>(), pose_R<S>());
    EXPECT_NE(rec.status, StepStatus::NotPosDef) << "second " << s << " detail " << to_string(rec.detail);
    fused += rec.fused ? 1 : 0;
    if (rec.detail == StepDetail::CovarianceRepaired) ++repaired;
  }
  EXPECT_EQ(not_ok, 0);
  EXPECT_GE(fused, 290);
  EXPECT_LT(double(f.state().r_hill_m.norm()), 0.1);
  const Quat<double> q_end = exp(Vec3<double>(0, 0, -n * 3900.0)) * q0;
  EXPECT_LT(boxminus(q_end, f.state().q_hb.template cast<double>()).norm(), 0.02);
  EXPECT_TRUE(is_pos_def(f.P()));
  this->RecordProperty("repaired_steps", int(repaired));
}

TYPED_TEST(NavUkfBiasTest, DelayedPoseEqualsOnTimePoseAndReplay) {
  using S = TypeParam;
  auto a = make_filter<S, true>();
  auto b = make_filter<S, true>();
  const Vec3<S> acc(S(1e-3), S(-2e-3), S(0));
  const Vec3<S> w(S(0.01), S(0.0), S(-0.01));
  for (int k = 1; k <= 10; ++k) {
    ASSERT_TRUE(a.predict(0.1 * k, acc, w).ok());
    ASSERT_TRUE(b.predict(0.1 * k, acc, w).ok());
  }
  const Vec3<S> r_meas = a.state().r_hill_m + Vec3<S>(S(0.03), S(0), S(0));
  const Quat<S> q_meas = a.state().q_hb;
  ASSERT_TRUE(a.update_pose(1.0, r_meas, q_meas, pose_R<S>()).ok());
  for (int k = 11; k <= 15; ++k) {
    ASSERT_TRUE(a.predict(0.1 * k, acc, w).ok());
    ASSERT_TRUE(b.predict(0.1 * k, acc, w).ok());
  }
  ASSERT_TRUE(b.update_pose(1.0, r_meas, q_meas, pose_R<S>()).ok());
  const double tol = std::is_same<S, double>::value ? 1e-9 : 1e-5;
  EXPECT_LT((a.state().stored() - b.state().stored()).template cast<double>().cwiseAbs().maxCoeff(), tol);
  EXPECT_LT((a.P() - b.P()).template cast<double>().cwiseAbs().maxCoeff(), tol);
}
