// The flight app's byte path (deframe, dispatch, filter, telemetry) does not
// touch the heap after construction.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "flight_app_util.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;
using namespace flight_app_test;

namespace {

// The uplink in 64-byte reads with the telemetry drained after each, under
// the heap guard; returns the allocations counted.
template <typename S>
long feed_counting_allocations(FlightApp<S>& app, const Uplink& up) {
  std::uint8_t out[4096];
  NoHeapGuard guard;
  for (std::size_t i = 0; i < up.bytes.size(); i += 64) {
    app.on_bytes(up.bytes.data() + i, std::min<std::size_t>(64, up.bytes.size() - i));
    while (app.tx_pending() > 0) app.take_tx(out, sizeof(out));
  }
  return guard.allocations();
}

}  // namespace

TEST(NoHeapTest, FlightAppByteToTelemetryPath) {
  auto app = std::make_unique<FlightApp<double>>();
  Uplink up;
  up.reset(0.0, Vec3<double>(0.1, -0.7, 0.0), Vec3<double>::Zero(), Quat<double>::Identity());
  for (int k = 1; k <= 30; ++k) {
    up.imu(0.1 * k, Vec3<double>(1e-3, 0, 0), Vec3<double>(0, 0, 0.01));
    up.valves(0.1 * k, 0.1, static_cast<std::uint8_t>(k));  // the next sample teaches the learner
    if (k % 10 == 0) up.pose(0.1 * k - 0.2, Vec3<double>(0.1, -0.7, 0.0), Quat<double>::Identity(), 0.04, 0.01);
  }
  const std::uint8_t junk[] = {0x01, 0x02, 0x00, 0x05, 0xFF, 0x00};
  up.bytes.insert(up.bytes.end(), junk, junk + sizeof(junk));
  EXPECT_EQ(feed_counting_allocations(*app, up), 0);
  EXPECT_EQ(app->counters().imu_steps, 30u);
  EXPECT_EQ(app->counters().pose_fused, 3u);
  EXPECT_EQ(app->counters().learner_samples, 29u);  // intervals ending at 0.2 .. 3.0 s
}

// Re-acquisition (a filter 1 m off and sure of it, then poses that agree)
// rebuilds the filter state in place: no heap, float and double.
template <typename S>
void reacquire_without_heap() {
  auto app = std::make_unique<FlightApp<S>>();
  Uplink up;
  up.reset(0.0, Vec3<double>(1.1, -0.7, 0.0), Vec3<double>::Zero(), Quat<double>::Identity());
  for (int k = 1; k <= 80; ++k) {
    up.imu(0.1 * k, Vec3<double>::Zero(), Vec3<double>::Zero());
    if (k % 10 == 0) up.pose(0.1 * k, Vec3<double>(0.1, -0.7, 0.0), Quat<double>::Identity(), 0.01, 0.005);
  }
  EXPECT_EQ(feed_counting_allocations(*app, up), 0);
  EXPECT_EQ(app->counters().reacquisitions, 1u);
  EXPECT_EQ(app->counters().pose_fused, 3u);  // the three poses after the fifth
}

TEST(NoHeapTest, FlightAppReacquisitionDouble) { reacquire_without_heap<double>(); }
TEST(NoHeapTest, FlightAppReacquisitionFloat) { reacquire_without_heap<float>(); }

