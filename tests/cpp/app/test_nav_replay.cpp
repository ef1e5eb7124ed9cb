// The log replay (fsw/app/nav_replay.hpp) gives what stepping the filter by
// hand gives, bit for bit: initialisation at t_init from pose 0, a predict
// per IMU sample, late poses fused when their time comes, a run start
// resetting the filter, a lost IMU tick, a gated pose; float and double.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "fsw/app/nav_replay.hpp"
#include "nav_replay_util.hpp"

using namespace fsw;
using namespace nav_replay_test;

namespace {

// The replay's rules written out step by step with the filter's own calls.
template <typename S>
Result<S> by_hand(const Log<S>& log, const NavConfig<S>& cfg) {
  using Ukf = NavUkf<S, false>;
  Result<S> res(log);
  auto ukf = std::make_unique<Ukf>(cfg);
  auto init = [&](long j, double t) {
    typename Ukf::Cov P0 = Ukf::Cov::Zero();
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) {
        P0(a, b) = log.R[36 * j + 6 * a + b];
        P0(6 + a, 6 + b) = log.R[36 * j + 6 * (3 + a) + 3 + b];
      }
    P0.template block<3, 3>(3, 3) = log.v0[j] * log.v0[j] * Mat3<S>::Identity();
    typename Ukf::State x;
    x.r_hill_m = Vec3<S>(log.r[3 * j], log.r[3 * j + 1], log.r[3 * j + 2]);
    x.q_hb = from_wxyz(Vec4<S>(log.q[4 * j], log.q[4 * j + 1], log.q[4 * j + 2], log.q[4 * j + 3]));
    ukf = std::make_unique<Ukf>(cfg);
    ASSERT_TRUE(ukf->init(t, x, P0).ok());
  };
  init(0, log.t_init);
  const long m = long(log.tc.size());
  long j = 1;
  while (j < m && log.tc[j] <= log.t_init + 1e-9) ++j;
  for (std::size_t k = 0; k < log.t.size(); ++k) {
    const double tk = log.t[k];
    if (!(tk > log.t_init + 1e-9)) continue;
    const Vec3<S> a(log.acc[3 * k], log.acc[3 * k + 1], log.acc[3 * k + 2]);
    const Vec3<S> w(log.gyr[3 * k], log.gyr[3 * k + 1], log.gyr[3 * k + 2]);
    if (j < m && log.start[j] && log.tc[j] <= tk + 1e-9) {
      init(j, log.tc[j]);
      ++j;
      if (tk > log.tc[j - 1] + 1e-9) ukf->predict(tk, a, w);
    } else {
      ukf->predict(tk, a, w);
    }
    const auto s = ukf->state().stored();
    for (int i = 0; i < 10; ++i) res.states[10 * k + i] = s(i);
    for (; j < m && log.tf[j] <= tk + 1e-9 && !log.start[j]; ++j) {
      Eigen::Matrix<S, 6, 6> R;
      for (int a2 = 0; a2 < 6; ++a2)
        for (int b = 0; b < 6; ++b) R(a2, b) = log.R[36 * j + 6 * a2 + b];
      const Quat<S> qj = from_wxyz(Vec4<S>(log.q[4 * j], log.q[4 * j + 1], log.q[4 * j + 2], log.q[4 * j + 3]));
      const auto rec = ukf->update_pose(log.tc[j], Vec3<S>(log.r[3 * j], log.r[3 * j + 1], log.r[3 * j + 2]), qj, R);
      if (rec.status != StepStatus::Ok) continue;
      res.fused[j] = 1;
      for (int i = 0; i < 6; ++i) res.innovation[6 * j + i] = rec.innovation(i);
      for (int a2 = 0; a2 < 6; ++a2)
        for (int b = 0; b < 6; ++b) res.cov[36 * j + 6 * a2 + b] = rec.innovation_cov(a2, b);
      res.nis[j] = rec.nis;
      res.ll[j] = rec.log_likelihood;
    }
  }
  return res;
}

template <typename S>
void expect_same_as_by_hand(S gate_chi2, int fused_expected) {
  NavConfig<S> cfg;
  cfg.gate_chi2 = gate_chi2;
  const Log<S> log;
  Result<S> got(log);
  auto rep = std::make_unique<NavReplay<S>>(cfg);
  ASSERT_TRUE(rep->config_ok());
  const NavReplaySummary summary = rep->run(log.view(), got.view());
  ASSERT_TRUE(summary.ok());
  EXPECT_EQ(summary.poses_fused, fused_expected);
  EXPECT_EQ(summary.predicts_rejected, 0);
  const Result<S> want = by_hand(log, cfg);
  EXPECT_EQ(got.fused, want.fused);
  EXPECT_EQ(got.innovation, want.innovation);
  EXPECT_EQ(got.cov, want.cov);
  EXPECT_EQ(got.nis, want.nis);
  EXPECT_EQ(got.ll, want.ll);
  EXPECT_EQ(got.states, want.states);
  EXPECT_EQ(got.fused[0], 0);  // pose 0 initialises
  EXPECT_EQ(got.fused[5], 0);  // pose 5 starts a run
}

}  // namespace

