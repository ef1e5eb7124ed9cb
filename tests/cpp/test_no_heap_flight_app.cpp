// The flight app's byte path (deframe, dispatch, filter, telemetry) does not
// touch the heap after construction.
#include <gtest/gtest.h>

#include <memory>

#include "flight_app_util.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;
using namespace flight_app_test;

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
  std::uint8_t out[4096];
  long allocations = 0;
  {
    NoHeapGuard guard;
    for (std::size_t i = 0; i < up.bytes.size(); i += 64) {
      const std::size_t n = std::min<std::size_t>(64, up.bytes.size() - i);
      app->on_bytes(up.bytes.data() + i, n);
      while (app->tx_pending() > 0) app->take_tx(out, sizeof(out));
    }
    allocations = guard.allocations();
  }
  EXPECT_EQ(allocations, 0);
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
  std::uint8_t out[4096];
  long allocations = 0;
  {
    NoHeapGuard guard;
    for (std::size_t i = 0; i < up.bytes.size(); i += 64) {
      app->on_bytes(up.bytes.data() + i, std::min<std::size_t>(64, up.bytes.size() - i));
      while (app->tx_pending() > 0) app->take_tx(out, sizeof(out));
    }
    allocations = guard.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(app->counters().reacquisitions, 1u);
  EXPECT_EQ(app->counters().pose_fused, 3u);  // the three poses after the fifth
}

TEST(NoHeapTest, FlightAppReacquisitionDouble) { reacquire_without_heap<double>(); }
TEST(NoHeapTest, FlightAppReacquisitionFloat) { reacquire_without_heap<float>(); }
