// The flight app's modal estimator: range images of the range-image paper's plate arrive
// as segments over the link and come back as tm_modal, one filter step per
// image; lost segments, short images, stale images and bad settings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "flight_app_util.hpp"
#include "fsw/modal/modal_decomposition.hpp"
#include "fsw/modal/modal_ukf.hpp"
#include "fsw/modal/plate_modes.hpp"
#include "plate_scene.hpp"

using namespace fsw;
using namespace flight_app_test;

namespace {

using plate_scene::kDt;
using plate_scene::kM;
using plate_scene::PlateScene;

template <typename S>
void feed(FlightApp<S>& app, Uplink& up, Telemetry& tm) {
  for (std::size_t i = 0; i < up.bytes.size(); i += 512) {
    app.on_bytes(up.bytes.data() + i, std::min<std::size_t>(512, up.bytes.size() - i));
    tm.drain(app);
  }
  up.bytes.clear();
}

void modal_reset(Uplink& up, double t) {
  CmdResetMsg<double> m;
  m.target_mask = 4;  // modal only
  up.add(Apid::CmdReset, m, t);
}

}  // namespace

template <typename S>
class FlightAppModalTest : public ::testing::Test {};
using Scalars = ::testing::Types<double, float>;
TYPED_TEST_SUITE(FlightAppModalTest, Scalars);

TYPED_TEST(FlightAppModalTest, FrequenciesConvergeWithinThreePeriodsOfTheLowestMode) {
  // The on-board model's first period 5 % long (every a priori frequency
  // 5 % low, told 10 %); 120 images = 3 periods of the lowest mode.
  using S = TypeParam;
  auto app = std::make_unique<FlightApp<S>>();
  PlateScene scene(11);
  Uplink up;
  Telemetry tm;
  up.config(0.0, ConfigParam::ModalPeriod1, 2400.0 * 1.05);
  modal_reset(up, 0.0);
  feed(*app, up, tm);
  std::vector<Vec3<double>> p;
  std::vector<double> sig;
  for (int k = 0; k < 120; ++k) {
    scene.image(k * kDt, p, sig);
    up.range_image(k * kDt, std::uint32_t(k), p, sig);
    feed(*app, up, tm);
  }
  ASSERT_EQ(tm.modal.size(), 120u);
  int fused = 0;
  for (const auto& m : tm.modal) {
    fused += m.fused;
    EXPECT_EQ(m.n_used, 900u);
    EXPECT_EQ(m.decomposition, std::uint8_t(ModalStatus::Ok));
    EXPECT_GT(m.rcond, 1e-4);  // central quarter: cond(M_Y) in the hundreds
  }
  EXPECT_EQ(fused, 120);
  EXPECT_EQ(app->counters().unhandled, 0u);
  EXPECT_EQ(app->modal().counters().images_fused, 120u);
  const auto& last = tm.modal.back();
  EXPECT_EQ(last.n_modes, kM);
  EXPECT_DOUBLE_EQ(double(last.t_s), 119 * kDt);
  int strong = 0;
  for (int i = 0; i < kM; ++i) {
    const double w = scene.truth.omega_radps(i);
    EXPECT_NEAR(double(app->modal().model().omega_radps(i)), w / 1.05, 1e-4 * w);  // the prior
    if (scene.amp[i] < 0.2) continue;  // too little signal at 18 m noise (docs/perf/modal.md)
    ++strong;
    EXPECT_NEAR(last.omega_radps(i), w, 0.01 * w) << "mode " << i << " amplitude " << scene.amp[i];
    EXPECT_NEAR(last.amplitude(i), scene.coeff(i, 119 * kDt), 4 * last.amplitude_sigma(i) + 0.02) << "mode " << i;
  }
  EXPECT_GE(strong, 6);
}

TEST(FlightAppModalTest, SameStepsAsTheLibraryFedDirectly) {
  // The segment path (framing, decoding, streaming per segment) changes
  // nothing: the same numbers as the decomposition and joint filter called
  // directly.
  FlightApp<double> app;
  PlateScene scene(3);
  Uplink up;
  Telemetry tm;
  PlateModes<double, kM> model;
  ModalDecomposition<double, kM> dec;
  ModalUkfJoint<double, kM> bank(ModalTracker<double, kM>::filter_config(model, ModalTrackerConfig()));
  std::vector<Vec3<double>> p;
  std::vector<double> sig;
  double phi[kM];
  for (int k = 0; k < 20; ++k) {
    scene.image(k * kDt, p, sig);
    up.range_image(k * kDt, std::uint32_t(k), p, sig);
    feed(app, up, tm);
    dec.reset();
    for (std::size_t j = 0; j < p.size(); ++j) {
      ASSERT_TRUE(model.phi(p[j].x(), p[j].y(), phi));
      dec.add_point(phi, p[j].z(), sig[j] * sig[j]);
    }
    ModalDecompositionRecord<double, kM> drec;
    dec.solve(drec);
    ModalStepRecord<double, kM> srec;
    bank.step(kDt, drec, srec);
    ASSERT_EQ(tm.modal.size(), std::size_t(k + 1));
    const auto& m = tm.modal.back();
    for (int i = 0; i < kM; ++i) {
      const auto x = bank.mode_state(i);
      EXPECT_EQ(m.amplitude(i), x(0)) << k << " " << i;
      EXPECT_EQ(m.omega_radps(i), x(2)) << k << " " << i;
      EXPECT_EQ(m.alpha_ps(i), x(3)) << k << " " << i;
    }
    EXPECT_EQ(m.nis, srec.nis);
  }
}

