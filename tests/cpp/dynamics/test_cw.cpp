// The Clohessy-Wiltshire closed forms against an independent numerical
// integration of the CW equations, and their group properties.
#include <gtest/gtest.h>

#include <cmath>

#include "fsw/dynamics/cw.hpp"
#include "tolerances.hpp"

using namespace fsw;

namespace {
constexpr double kRadius500km = kEarthRadius + 500e3;

using MatL = Eigen::Matrix<long double, 6, 9>;

// d/dt [Phi Gamma] = A [Phi Gamma] + [0 B], integrated with classical RK4 in
// long double; A is the CW system matrix written directly from the ODEs.
MatL integrate_cw(long double n, long double t_end, int steps) {
  Eigen::Matrix<long double, 6, 6> A = Eigen::Matrix<long double, 6, 6>::Zero();
  A(0, 3) = A(1, 4) = A(2, 5) = 1;
  A(3, 0) = 3 * n * n;
  A(3, 4) = 2 * n;
  A(4, 3) = -2 * n;
  A(5, 2) = -n * n;
  MatL forcing = MatL::Zero();
  forcing.block<3, 3>(3, 6).setIdentity();
  auto f = [&](const MatL& y) {
    MatL d = A * y;
    d += forcing;
    return d;
  };
  MatL y = MatL::Zero();
  y.block<6, 6>(0, 0).setIdentity();
  const long double h = t_end / steps;
  for (int k = 0; k < steps; ++k) {
    const MatL k1 = f(y);
    const MatL k2 = f(y + h / 2 * k1);
    const MatL k3 = f(y + h / 2 * k2);
    const MatL k4 = f(y + h * k3);
    y += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return y;
}

double rel_err(const Eigen::MatrixXd& a, const Eigen::MatrixXd& ref) { return (a - ref).norm() / ref.norm(); }
}  // namespace

TEST(CwTest, OrbitRateFromRadius) {
  // 500 km circular orbit: period 5677 s (Vallado, Table of LEO periods).
  const double n = orbit_rate(kRadius500km);
  EXPECT_NEAR(2 * M_PI / n, 5676.98, 0.05);
}

TEST(CwTest, StmAtZeroIsIdentity) {
  const double n = orbit_rate(kRadius500km);
  EXPECT_EQ(cw_stm(n, 0.0), Mat6<double>::Identity());
  EXPECT_EQ(cw_accel_response(n, 0.0), Mat63<double>::Zero());
  EXPECT_EQ(cw_stm(float(n), 0.0f), Mat6<float>::Identity());
}

TEST(CwTest, StmComposes) {
  const double n = orbit_rate(kRadius500km);
  const double pairs[][2] = {{0.1, 0.1}, {10, 250}, {1000, 2000}, {3000, 2677}, {1e-3, 5e3}};
  for (auto& p : pairs) {
    const Mat6<double> lhs = cw_stm(n, p[0] + p[1]);
    const Mat6<double> rhs = cw_stm(n, p[0]) * cw_stm(n, p[1]);
    EXPECT_LE(rel_err(lhs, rhs), 1e-12) << p[0] << " + " << p[1];
  }
}

TEST(CwTest, AccelResponseComposes) {
  // Gamma(a + b) = Phi(b) Gamma(a) + Gamma(b): constant input over two spans.
  const double n = orbit_rate(kRadius500km);
  const double a = 700, b = 1300;
  const Mat63<double> lhs = cw_accel_response(n, a + b);
  const Mat63<double> rhs = cw_stm(n, b) * cw_accel_response(n, a) + cw_accel_response(n, b);
  EXPECT_LE(rel_err(lhs, rhs), 1e-12);
}

class CwIntegration : public ::testing::TestWithParam<double> {};

TEST_P(CwIntegration, ClosedFormMatchesRk4WithinOnePartIn1e9) {
  const double n = orbit_rate(kRadius500km);
  const double t = GetParam() * 2 * M_PI / n;
  const MatL num = integrate_cw(n, t, 40000);
  const Eigen::MatrixXd phi_num = num.block<6, 6>(0, 0).cast<double>();
  const Eigen::MatrixXd gam_num = num.block<6, 3>(0, 6).cast<double>();
  EXPECT_LE(rel_err(cw_stm(n, t), phi_num), 1e-9);
  EXPECT_LE(rel_err(cw_accel_response(n, t), gam_num), 1e-9);
  // Column by column too, so a small column cannot hide in a large norm.
  // Over a whole orbit the cross-track response to a constant cross-track
  // acceleration returns to zero (1 - cos(2 pi) = 0): that column is checked
  // against the size it reaches over the orbit, (2/n^2), instead of itself.
  for (int j = 0; j < 6; ++j) {
    EXPECT_LE(rel_err(cw_stm(n, t).col(j), phi_num.col(j)), 1e-9) << "Phi column " << j;
  }
  for (int j = 0; j < 3; ++j) {
    const Eigen::VectorXd col = cw_accel_response(n, t).col(j);
    const Eigen::VectorXd ref = gam_num.col(j);
    const double scale = std::max(ref.norm(), j == 2 ? 2.0 / (n * n) : 0.0);
    EXPECT_LE((col - ref).norm() / scale, 1e-9) << "Gamma column " << j;
  }
}

INSTANTIATE_TEST_SUITE_P(QuarterAndWholeOrbit, CwIntegration, ::testing::Values(0.25, 1.0));

TEST(CwTest, TenHertzStepMatchesRk4) {
  const double n = orbit_rate(kRadius500km);
  const MatL num = integrate_cw(n, 0.1, 100);
  EXPECT_LE(rel_err(cw_stm(n, 0.1), num.block<6, 6>(0, 0).cast<double>()), 1e-12);
  EXPECT_LE(rel_err(cw_accel_response(n, 0.1), num.block<6, 3>(0, 6).cast<double>()), 1e-12);
}

TEST(CwTest, FloatBuildAgreesWithDouble) {
  // Float tolerance is documented in tolerances.hpp; at 10 Hz the naive
  // (1 - cos) form would lose every digit in float. The float build is for
  // the flight steps (0.1 s to 100 s); over long spans the rounding of n t
  // (1e-7 relative) is amplified by the secular along-track terms.
  const double n = orbit_rate(kRadius500km);
  for (double t : {0.1, 1.0, 10.0, 100.0}) {
    const Mat6<double> pd = cw_stm(n, t);
    const Mat6<double> pf = cw_stm(float(n), float(t)).cast<double>();
    const Mat63<double> gd = cw_accel_response(n, t);
    const Mat63<double> gf = cw_accel_response(float(n), float(t)).cast<double>();
    for (int j = 0; j < 6; ++j) EXPECT_LE(rel_err(pf.col(j), pd.col(j)), Tol<float>::cw_rel) << t;
    for (int j = 0; j < 3; ++j) EXPECT_LE(rel_err(gf.col(j), gd.col(j)), Tol<float>::cw_rel) << t;
  }
}

TEST(CwTest, PropagatorStepEqualsClosedForm) {
  const double n = orbit_rate(kRadius500km);
  CwPropagator<double> prop(n, 0.1);
  Vec6<double> s;
  s << 0.5, -0.3, 0.1, 0.01, -0.02, 0.005;
  const Eigen::Vector3d a(1e-3, -2e-3, 5e-4);
  Vec6<double> x = s;
  for (int k = 0; k < 1000; ++k) x = prop.step(x, a);
  const Vec6<double> expected = cw_stm(n, 100.0) * s + cw_accel_response(n, 100.0) * a;
  EXPECT_LE((x - expected).norm() / expected.norm(), 1e-11);
}

TEST(CwTest, AlongTrackOffsetIsEquilibrium) {
  const double n = orbit_rate(kRadius500km);
  Vec6<double> s = Vec6<double>::Zero();
  s(1) = 10.0;
  EXPECT_LE((cw_stm(n, 5000.0) * s - s).norm(), 1e-12);
}

// The propagator keeps the closed-form matrices of its step, reports its
// orbit rate and step, and a step without thrust is the free CW motion.
TEST(CwTest, PropagatorKeepsItsMatricesAndCoastsWithoutThrust) {
  const double n = orbit_rate(kRadius500km);
  const CwPropagator<double> prop(n, 0.1);
  EXPECT_EQ(prop.orbit_rate_radps(), n);
  EXPECT_EQ(prop.dt_s(), 0.1);
  EXPECT_EQ(prop.stm(), cw_stm(n, 0.1));
  EXPECT_EQ(prop.accel_response(), cw_accel_response(n, 0.1));
  Vec6<double> s;
  s << 0.5, -0.3, 0.1, 0.01, -0.02, 0.005;
  EXPECT_EQ(prop.step(s), prop.step(s, Eigen::Vector3d::Zero()));
  Vec6<double> x = s;
  for (int k = 0; k < 1000; ++k) x = prop.step(x);
  const Vec6<double> expected = cw_stm(n, 100.0) * s;
  EXPECT_LE((x - expected).norm() / expected.norm(), 1e-11);
}
