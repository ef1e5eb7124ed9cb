// The flight app: packets in, the same estimates as the filter driven
// directly, telemetry out; bad bytes counted, never fatal.
#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "flight_app_util.hpp"

using namespace fsw;
using namespace flight_app_test;

namespace {
const Quat<double> kQ0 = fsw::exp(Vec3<double>(0.1, -0.2, 0.05));
const Vec3<double> kR0(0.1, -0.7, 0.05);
const Vec3<double> kV0(0.0, 0.01, 0.0);

NavUkf<double>::Cov p0() {
  NavUkf<double>::Cov P = NavUkf<double>::Cov::Zero();
  P.diagonal() << 0.0025, 0.0025, 0.0025, 1e-4, 1e-4, 1e-4, 0.0025, 0.0025, 0.0025;
  return P;
}

// The filter the app should match, initialised as up.reset(0.0, kR0, kV0, kQ0) does.
std::unique_ptr<NavUkf<double>> reference_filter() {
  auto ref = std::make_unique<NavUkf<double>>(NavConfig<double>());
  NavUkf<double>::State x0;
  x0.r_hill_m = kR0;
  x0.v_hill_mps = kV0;
  x0.q_hb = kQ0;
  EXPECT_TRUE(ref->init(0.0, x0, p0()).ok());
  return ref;
}
}  // namespace

TEST(FlightAppTest, EstimatesEqualTheFilterDrivenDirectly) {
  auto app = std::make_unique<FlightApp<double>>();
  auto ref = reference_filter();
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 1; k <= 50; ++k) {
    const double t = 0.1 * k;
    const Vec3<double> a(1e-3 * g(rng), 1e-3 * g(rng), 1e-3 * g(rng));
    const Vec3<double> w(0.01 * g(rng), 0.01 * g(rng), 0.01 * g(rng));
    up.imu(t, a, w);
    ref->predict(t, a, w);
    if (k % 10 == 0) {
      const Vec3<double> r = ref->state().r_hill_m + Vec3<double>(0.01, -0.02, 0.01);
      const Quat<double> q = boxplus(ref->state().q_hb, Vec3<double>(0.005, 0.0, -0.005));
      // The pose captured 0.3 s earlier arrives now (a late measurement).
      up.pose(t - 0.3, r, q, 0.04, 0.01);
      NavUkf<double>::MeasCov R = NavUkf<double>::MeasCov::Zero();
      R.diagonal() << 0.0016, 0.0016, 0.0016, 1e-4, 1e-4, 1e-4;
      ASSERT_TRUE(ref->update_pose(t - 0.3, r, q, R).fused);
    }
  }
  // Feed in awkward chunks (1 to 37 bytes) to exercise reassembly.
  std::size_t i = 0, chunk = 1;
  while (i < up.bytes.size()) {
    const std::size_t n = std::min(chunk, up.bytes.size() - i);
    app->on_bytes(up.bytes.data() + i, n);
    tm.drain(*app);
    i += n;
    chunk = chunk % 37 + 1;
  }
  EXPECT_EQ(app->link().packets_accepted, 1u + 50u + 5u);
  EXPECT_EQ(app->counters().pose_fused, 5u);
  ASSERT_EQ(tm.estimates.size(), 1u + 50u + 5u);
  const auto& last = tm.estimates.back();
  EXPECT_EQ(last.r_hill_m, ref->state().r_hill_m);
  EXPECT_EQ(last.v_hill_mps, ref->state().v_hill_mps);
  EXPECT_EQ(last.q_hb.coeffs(), ref->state().q_hb.coeffs());
  EXPECT_EQ(tm.covariances.back().p_diag.head<9>(), ref->P().diagonal());
  EXPECT_EQ(tm.rejected, 0);
  EXPECT_EQ(tm.link_counters, 5);  // every tenth IMU sample
}

