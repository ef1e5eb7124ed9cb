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