TEST(NavReplayTest, SameAsSteppingByHandDouble) { expect_same_as_by_hand<double>(0.0, 6); }
TEST(NavReplayTest, SameAsSteppingByHandFloat) { expect_same_as_by_hand<float>(0.0f, 6); }
TEST(NavReplayTest, GatedPoseNotFusedDouble) { expect_same_as_by_hand<double>(22.46, 5); }
TEST(NavReplayTest, GatedPoseNotFusedFloat) { expect_same_as_by_hand<float>(22.46f, 5); }

TEST(NavReplayTest, FailedInitialisationStopsAndNamesThePose) {
  Log<double> log;
  log.R[36 * 5] = std::nan("");  // run start 5: P0 not finite
  Result<double> got(log);
  NavReplay<double> rep{NavConfig<double>()};
  const NavReplaySummary s = rep.run(log.view(), got.view());
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.failed_pose, 5);
}

TEST(NavReplayTest, BadConfigurationRefused) {
  NavConfig<double> cfg;
  cfg.max_delay_s = 10.0;  // more than the history holds
  NavReplay<double> rep(cfg);
  EXPECT_FALSE(rep.config_ok());
  const Log<double> log;
  Result<double> got(log);
  EXPECT_EQ(rep.run(log.view(), got.view()).detail, StepDetail::BadConfig);
}

// Every setting the filter checks is refused naming that field (the replay
// reports the filter's verdict), in both scalar builds: not finite, not
// positive, below its floor or inconsistent with another setting.
template <typename S>
void each_invalid_field_is_named() {
  using C = NavConfig<S>;
  struct Case {
    const char* field;
    void (*set)(C&);
  };
  const Case cases[] = {
      {"n_radps", [](C& c) { c.n_radps = S(0); }},
      {"n_radps", [](C& c) { c.n_radps = std::numeric_limits<S>::quiet_NaN(); }},
      {"dt_imu_s", [](C& c) { c.dt_imu_s = -0.1; }},
      {"max_gap_s", [](C& c) { c.max_gap_s = 0.0; }},
      {"max_gap_s", [](C& c) { c.max_gap_s = 1e5; }},  // more than 1e5 ticks
      {"accel_sigma_mps2", [](C& c) { c.accel_sigma_mps2 = S(-1e-3); }},
      {"gyro_sigma_rps", [](C& c) { c.gyro_sigma_rps = std::numeric_limits<S>::infinity(); }},
      {"gap_accel_sigma_mps2", [](C& c) { c.gap_accel_sigma_mps2 = S(-1); }},
      {"gap_gyro_sigma_rps", [](C& c) { c.gap_gyro_sigma_rps = std::numeric_limits<S>::quiet_NaN(); }},
      {"gyro_bias_walk", [](C& c) { c.gyro_bias_walk = S(-1e-5); }},
      {"accel_bias_walk", [](C& c) { c.accel_bias_walk = std::numeric_limits<S>::infinity(); }},
      {"gate_chi2", [](C& c) { c.gate_chi2 = std::numeric_limits<S>::quiet_NaN(); }},
      {"max_delay_s", [](C& c) { c.max_delay_s = -0.5; }},
      {"time_tol_s", [](C& c) { c.time_tol_s = 0.0; }},
      {"time_tol_s", [](C& c) { c.time_tol_s = 0.05; }},  // half the IMU period
      {"max_dt_s", [](C& c) { c.max_dt_s = 0.0; }},
      {"alpha", [](C& c) { c.alpha = S(0); }},
      {"beta", [](C& c) { c.beta = S(-1); }},
      {"kappa", [](C& c) { c.kappa = std::numeric_limits<S>::quiet_NaN(); }},
      {"kappa", [](C& c) { c.kappa = S(-9); }},  // alpha^2 (n + kappa) = 0
      {"var_min", [](C& c) { c.var_min = S(0); }},
      {"pos_var_max_m2", [](C& c) { c.pos_var_max_m2 = S(0); }},
      {"pos_var_max_m2", [](C& c) { c.pos_var_max_m2 = c.var_min; }},
      {"vel_var_max_m2ps2", [](C& c) { c.vel_var_max_m2ps2 = std::numeric_limits<S>::infinity(); }},
      {"att_var_max_rad2", [](C& c) { c.att_var_max_rad2 = c.var_min; }},
      {"gyro_bias_var_max", [](C& c) { c.gyro_bias_var_max = S(-1); }},
      {"accel_bias_var_max", [](C& c) { c.accel_bias_var_max = S(0); }},
      {"quat_unit_tol", [](C& c) { c.quat_unit_tol = S(0); }},
      {"max_delay_s", [](C& c) { c.max_delay_s = 2.0; }},  // beyond the history's 16 ticks
  };
  const Log<S> log;
  for (const Case& k : cases) {
    C cfg;
    k.set(cfg);
    NavReplay<S> rep(cfg);
    EXPECT_FALSE(rep.config_ok()) << k.field;
    ASSERT_NE(rep.config_invalid_field(), nullptr) << k.field;
    EXPECT_STREQ(rep.config_invalid_field(), k.field);
    Result<S> got(log);
    const NavReplaySummary s = rep.run(log.view(), got.view());
    EXPECT_EQ(s.status, StepStatus::BadInput) << k.field;
    EXPECT_EQ(s.detail, StepDetail::BadConfig) << k.field;
  }
  NavReplay<S> good{C()};
  EXPECT_TRUE(good.config_ok());
  EXPECT_EQ(good.config_invalid_field(), nullptr);
}