TEST(FlightAppTest, EveryStepAnswersWithItsRecord) {
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  up.imu(0.1, Vec3<double>::Zero(), Vec3<double>::Zero());
  up.pose(0.1, kR0 + Vec3<double>(1.0, 0.0, 0.0), kQ0, 0.04, 0.01);  // 1 m outlier: gated
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  ASSERT_EQ(tm.innovations.size(), 3u);
  EXPECT_EQ(tm.innovations[0].step_kind, static_cast<std::uint8_t>(StepKind::Reset));
  EXPECT_EQ(tm.innovations[1].step_kind, static_cast<std::uint8_t>(StepKind::Predict));
  EXPECT_EQ(tm.innovations[2].step_kind, static_cast<std::uint8_t>(StepKind::PoseUpdate));
  EXPECT_EQ(tm.innovations[2].status, static_cast<std::uint8_t>(StepStatus::Gated));
  EXPECT_EQ(tm.innovations[2].fused, 0);
  EXPECT_GT(tm.innovations[2].nis, 22.46);
}

TEST(FlightAppTest, ImuBeforeResetIsBadInputNotACrash) {
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  Telemetry tm;
  up.imu(0.1, Vec3<double>::Zero(), Vec3<double>::Zero());
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  ASSERT_EQ(tm.innovations.size(), 1u);
  EXPECT_EQ(tm.innovations[0].status, static_cast<std::uint8_t>(StepStatus::BadInput));
  EXPECT_TRUE(tm.estimates.empty());
}

TEST(FlightAppTest, GarbageBetweenPacketsIsCountedAndSkipped) {
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  const std::size_t first = up.bytes.size();
  const std::uint8_t junk[] = {0x13, 0x37, 0x00, 0xFF, 0xFF, 0xFF, 0x00};
  up.bytes.insert(up.bytes.end(), junk, junk + sizeof(junk));
  up.imu(0.1, Vec3<double>::Zero(), Vec3<double>::Zero());
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  EXPECT_GT(first, 0u);
  EXPECT_EQ(app->link().packets_accepted, 2u);
  EXPECT_EQ(app->link().rejected_total(), 2u);
  EXPECT_EQ(tm.estimates.size(), 2u);
}