TYPED_TEST(FlightAppModalTest, ALostSegmentLosesOnlyItsPoints) {
  using S = TypeParam;
  FlightApp<S> app;
  PlateScene scene(5);
  Uplink up;
  Telemetry tm;
  std::vector<Vec3<double>> p;
  std::vector<double> sig;
  // 900 points = 37 segments of 24 and a last one of 12.
  const std::vector<std::vector<int>> drops = {{}, {5}, {37}, {}};
  for (int k = 0; k < 4; ++k) {
    scene.image(k * kDt, p, sig);
    up.range_image(k * kDt, std::uint32_t(100 + k), p, sig, drops[std::size_t(k)]);
  }
  feed(app, up, tm);
  ASSERT_EQ(tm.modal.size(), 4u);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(tm.modal[std::size_t(k)].image_id, std::uint32_t(100 + k));
    EXPECT_EQ(tm.modal[std::size_t(k)].fused, 1);
    EXPECT_DOUBLE_EQ(double(tm.modal[std::size_t(k)].t_s), k * kDt);
  }
  EXPECT_EQ(tm.modal[1].n_used, 900u - 24u);
  EXPECT_EQ(tm.modal[2].n_used, 900u - 12u);  // closed by image 103's first segment
  EXPECT_EQ(app.modal().counters().images_incomplete, 1u);
  EXPECT_EQ(app.link().gaps_total(), 2u);
}

TYPED_TEST(FlightAppModalTest, ShortStaleAndOffPlateImages) {
  using S = TypeParam;
  FlightApp<S> app;
  PlateScene scene(8);
  Uplink up;
  Telemetry tm;
  std::vector<Vec3<double>> p;
  std::vector<double> sig;
  scene.image(0.0, p, sig);
  up.range_image(0.0, 1, p, sig);
  // 3 x 3 = 9 points for 10 modes: no estimate, no update.
  scene.image(kDt, p, sig, 3);
  up.range_image(kDt, 2, p, sig);
  feed(app, up, tm);
  ASSERT_EQ(tm.modal.size(), 2u);
  EXPECT_EQ(tm.modal[1].decomposition, std::uint8_t(ModalStatus::TooFewPoints));
  EXPECT_EQ(tm.modal[1].status, std::uint8_t(StepStatus::BadInput));
  EXPECT_EQ(tm.modal[1].fused, 0);
  EXPECT_EQ(tm.modal[1].n_used, 9u);
  // Another image at the time of the last one stepped: dropped whole,
  // counted. (One from earlier never gets past the link: time_backwards.)
  scene.image(kDt, p, sig);
  up.range_image(kDt, 3, p, sig);
  scene.image(30.0, p, sig);
  up.range_image(30.0, 4, p, sig);
  feed(app, up, tm);
  EXPECT_EQ(tm.modal.size(), 2u);
  EXPECT_EQ(app.modal().counters().segments_stale, 38u);
  EXPECT_EQ(app.link().rejected[std::size_t(RejectReason::TimeBackwards)], 38u);
  // Points off the plate are skipped and counted; the rest fuse.
  scene.image(2 * kDt, p, sig);
  for (int j = 0; j < 10; ++j) p[std::size_t(j)].x() = -5.0;
  up.range_image(2 * kDt, 5, p, sig);
  feed(app, up, tm);
  ASSERT_EQ(tm.modal.size(), 3u);
  EXPECT_EQ(tm.modal[2].n_used, 890u);
  EXPECT_EQ(tm.modal[2].n_skipped, 10u);
  EXPECT_EQ(tm.modal[2].fused, 1);
  EXPECT_EQ(app.modal().counters().points_outside, 10u);
  // A modal reset restarts the filter; the counters run on.
  modal_reset(up, 2 * kDt);
  feed(app, up, tm);
  EXPECT_FALSE(app.modal().filter().initialized());
  EXPECT_EQ(app.modal().counters().images, 3u);
  EXPECT_EQ(app.modal().counters().segments_stale, 38u);
}

TEST(FlightAppModalTest, SettingsApplyAtTheModalResetAndBadOnesAreRefused) {
  FlightApp<double> app;
  Uplink up;
  Telemetry tm;
  up.config(0.0, ConfigParam::ModalPeriod1, -5.0);
  up.config(0.0, ConfigParam::ModalPriorOmegaFrac, 1.5);
  up.config(0.0, ConfigParam::ModalPlateLx, 0.0);
  up.config(0.0, ConfigParam::ModalPeak1, 10.0);
  up.config(0.0, ConfigParam::ModalPeriod1, 1200.0);
  up.config(0.0, ConfigParam::ModalAcquireAfterPeriods, -1.0);
  up.config(0.0, ConfigParam::ModalAcquireAfterPeriods, 3.0);
  feed(app, up, tm);
  EXPECT_EQ(app.counters().configs_rejected, 4u);
  EXPECT_EQ(app.modal().config().acquire_after_periods, 2.0);                                  // not yet
  EXPECT_NEAR(2 * 3.14159265358979323846 / app.modal().model().omega_radps(0), 2400.0, 1e-9);  // not yet
  modal_reset(up, 0.0);
  feed(app, up, tm);
  EXPECT_NEAR(2 * 3.14159265358979323846 / app.modal().model().omega_radps(0), 1200.0, 1e-9);
  EXPECT_NEAR(app.modal().model().scale_m(0), 10.0, 1e-12);
  EXPECT_EQ(app.modal().config().acquire_after_periods, 3.0);
  EXPECT_FALSE(app.modal().filter().initialized());
}