TEST(NavReplayTest, EachInvalidSettingIsRefusedByNameDouble) { each_invalid_field_is_named<double>(); }
TEST(NavReplayTest, EachInvalidSettingIsRefusedByNameFloat) { each_invalid_field_is_named<float>(); }

// A log without poses cannot start the filter (BadInput, NotInitialized);
// an IMU sample whose time does not advance is counted as a rejected
// predict and the replay goes on.
TEST(NavReplayTest, NoPoseIsNotInitialisedAndARepeatedImuTimeIsCounted) {
  Log<double> log;
  Result<double> got(log);
  NavReplay<double> rep{NavConfig<double>()};
  NavReplayLog<double> none = log.view();
  none.n_pose = 0;
  const NavReplaySummary s0 = rep.run(none, got.view());
  EXPECT_EQ(s0.status, StepStatus::BadInput);
  EXPECT_EQ(s0.detail, StepDetail::NotInitialized);
  const NavReplaySummary whole = rep.run(log.view(), got.view());
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(whole.predicts_rejected, 0);
  log.t[40] = log.t[39];  // sample 40 repeats 39's time (4.1 s; the next tick bridges the gap)
  Result<double> got2(log);
  const NavReplaySummary s = rep.run(log.view(), got2.view());
  EXPECT_TRUE(s.ok());
  EXPECT_EQ(s.predicts_rejected, 1);
  EXPECT_EQ(s.poses_fused, whole.poses_fused);
}

// A run-start pose whose quaternion is not of unit norm cannot initialise
// the filter: the replay stops there and names that pose and the reason.
TEST(NavReplayTest, NonUnitRunStartQuaternionStopsAndNamesThePose) {
  Log<float> log;
  for (int c = 0; c < 4; ++c) log.q[4 * 5 + c] *= 1.1f;  // run start 5
  Result<float> got(log);
  NavReplay<float> rep{NavConfig<float>()};
  const NavReplaySummary s = rep.run(log.view(), got.view());
  EXPECT_EQ(s.status, StepStatus::BadInput);
  EXPECT_EQ(s.detail, StepDetail::NonUnitQuaternion);
  EXPECT_EQ(s.failed_pose, 5);
}

// A gyro sample so large (finite, but the attitude step overflows) that the
// propagated state is not finite: that predict is refused and counted, the
// filter keeps its state, and the next sample bridges the gap.
TEST(NavReplayTest, ImuSampleThatOverflowsThePropagationIsRefusedAndCounted) {
  Log<double> log;
  for (int c = 0; c < 3; ++c) log.gyr[3 * 40 + c] = 1e200;
  Result<double> got(log);
  NavReplay<double> rep{NavConfig<double>()};
  const NavReplaySummary s = rep.run(log.view(), got.view());
  EXPECT_TRUE(s.ok());
  EXPECT_EQ(s.predicts_rejected, 1);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(got.states[10 * 40 + i], got.states[10 * 39 + i]) << i;
  for (double v : got.states) EXPECT_TRUE(std::isfinite(v));
}