TEST(FlightAppTest, ConfigWithUnknownParameterIsCountedAsRejected) {
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  CmdConfigMsg<double> m;
  m.param_id = 999;
  m.value = 1.0;
  up.add(Apid::CmdConfig, m, 0.0);
  app->on_bytes(up.bytes.data(), up.bytes.size());
  EXPECT_EQ(app->counters().configs_rejected, 1u);

  // Each known parameter: a value out of its range is refused and counted
  // and changes nothing; one in range is taken, not counted, and the
  // filter's and the modal estimator's settings apply at the next reset.
  struct Case {
    ConfigParam id;
    double bad, good;
  };
  const Case cases[] = {
      {ConfigParam::PosePosFraction, 0.0, 0.02},
      {ConfigParam::PoseAttSigmaRad, -0.01, 0.02},
      {ConfigParam::HousekeepingEvery, 100001.0, 5.0},
      {ConfigParam::NavAccelSigma, -1.0, 2e-3},
      {ConfigParam::NavGyroSigma, -1.0, 6e-3},
      {ConfigParam::NavMaxDelay, 10.0, 0.4},  // beyond the filter's history
      {ConfigParam::NavOrbitRate, 0.0, 1.2e-3},
      {ConfigParam::NavDtImu, -0.1, 0.1},
      {ConfigParam::ReacquireAfterPoses, 1001.0, 3.0},
      {ConfigParam::ReacquireLostPosSigma, -1.0, 20.0},
      {ConfigParam::ReacquireLostAttSigma, -1.0, 0.4},
      {ConfigParam::ModalPlateLx, -1.0, 1500.0},
      {ConfigParam::ModalPlateLy, 0.0, 1200.0},
      {ConfigParam::ModalPeriod1, -5.0, 2000.0},
      {ConfigParam::ModalPeak1, 0.0, 20.0},
      {ConfigParam::ModalPriorOmegaFrac, 1.5, 0.15},
      {ConfigParam::ModalAcquireAfterPeriods, -1.0, 3.0},
  };
  std::uint32_t rejected = app->counters().configs_rejected;
  Uplink& cmd = up;  // one sequence count per APID across the commands
  for (const Case& c : cases) {
    cmd.bytes.clear();
    cmd.config(0.0, c.id, c.bad);
    app->on_bytes(cmd.bytes.data(), cmd.bytes.size());
    EXPECT_EQ(app->counters().configs_rejected, ++rejected) << static_cast<int>(c.id);
    cmd.bytes.clear();
    cmd.config(0.0, c.id, c.good);
    app->on_bytes(cmd.bytes.data(), cmd.bytes.size());
    EXPECT_EQ(app->counters().configs_rejected, rejected) << static_cast<int>(c.id);
  }
  cmd.bytes.clear();
  cmd.config(0.0, ConfigParam::NavGateChi2, 30.0);
  CmdResetMsg<double> r;
  r.target_mask = 0x5;  // filter and modal estimator
  r.r_hill_m = kR0;
  r.v_hill_mps = kV0;
  r.q_hb = kQ0;
  r.pos_sigma_m = 0.05;
  r.vel_sigma_mps = 0.01;
  r.att_sigma_rad = 0.05;
  cmd.add(Apid::CmdReset, r, 1.0);
  for (int k = 1; k <= 5; ++k) cmd.imu(1.0 + 0.1 * k, Vec3<double>::Zero(), Vec3<double>::Zero());
  app->on_bytes(cmd.bytes.data(), cmd.bytes.size());
  Telemetry tm;
  tm.drain(*app);
  EXPECT_EQ(app->counters().configs_rejected, rejected);
  const NavConfig<double>& nav = app->nav().config();
  EXPECT_EQ(nav.accel_sigma_mps2, 2e-3);
  EXPECT_EQ(nav.gyro_sigma_rps, 6e-3);
  EXPECT_EQ(nav.max_delay_s, 0.4);
  EXPECT_EQ(nav.n_radps, 1.2e-3);
  EXPECT_EQ(nav.dt_imu_s, 0.1);
  EXPECT_EQ(nav.gate_chi2, 30.0);
  const ModalTrackerConfig& modal = app->modal().config();
  EXPECT_EQ(modal.plate.lx_m, 1500.0);
  EXPECT_EQ(modal.plate.ly_m, 1200.0);
  EXPECT_EQ(modal.plate.period1_s, 2000.0);
  EXPECT_EQ(modal.plate.peak1_m, 20.0);
  EXPECT_EQ(modal.prior_omega_frac, 0.15);
  EXPECT_EQ(modal.acquire_after_periods, 3.0);
  EXPECT_EQ(tm.housekeeping.size(), 1u);  // every fifth IMU sample now
}