// Range images through the modal estimator (segments into the streaming
// decomposition, one joint step per image, tm_modal out) and, at the third
// image, the frequency acquisition (search and replay): no heap, float and
// double. Three images of the plate's first mode, the second missing a segment.
template <typename S>
void modal_without_heap() {
  auto app = std::make_unique<FlightApp<S>>();
  Uplink up;
  up.config(0.0, ConfigParam::ModalAcquireAfterPeriods, 0.04);  // 96 s of the 2400 s period
  CmdResetMsg<double> reset;
  reset.target_mask = 4;  // applies the modal settings
  up.add(Apid::CmdReset, reset, 0.0);
  const double pi = 3.14159265358979323846;
  for (int k = 0; k < 3; ++k) {
    std::vector<Vec3<double>> p;
    std::vector<double> sig;
    for (int j = 0; j < 400; ++j) {
      const double x = 500.0 + 50.0 * (j % 20), y = 433.0 + 43.3 * (j / 20);
      const double z = 25.0 * std::sin(pi * x / 2000.0) * std::sin(pi * y / 1732.0) * std::cos(0.0026 * 60.0 * k);
      p.emplace_back(x, y, z + 0.5 * std::sin(7.0 * j));
      sig.push_back(0.5);
    }
    up.range_image(60.0 * k, std::uint32_t(k), p, sig, k == 1 ? std::vector<int>{3} : std::vector<int>{});
  }
  EXPECT_EQ(feed_counting_allocations(*app, up), 0);
  EXPECT_EQ(app->modal().counters().images, 3u);
  EXPECT_EQ(app->modal().counters().images_fused, 3u);
  EXPECT_EQ(app->modal().counters().acquisitions, 1u);
}

TEST(NoHeapTest, FlightAppModalDouble) { modal_without_heap<double>(); }
TEST(NoHeapTest, FlightAppModalFloat) { modal_without_heap<float>(); }

// A valve plan uplinked entry by entry, refused once (an overlap), loaded,
// started, run over its intervals (commands into telemetry and the
// learner), finished, started again and aborted: no heap, float and double.
template <typename S>
void plan_without_heap() {
  auto app = std::make_unique<FlightApp<S>>();
  Uplink up;
  up.reset(0.0, Vec3<double>(0.1, -0.7, 0.0), Vec3<double>::Zero(), Quat<double>::Identity());
  auto entry = [&up](std::uint32_t id, std::uint16_t i, std::uint16_t n, std::uint8_t valve, double a, double b) {
    CmdPlanEntryMsg m;
    m.plan_id = id;
    m.entry_index = i;
    m.entry_count = n;
    m.valve = valve;
    m.t_open_s = a;
    m.t_close_s = b;
    up.add(Apid::CmdPlanEntry, m, 0.0);
  };
  auto command = [&up](double t, PlanAction action, std::uint32_t id, std::uint32_t n, double duration) {
    CmdPlanMsg m;
    m.action = static_cast<std::uint32_t>(action);
    m.plan_id = id;
    m.entry_count = n;
    m.duration_s = duration;
    up.add(Apid::CmdPlan, m, t);
  };
  entry(1, 0, 2, 3, 0.0, 0.5);
  entry(1, 1, 2, 3, 0.4, 0.9);  // overlaps the first
  command(0.0, PlanAction::Load, 1, 2, 2.0);
  for (std::uint16_t i = 0; i < 8; ++i) entry(2, i, 8, std::uint8_t(i), 0.2 * i, 0.2 * i + 0.3);
  command(0.0, PlanAction::Load, 2, 8, 2.0);
  command(0.5, PlanAction::Start, 2, 0, 0.0);
  for (int k = 5; k <= 40; ++k) {
    up.imu(0.1 * k, Vec3<double>(1e-3, 0, 0), Vec3<double>(0, 0, 0.01));
    if (k == 30) command(3.0, PlanAction::Start, 2, 0, 0.0);
  }
  command(4.05, PlanAction::Abort, 2, 0, 0.0);
  EXPECT_EQ(feed_counting_allocations(*app, up), 0);
  EXPECT_EQ(app->counters().plans_loaded, 1u);
  EXPECT_EQ(app->counters().plan_commands_refused, 1u);
  EXPECT_EQ(app->counters().plans_finished, 1u);
  EXPECT_EQ(app->counters().plan_aborts, 1u);
  EXPECT_EQ(app->counters().plan_valve_commands, 20u + 10u);  // 0.5 .. 2.4, then 3.1 .. 4.0 (started after 3.0)
  EXPECT_GT(app->counters().learner_samples, 0u);
}

TEST(NoHeapTest, FlightAppValvePlanDouble) { plan_without_heap<double>(); }
TEST(NoHeapTest, FlightAppValvePlanFloat) { plan_without_heap<float>(); }
