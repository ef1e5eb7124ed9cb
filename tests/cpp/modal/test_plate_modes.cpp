// PlateModes: the flight copy of the bench's plate model (bench/sim/structure.py).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "fsw/modal/plate_modes.hpp"

using namespace fsw;

namespace {

constexpr double kPi = 3.14159265358979323846;

TEST(PlateModesTest, LowestModesInOrderOfWavenumber) {
  PlateModes<double, 10> m;  // 2000 m x 1732 m
  // k = (p / 2000)^2 + (q / 1732)^2 sorted (as bench.sim.structure.Plate(10).pq):
  const int p[10] = {1, 2, 1, 2, 3, 1, 3, 2, 4, 3};
  const int q[10] = {1, 1, 2, 2, 1, 3, 2, 3, 1, 3};
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(m.p(i), p[i]) << i;
    EXPECT_EQ(m.q(i), q[i]) << i;
  }
  for (int i = 1; i < 10; ++i) EXPECT_GT(m.omega_radps(i), m.omega_radps(i - 1));
}

TEST(PlateModesTest, FirstPeriodAndEnergyNormalisation) {
  PlateModes<double, 50> m;
  EXPECT_NEAR(2 * kPi / m.omega_radps(0), 2400.0, 1e-9);
  EXPECT_NEAR(m.scale_m(0), 25.0, 1e-12);
  const double e0 = std::pow(m.omega_radps(0) * m.scale_m(0), 2);
  for (int i = 1; i < 50; ++i) EXPECT_NEAR(std::pow(m.omega_radps(i) * m.scale_m(i), 2), e0, 1e-9 * e0) << i;
}

TEST(PlateModesTest, ShapeValuesAndPointsOffThePlate) {
  PlateModes<double, 3> m;
  double phi[3];
  ASSERT_TRUE(m.phi(1000.0, 866.0, phi));  // the centre: mode (1, 1) at its peak
  EXPECT_NEAR(phi[0], 25.0, 1e-12);
  EXPECT_NEAR(phi[1], 0.0, 1e-9);  // (2, 1) has a node line at x = Lx / 2
  const double x = 300.0, y = 1200.0;
  ASSERT_TRUE(m.phi(x, y, phi));
  EXPECT_NEAR(phi[2], m.scale_m(2) * std::sin(kPi * x / 2000.0) * std::sin(2 * kPi * y / 1732.0), 1e-12);
  phi[0] = -7.0;
  EXPECT_FALSE(m.phi(-1.0, 10.0, phi));
  EXPECT_FALSE(m.phi(10.0, 1733.0, phi));
  EXPECT_FALSE(m.phi(std::nan(""), 10.0, phi));
  EXPECT_EQ(phi[0], -7.0);  // untouched
}

// The harmonics come from a recurrence, not one sin per mode: against
// std::sin over the whole plate at 50 modes (p up to 12, q up to 10).
template <typename S>
void recurrence_matches_direct_sines(double tol) {
  PlateModes<S, 50> m;
  S phi[50];
  double worst = 0.0;
  for (int i = 0; i <= 40; ++i)
    for (int j = 0; j <= 40; ++j) {
      const double x = 2000.0 * i / 40, y = 1732.0 * j / 40;
      ASSERT_TRUE(m.phi(S(x), S(y), phi));
      for (int k = 0; k < 50; ++k) {
        const double ref = double(m.scale_m(k)) * std::sin(m.p(k) * kPi * double(S(x)) / 2000.0) *
                           std::sin(m.q(k) * kPi * double(S(y)) / 1732.0);
        worst = std::max(worst, std::abs(double(phi[k]) - ref) / double(m.scale_m(k)));
      }
    }
  EXPECT_LT(worst, tol);
}

TEST(PlateModesTest, RecurrenceMatchesDirectSinesDouble) { recurrence_matches_direct_sines<double>(1e-13); }
TEST(PlateModesTest, RecurrenceMatchesDirectSinesFloat) { recurrence_matches_direct_sines<float>(2e-5); }

TEST(PlateModesTest, InvalidConfigNamesTheFieldAndKeepsTheModel) {
  PlateModes<float, 4> m;
  PlateModelConfig c;
  c.period1_s = -1.0;
  EXPECT_STREQ(plate_config_invalid_field(c), "period1_s");
  EXPECT_FALSE(m.configure(c));
  EXPECT_NEAR(2 * kPi / double(m.omega_radps(0)), 2400.0, 1e-3);
  c = PlateModelConfig();
  c.ly_m = std::nan("");
  EXPECT_STREQ(plate_config_invalid_field(c), "ly_m");
  c = PlateModelConfig();
  c.period1_s = 1200.0;
  ASSERT_TRUE(m.configure(c));
  EXPECT_NEAR(2 * kPi / double(m.omega_radps(0)), 1200.0, 1e-3);
}

}  // namespace
