// The flight app re-acquires from poses when its filter is lost (a long
// outage) or keeps rejecting poses that agree with each other, and does not
// for lone or disagreeing outliers.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <random>
#include <type_traits>

#include "flight_app_util.hpp"

using namespace fsw;
using namespace flight_app_test;

namespace {

const Quat<double> kQ0 = normalized(Quat<double>(0.9, 0.1, -0.2, 0.3));
const Vec3<double> kR0(0.1, -0.7, 0.05);

// The inspector inertially fixed: the body turns at -n about Hill z.
Quat<double> q_true(double n, double t) { return fsw::exp(Vec3<double>(0, 0, -n * t)) * kQ0; }

// Fed in small chunks with the telemetry drained after each (the app's
// transmit buffer holds about 50 steps' answers).
template <typename S>
void feed(FlightApp<S>& app, Uplink& up, Telemetry& tm) {
  for (std::size_t i = 0; i < up.bytes.size(); i += 256) {
    app.on_bytes(up.bytes.data() + i, std::min<std::size_t>(256, up.bytes.size() - i));
    tm.drain(app);
  }
  up.bytes.clear();
}

int count_kind(const Telemetry& tm, StepKind k, StepStatus st) {
  int c = 0;
  for (const auto& i : tm.innovations)
    if (i.step_kind == static_cast<std::uint8_t>(k) && i.status == static_cast<std::uint8_t>(st)) ++c;
  return c;
}

}  // namespace

template <typename S>
class FlightAppReacquireTest : public ::testing::Test {};
using Scalars = ::testing::Types<double, float>;
TYPED_TEST_SUITE(FlightAppReacquireTest, Scalars);

TYPED_TEST(FlightAppReacquireTest, AfterAnHourWithoutPosesTheFirstPoseReacquiresAndTheRestFuse) {
  // Beside it, the same bytes into an app with both rules off (the control):
  // in float its first poses after the outage are refused (the update would
  // shrink kilometres of position variance to centimetres, below float's
  // resolution), where the re-acquiring app fuses every pose after the first.
  using S = TypeParam;
  auto app = std::make_unique<FlightApp<S>>();
  auto control = std::make_unique<FlightApp<S>>();
  const double n = double(app->nav().config().n_radps);
  const double sa = double(app->nav().config().accel_sigma_mps2), sg = double(app->nav().config().gyro_sigma_rps);
  std::mt19937_64 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  Telemetry tm, tm_control;
  Uplink up, up_control;
  auto both = [&]() {
    up_control.bytes = up.bytes;
    feed(*app, up, tm);
    feed(*control, up_control, tm_control);
  };
  up.config(0.0, ConfigParam::ReacquireAfterPoses, 0.0);
  up.config(0.0, ConfigParam::ReacquireLostPosSigma, 0.0);
  up.config(0.0, ConfigParam::ReacquireLostAttSigma, 0.0);
  up_control.bytes = up.bytes;
  feed(*control, up_control, tm_control);
  up.bytes.clear();
  up.reset(0.0, Vec3<double>::Zero(), Vec3<double>::Zero(), kQ0);  // at the host's centre of mass, at rest
  both();
  for (long s = 1; s <= 3600; ++s) {
    for (int k = 1; k <= 10; ++k)
      up.imu(double(s - 1) + 0.1 * k, Vec3<double>(sa * g(rng), sa * g(rng), sa * g(rng)),
             Vec3<double>(sg * g(rng), sg * g(rng), sg * g(rng)));
    both();
  }
  // Lost: position sigma above 10 m (the attitude's grows only with gyro noise).
  ASSERT_GT(double(app->nav().P()(0, 0)), 100.0);
  const double rs = 0.01, as = 0.005;
  for (long s = 3601; s <= 3900; ++s) {
    for (int k = 1; k <= 10; ++k)
      up.imu(double(s - 1) + 0.1 * k, Vec3<double>(sa * g(rng), sa * g(rng), sa * g(rng)),
             Vec3<double>(sg * g(rng), sg * g(rng), sg * g(rng)));
    up.pose(double(s), Vec3<double>(rs * g(rng), rs * g(rng), rs * g(rng)),
            boxplus(q_true(n, double(s)), Vec3<double>(as * g(rng), as * g(rng), as * g(rng))), rs, as);
    both();
  }
  EXPECT_EQ(app->counters().reacquisitions, 1u);
  EXPECT_EQ(count_kind(tm, StepKind::Reacquire, StepStatus::Ok), 1);
  // Every pose after the first fuses but for the NIS gate's own false
  // rejections: it refuses a consistent pose with probability 0.001 (chi2, 6
  // dof, at 22.46), so over 299 poses none with probability 0.74 and more
  // than 3 with probability 2e-4 (binomial). Which poses it refuses follows
  // the noise draws, and those follow the platform's libm
  // (std::normal_distribution calls log): one of 299 under qemu-aarch64.
  const int gated = count_kind(tm, StepKind::PoseUpdate, StepStatus::Gated);
  EXPECT_LE(gated, 3);
  EXPECT_EQ(app->counters().pose_fused + unsigned(gated), 299u);
  EXPECT_EQ(count_kind(tm, StepKind::PoseUpdate, StepStatus::NotPosDef), 0);
  EXPECT_LT(double(app->nav().state().r_hill_m.norm()), 0.05);
  EXPECT_LT(boxminus(q_true(n, 3900.0), app->nav().state().q_hb.template cast<double>()).norm(), 0.02);
  EXPECT_EQ(control->counters().reacquisitions, 0u);
  if constexpr (std::is_same_v<S, float>) {
    EXPECT_GT(count_kind(tm_control, StepKind::PoseUpdate, StepStatus::NotPosDef), 0);
  }
}