TEST(FlightAppTest, PoseBeforeItsImuTickWaitsAndIsFusedAfterIt) {
  // The IMU sample of t = 0.2 s is lost; the pose captured at 0.2 s arrives
  // first (from_future), waits, and is fused right after the 0.3 s sample
  // (which bridges the missed tick). The result equals the filter driven
  // directly with the same samples and the pose 0.1 s late.
  auto app = std::make_unique<FlightApp<double>>();
  auto ref = reference_filter();
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  const Vec3<double> a(1e-3, -5e-4, 2e-4), w(0.01, 0.0, -0.01);
  up.imu(0.1, a, w);
  ref->predict(0.1, a, w);
  const Vec3<double> r = kR0 + Vec3<double>(0.01, 0.0, -0.01);
  up.pose(0.2, r, kQ0, 0.04, 0.01);  // before the IMU sample of its tick
  up.imu(0.3, a, w);                 // the 0.2 s sample was lost
  ASSERT_TRUE(ref->predict(0.3, a, w).ok());
  NavUkf<double>::MeasCov R = NavUkf<double>::MeasCov::Zero();
  R.diagonal() << 0.0016, 0.0016, 0.0016, 1e-4, 1e-4, 1e-4;
  ASSERT_TRUE(ref->update_pose(0.2, r, kQ0, R).fused);

  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  EXPECT_EQ(app->counters().poses_deferred, 1u);
  EXPECT_EQ(app->counters().pose_fused, 1u);
  // Reset, predict, pose (from_future, not fused), predict, pose (fused).
  ASSERT_EQ(tm.innovations.size(), 5u);
  EXPECT_EQ(tm.innovations[2].status, static_cast<std::uint8_t>(StepStatus::BadInput));
  EXPECT_EQ(tm.innovations[2].fused, 0);
  EXPECT_EQ(tm.innovations[4].step_kind, static_cast<std::uint8_t>(StepKind::PoseUpdate));
  EXPECT_EQ(tm.innovations[4].fused, 1);
  const auto& last = tm.estimates.back();
  EXPECT_LT((last.r_hill_m - ref->state().r_hill_m).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((last.v_hill_mps - ref->state().v_hill_mps).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((last.q_hb.coeffs() - ref->state().q_hb.coeffs()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(FlightAppTest, ValveCommandsTeachTheThrusterLearnerAndItsOutputIsTelemetry) {
  // Each firing interval [t, t + 0.1) is announced by thruster_valves at t;
  // the IMU sample at t + 0.1 enters the learner (accelerometer x dt, gyro
  // change) and the app answers with tm_learner. Same samples into a
  // ThrusterBlr driven directly give the same prediction.
  auto app = std::make_unique<FlightApp<double>>();
  auto ref = std::make_unique<ThrusterBlr<double, 30>>();
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  Vec3<double> w_prev = Vec3<double>::Zero();
  up.imu(0.1, Vec3<double>::Zero(), w_prev);  // the first sample only sets the gyro reference
  int fed = 0;
  std::uint8_t mask = 0;
  for (int k = 1; k <= 60; ++k) {
    const double t = 0.1 * k;
    mask = static_cast<std::uint8_t>(1 + (k * 37) % 255);
    up.valves(t, 0.1, mask);
    const Vec3<double> a(1e-3 * g(rng), 1e-3 * g(rng), 1e-3 * g(rng));
    const Vec3<double> w(0.01 * g(rng), 0.01 * g(rng), 0.01 * g(rng));
    up.imu(t + 0.1, a, w);
    ThrusterBlr<double, 30>::VecY y;
    y << a * 0.1, w - w_prev;
    ASSERT_EQ(ref->add(ValveFeatures<double>::from_mask(mask), y).status, StepStatus::Ok);
    ++fed;
    w_prev = w;
  }
  for (std::size_t i = 0; i < up.bytes.size(); i += 256) {  // drain as a serial port would
    app->on_bytes(up.bytes.data() + i, std::min<std::size_t>(256, up.bytes.size() - i));
    tm.drain(*app);
  }
  EXPECT_EQ(app->counters().tx_dropped, 0u);
  EXPECT_EQ(app->counters().valves, 60u);
  EXPECT_EQ(app->counters().learner_samples, static_cast<std::uint32_t>(fed));
  ASSERT_EQ(tm.learner.size(), 60u);
  const auto pred = ref->predict(ValveFeatures<double>::from_mask(mask));
  EXPECT_EQ(tm.learner.back().n_samples, 30u);  // the window is full
  EXPECT_LT((tm.learner.back().dv_b_mps - pred.mean.head<3>()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((tm.learner.back().dw_b_rps - pred.mean.tail<3>()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((tm.learner.back().variance - pred.variance).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(tm.rejected, 0);
}

TEST(FlightAppTest, LearnerSkipsAnIntervalWhoseOpeningImuSampleWasLost) {
  // Valves for [0.2, 0.3) but the 0.2 s sample never arrived: the gyro change
  // from 0.1 to 0.3 spans two intervals, so the sample must not be learned.
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  up.imu(0.1, Vec3<double>::Zero(), Vec3<double>::Zero());
  up.valves(0.1, 0.1, 3);
  up.imu(0.2, Vec3<double>(1e-3, 0, 0), Vec3<double>(0, 0, 0.01));  // ends [0.1, 0.2): learned
  up.valves(0.2, 0.1, 5);
  // the 0.3 s sample (end of [0.2, 0.3)) is lost; valves for [0.3, 0.4) follow
  up.valves(0.3, 0.1, 6);
  up.imu(0.4, Vec3<double>(1e-3, 0, 0), Vec3<double>(0, 0, 0.02));  // its opening sample (0.3 s) lost: skipped
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  EXPECT_EQ(app->counters().valves, 3u);
  EXPECT_EQ(app->counters().learner_samples, 1u);
  EXPECT_EQ(tm.learner.size(), 1u);

  // Valves for [0.5, 0.6) whose closing sample is lost: the 0.7 s sample,
  // past that interval, drops it unlearned; the next interval is learned.
  Uplink more = up;
  more.bytes.clear();
  more.imu(0.5, Vec3<double>::Zero(), Vec3<double>(0, 0, 0.02));
  more.valves(0.5, 0.1, 9);
  more.imu(0.7, Vec3<double>(2e-3, 0, 0), Vec3<double>(0, 0, 0.03));  // 0.6 s lost
  more.valves(0.7, 0.1, 9);
  more.imu(0.8, Vec3<double>(2e-3, 0, 0), Vec3<double>(0, 0, 0.04));
  app->on_bytes(more.bytes.data(), more.bytes.size());
  tm.drain(*app);
  EXPECT_EQ(app->counters().valves, 5u);
  EXPECT_EQ(app->counters().learner_samples, 2u);
  ASSERT_EQ(tm.learner.size(), 2u);
  EXPECT_EQ(app->learner().count(), 2);

  // A reset of the learner (bit 1) empties it; with bit 3 the link counters
  // start again from the reset.
  ASSERT_GT(app->link().packets_accepted, 0u);
  CmdResetMsg<double> r;
  r.target_mask = 0x2 | 0x8;
  Uplink reset = more;
  reset.bytes.clear();
  reset.add(Apid::CmdReset, r, 1.0);
  app->on_bytes(reset.bytes.data(), reset.bytes.size());
  EXPECT_EQ(app->learner().count(), 0);
  EXPECT_EQ(app->link().packets_accepted, 0u);
  EXPECT_EQ(app->counters().resets, 2u);
}

// ------------------------------------------------------------ hostile inputs

TEST(FlightAppTest, OverflowingPoseGivesFiniteTelemetry) {
  // A valid pose 1e308 m away overflows the step: NIS = inf, log-likelihood
  // -inf. Telemetry carries them as the largest finite doubles, so the
  // bench accepts every frame.
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  up.pose(0.0, Vec3<double>(0.0, 1e308, 0.0), kQ0, 0.0, 0.0);
  up.pose(0.0, Vec3<double>(1e308, -1e308, 1e308), kQ0, 0.04, 0.01);
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  EXPECT_EQ(tm.rejected, 0);
  ASSERT_EQ(tm.innovations.size(), 3u);
  constexpr double kMax = std::numeric_limits<double>::max();
  for (int i = 1; i < 3; ++i) {
    EXPECT_NE(tm.innovations[i].status, static_cast<std::uint8_t>(StepStatus::Ok));
    EXPECT_EQ(tm.innovations[i].fused, 0);
  }
  EXPECT_EQ(tm.innovations[2].nis, kMax);
  EXPECT_EQ(tm.innovations[2].log_likelihood, -kMax);
  EXPECT_GT(app->counters().tm_values_clamped, 0u);
  EXPECT_EQ(tm.estimates.size(), 3u);  // the filter kept its estimate
  EXPECT_TRUE(tm.estimates.back().r_hill_m.isApprox(kR0));
}

TEST(FlightAppTest, ResetFarInTheFutureDoesNotLockResetsOut) {
  // A reset tagged t = 1e300 is carried out; it clears the link's time
  // history, so a reset at a normal time is accepted after it, and the
  // filter runs on from there.
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  Telemetry tm;
  up.reset(1e300, kR0, kV0, kQ0);
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  // Its telemetry is tagged 1e300 too: the ground forgets its telemetry
  // time history when it commands a reset, as the flight side does.
  tm.deframer.reset_time_history();
  up.bytes.clear();
  up.reset(5.0, kR0, kV0, kQ0);
  up.imu(5.1, Vec3<double>::Zero(), Vec3<double>::Zero());
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  EXPECT_EQ(app->link().rejected_total(), 0u);
  EXPECT_EQ(app->counters().resets, 2u);
  EXPECT_EQ(app->nav().t_s(), 5.1);
  EXPECT_EQ(tm.rejected, 0);
  ASSERT_EQ(tm.innovations.size(), 3u);
  EXPECT_EQ(tm.innovations[2].status, static_cast<std::uint8_t>(StepStatus::Ok));
}

TEST(FlightAppTest, RepeatedResetIsStillADuplicate) {
  // Clearing the time history keeps the sequence counts: the same reset
  // packet received twice is carried out once.
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  up.reset(0.0, kR0, kV0, kQ0);
  const std::vector<std::uint8_t> once = up.bytes;
  app->on_bytes(once.data(), once.size());
  app->on_bytes(once.data(), once.size());
  EXPECT_EQ(app->counters().resets, 1u);
  EXPECT_EQ(app->link().rejected[static_cast<std::size_t>(RejectReason::DuplicateSequence)], 1u);
}

namespace {
// Reset at 0, 20 IMU samples with a pose at 1.0 s, valves into the learner.
void running_filter(Uplink& up) {
  up.reset(0.0, kR0, kV0, kQ0);
  for (int k = 1; k <= 20; ++k) {
    up.imu(0.1 * k, Vec3<double>(1e-4 * k, 0.0, 0.0), Vec3<double>(0.0, 0.0, 1e-3));
    if (k == 10) up.pose(1.0, kR0 + Vec3<double>(0.01, 0.0, 0.0), kQ0, 0.04, 0.01);
    if (k == 15) up.valves(1.5, 0.1, 3);
  }
}
}  // namespace

TEST(FlightAppTest, RefusedResetLeavesTheStateAsItWas) {
  // cmd_reset with every target bit and pos_sigma = 1e200 (its square
  // overflows): refused whole. The filter, learner, modal estimator and
  // link counters are as they were, and later samples step the same filter.
  for (const double bad_sigma : {1e200, 0.0}) {
    auto app = std::make_unique<FlightApp<double>>();
    auto ref = std::make_unique<FlightApp<double>>();
    Uplink up, up_ref;
    running_filter(up);
    running_filter(up_ref);
    CmdResetMsg<double> bad;
    bad.target_mask = 0xF;
    bad.r_hill_m = Vec3<double>(5.0, 5.0, 5.0);
    bad.q_hb = kQ0;
    bad.pos_sigma_m = bad_sigma;
    bad.vel_sigma_mps = 0.01;
    bad.att_sigma_rad = 0.05;
    up.add(Apid::CmdReset, bad, 2.05);
    for (auto* u : {&up, &up_ref}) {
      for (int k = 21; k <= 30; ++k) u->imu(0.1 * k, Vec3<double>::Zero(), Vec3<double>(0.0, 0.0, 1e-3));
    }
    app->on_bytes(up.bytes.data(), up.bytes.size());
    ref->on_bytes(up_ref.bytes.data(), up_ref.bytes.size());
    Telemetry tm;
    tm.drain(*app);
    EXPECT_EQ(app->counters().resets, 1u);
    EXPECT_EQ(app->counters().resets_refused, 1u);
    EXPECT_EQ(app->counters().learner_samples, 1u);
    EXPECT_EQ(app->learner().count(), ref->learner().count());
    EXPECT_EQ(app->link().packets_accepted, ref->link().packets_accepted + 1);
    ASSERT_TRUE(app->nav().initialized());
    EXPECT_EQ(app->nav().t_s(), ref->nav().t_s());
    EXPECT_EQ(app->nav().state().r_hill_m, ref->nav().state().r_hill_m);
    EXPECT_EQ(app->nav().P(), ref->nav().P());
    // The refused reset answers with its verdict and the unchanged estimate.
    const auto it = std::find_if(tm.innovations.begin(), tm.innovations.end(), [](const auto& m) {
      return m.step_kind == static_cast<std::uint8_t>(StepKind::Reset) && m.status != 0;
    });
    ASSERT_NE(it, tm.innovations.end());
    EXPECT_EQ(tm.innovations.back().status, static_cast<std::uint8_t>(StepStatus::Ok));
    EXPECT_EQ(tm.rejected, 0);
  }
}

TEST(FlightAppTest, TelemetryDropsAreInHousekeeping) {
  // A burst of 200 IMU samples in one read overflows the transmit buffer;
  // the drops are counted and the next housekeeping packet carries them.
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  up.reset(0.0, kR0, kV0, kQ0);
  for (int k = 1; k <= 200; ++k) up.imu(0.1 * k, Vec3<double>::Zero(), Vec3<double>::Zero());
  app->on_bytes(up.bytes.data(), up.bytes.size());
  const std::uint32_t dropped = app->counters().tx_dropped;
  EXPECT_GT(dropped, 0u);
  Telemetry tm;
  tm.drain(*app);
  Uplink more = up;
  more.bytes.clear();
  for (int k = 201; k <= 210; ++k) more.imu(0.1 * k, Vec3<double>::Zero(), Vec3<double>::Zero());
  app->on_bytes(more.bytes.data(), more.bytes.size());
  tm.drain(*app);
  ASSERT_FALSE(tm.housekeeping.empty());
  EXPECT_EQ(tm.housekeeping.back().tx_dropped, dropped);
  EXPECT_EQ(app->counters().tx_dropped, dropped);
  EXPECT_EQ(tm.housekeeping.back().cycle_count, 210u);
  // The platform's step times: the last one and the longest so far.
  app->note_step_cpu(2e-3);
  app->note_step_cpu(5e-4);
  more.bytes.clear();
  for (int k = 211; k <= 220; ++k) more.imu(0.1 * k, Vec3<double>::Zero(), Vec3<double>::Zero());
  app->on_bytes(more.bytes.data(), more.bytes.size());
  tm.drain(*app);
  EXPECT_EQ(tm.housekeeping.back().last_step_cpu_s, 5e-4);
  EXPECT_EQ(tm.housekeeping.back().max_step_cpu_s, 2e-3);
}

TEST(FlightAppTest, FloatBuildRefusesAResetWhoseSquareOverflowsFloat) {
  // pos_sigma 1e20 m is fine in double but its square overflows float: the
  // float app refuses the reset whole and keeps its filter; a pose 1e308 m
  // away (inf in float) still gives only finite telemetry.
  auto app = std::make_unique<FlightApp<float>>(NavConfig<float>());
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, kV0, kQ0);
  up.imu(0.1, Vec3<double>::Zero(), Vec3<double>::Zero());
  CmdResetMsg<double> bad;
  bad.target_mask = 0x1;
  bad.q_hb = kQ0;
  bad.pos_sigma_m = 1e20;
  bad.vel_sigma_mps = 0.01;
  bad.att_sigma_rad = 0.05;
  up.add(Apid::CmdReset, bad, 0.15);
  up.imu(0.2, Vec3<double>::Zero(), Vec3<double>::Zero());
  up.pose(0.2, Vec3<double>(0.0, 1e308, 0.0), kQ0, 0.04, 0.01);
  app->on_bytes(up.bytes.data(), up.bytes.size());
  tm.drain(*app);
  EXPECT_EQ(app->counters().resets, 1u);
  EXPECT_EQ(app->counters().resets_refused, 1u);
  ASSERT_TRUE(app->nav().initialized());
  EXPECT_EQ(app->nav().t_s(), 0.2);
  EXPECT_LT((app->nav().state().r_hill_m.cast<double>() - kR0).norm(), 0.01);  // the old filter, coasting
  EXPECT_EQ(tm.rejected, 0);
  ASSERT_FALSE(tm.innovations.empty());
  EXPECT_EQ(tm.innovations.back().status, static_cast<std::uint8_t>(StepStatus::BadInput));
}