TYPED_TEST(FlightAppReacquireTest, AConfidentlyWrongFilterReacquiresAtTheFifthAgreeingRejectedPose) {
  using S = TypeParam;
  auto app = std::make_unique<FlightApp<S>>();
  const double n = double(app->nav().config().n_radps);
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0 + Vec3<double>(1.0, 0.0, 0.0), Vec3<double>::Zero(), kQ0);  // 1 m off, told 5 cm
  for (int k = 1; k <= 100; ++k) {
    const double t = 0.1 * k;
    up.imu(t, Vec3<double>::Zero(), Vec3<double>::Zero());
    if (k % 10 == 0) up.pose(t, kR0, q_true(n, t), 0.01, 0.005);
  }
  feed(*app, up, tm);
  // tm_innovation per step: reset, then per second 10 predicts and one pose record.
  std::vector<std::uint8_t> pose_kinds, pose_status;
  for (const auto& i : tm.innovations)
    if (i.step_kind == static_cast<std::uint8_t>(StepKind::PoseUpdate) ||
        i.step_kind == static_cast<std::uint8_t>(StepKind::Reacquire)) {
      pose_kinds.push_back(i.step_kind);
      pose_status.push_back(i.status);
    }
  ASSERT_EQ(pose_kinds.size(), 10u);
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(pose_kinds[i], static_cast<std::uint8_t>(StepKind::PoseUpdate));
    EXPECT_EQ(pose_status[i], static_cast<std::uint8_t>(StepStatus::Gated));
  }
  EXPECT_EQ(pose_kinds[4], static_cast<std::uint8_t>(StepKind::Reacquire));
  EXPECT_EQ(pose_status[4], static_cast<std::uint8_t>(StepStatus::Ok));
  for (int i = 5; i < 10; ++i) {
    EXPECT_EQ(pose_kinds[i], static_cast<std::uint8_t>(StepKind::PoseUpdate));
    EXPECT_EQ(pose_status[i], static_cast<std::uint8_t>(StepStatus::Ok));
  }
  EXPECT_EQ(app->counters().reacquisitions, 1u);
  EXPECT_EQ(app->counters().pose_fused, 5u);
  EXPECT_LT((app->nav().state().r_hill_m.template cast<double>() - kR0).norm(), 0.03);
}

TEST(FlightAppReacquireTest, LoneOrDisagreeingOutliersDoNotReacquire) {
  auto app = std::make_unique<FlightApp<double>>();
  const double n = app->nav().config().n_radps;
  Uplink up;
  Telemetry tm;
  up.reset(0.0, kR0, Vec3<double>::Zero(), kQ0);
  int second = 0;
  auto one_second = [&](const Vec3<double>& pose_offset) {
    ++second;
    for (int k = 1; k <= 10; ++k) up.imu(second - 1 + 0.1 * k, Vec3<double>::Zero(), Vec3<double>::Zero());
    up.pose(second, kR0 + pose_offset, q_true(n, second), 0.01, 0.005);
  };
  for (int i = 0; i < 3; ++i) one_second(Vec3<double>::Zero());
  for (int i = 0; i < 4; ++i) one_second(Vec3<double>(1.0, 0.0, 0.0));  // 4 agreeing outliers: one short of 5
  one_second(Vec3<double>::Zero());                                     // a good pose ends the run
  for (int i = 0; i < 8; ++i) one_second(Vec3<double>((i % 2) ? 1.0 : -1.0, 0.0, 0.0));  // outliers that disagree
  for (int i = 0; i < 3; ++i) one_second(Vec3<double>::Zero());
  feed(*app, up, tm);
  EXPECT_EQ(app->counters().reacquisitions, 0u);
  EXPECT_EQ(count_kind(tm, StepKind::PoseUpdate, StepStatus::Gated), 12);
  EXPECT_EQ(app->counters().pose_fused, 7u);
  EXPECT_LT((app->nav().state().r_hill_m - kR0).norm(), 0.02);
}

TEST(FlightAppReacquireTest, ConfigZeroDisablesARuleAndBadValuesAreRefused) {
  auto app = std::make_unique<FlightApp<double>>();
  const double n = app->nav().config().n_radps;
  Uplink up;
  Telemetry tm;
  up.config(0.0, ConfigParam::ReacquireAfterPoses, 0.0);
  up.config(0.0, ConfigParam::ReacquireLostAttSigma, -1.0);  // refused
  up.config(0.0, ConfigParam::ReacquireAfterPoses, 5000.0);  // refused
  up.reset(0.0, kR0 + Vec3<double>(1.0, 0.0, 0.0), Vec3<double>::Zero(), kQ0);
  for (int k = 1; k <= 100; ++k) {
    up.imu(0.1 * k, Vec3<double>::Zero(), Vec3<double>::Zero());
    if (k % 10 == 0) up.pose(0.1 * k, kR0, q_true(n, 0.1 * k), 0.01, 0.005);
  }
  feed(*app, up, tm);
  EXPECT_EQ(app->counters().configs_rejected, 2u);
  EXPECT_EQ(app->counters().reacquisitions, 0u);
  EXPECT_EQ(count_kind(tm, StepKind::PoseUpdate, StepStatus::Gated), 10);
}
