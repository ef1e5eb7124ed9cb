// Properties of the SO(3) vocabulary, for float and double.
#include <gtest/gtest.h>

#include <random>

#include "fsw/dynamics/hill_attitude.hpp"
#include "fsw/math/so3.hpp"
#include "tolerances.hpp"

using namespace fsw;

template <typename S>
class So3Test : public ::testing::Test {};
using Scalars = ::testing::Types<double, float>;
TYPED_TEST_SUITE(So3Test, Scalars);

namespace {
// Rotation vectors from tiny (series branch) to near pi (large branch).
template <typename S>
std::vector<Vec3<S>> sample_vectors(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Vec3<S>> out;
  const double mags[] = {0.0, 1e-9, 1e-6, 1e-4, 5e-3, 1e-2, 0.1, 1.0, 2.5, 3.1};
  for (double m : mags) {
    for (int k = 0; k < 20; ++k) {
      Eigen::Vector3d d(g(rng), g(rng), g(rng));
      d = d.normalized() * m;
      out.push_back(d.cast<S>());
    }
  }
  return out;
}
}  // namespace

TYPED_TEST(So3Test, LogOfExpIsIdentity) {
  using S = TypeParam;
  for (const auto& v : sample_vectors<S>(1)) {
    const Vec3<S> back = fsw::log(fsw::exp(v));
    EXPECT_LE((back - v).norm(), Tol<S>::so3 * std::max<S>(1, v.norm())) << v.transpose();
  }
}

TYPED_TEST(So3Test, ExpIsUnitQuaternion) {
  using S = TypeParam;
  for (const auto& v : sample_vectors<S>(2)) {
    EXPECT_NEAR(fsw::exp(v).norm(), S(1), Tol<S>::so3);
  }
}

TYPED_TEST(So3Test, BoxminusOfBoxplusIsIdentity) {
  using S = TypeParam;
  const auto base = sample_vectors<S>(3);
  const auto deltas = sample_vectors<S>(4);
  for (size_t i = 0; i < base.size(); ++i) {
    const Quat<S> q = fsw::exp(base[i]);
    const Vec3<S>& d = deltas[i];
    const Vec3<S> back = boxminus(boxplus(q, d), q);
    EXPECT_LE((back - d).norm(), S(4) * Tol<S>::so3 * std::max<S>(1, d.norm()));
  }
}

TYPED_TEST(So3Test, ExpMatchesAngleAxis) {
  using S = TypeParam;
  for (const auto& v : sample_vectors<S>(5)) {
    if (v.norm() == S(0)) continue;
    const Eigen::AngleAxis<S> aa(v.norm(), v.normalized());
    const Mat3<S> expected = aa.toRotationMatrix();
    EXPECT_LE((rotation_matrix(fsw::exp(v)) - expected).norm(), S(4) * Tol<S>::so3);
  }
}

TYPED_TEST(So3Test, LogPicksShortestRotation) {
  using S = TypeParam;
  const Vec3<S> v(S(0.3), S(-0.2), S(0.1));
  Quat<S> q = fsw::exp(v);
  q.coeffs() = -q.coeffs();  // same rotation, other hemisphere
  EXPECT_LE((fsw::log(q) - v).norm(), Tol<S>::so3);
}

TYPED_TEST(So3Test, RotationMatrixTakesBodyToHill) {
  using S = TypeParam;
  // 90 deg about Hill z: body x lies along Hill y.
  const Quat<S> q = fsw::exp(Vec3<S>(S(0), S(0), S(M_PI / 2)));
  const Vec3<S> x_in_hill = rotation_matrix(q) * Vec3<S>::UnitX();
  EXPECT_LE((x_in_hill - Vec3<S>::UnitY()).norm(), S(4) * Tol<S>::so3);
}

TYPED_TEST(So3Test, WxyzRoundTripIsScalarFirst) {
  using S = TypeParam;
  const Vec4<S> wxyz(S(0.5), S(0.5), S(-0.5), S(0.5));
  const Quat<S> q = from_wxyz(wxyz);
  EXPECT_EQ(q.w(), S(0.5));
  EXPECT_EQ(q.y(), S(-0.5));
  EXPECT_EQ(to_wxyz(q), wxyz);
}

TYPED_TEST(So3Test, IsUnitRejectsNanAndNonUnit) {
  using S = TypeParam;
  EXPECT_TRUE(is_unit(Vec4<S>(1, 0, 0, 0), S(1e-3)));
  EXPECT_FALSE(is_unit(Vec4<S>(1.1f, 0, 0, 0), S(1e-3)));
  EXPECT_FALSE(is_unit(Vec4<S>(std::numeric_limits<S>::quiet_NaN(), 0, 0, 0), S(1e-3)));
}

TYPED_TEST(So3Test, InertiallyFixedBodyCountersHillRotation) {
  // A body that does not turn in inertial space turns at -n about Hill z,
  // so after a quarter orbit its attitude in the Hill frame is -90 deg about z.
  using S = TypeParam;
  const S n = S(0.0011);
  const S quarter = S(M_PI / 2) / n;
  const int steps = 10000;
  Quat<S> q = Quat<S>::Identity();
  const S dt = quarter / S(steps);
  for (int k = 0; k < steps; ++k) q = propagate_attitude(q, Vec3<S>(Vec3<S>::Zero()), n, dt);
  const Vec3<S> expected(S(0), S(0), S(-M_PI / 2));
  EXPECT_LE((fsw::log(q) - expected).norm(), S(steps) * Tol<S>::so3 + Tol<S>::so3);
}

TYPED_TEST(So3Test, AttitudeStepIsExactForConstantRates) {
  // Constant body rate: one big step equals many small ones.
  using S = TypeParam;
  const S n = S(0.0011);
  const Vec3<S> w(S(0.02), S(-0.01), S(0.03));
  const Quat<S> q0 = fsw::exp(Vec3<S>(S(0.1), S(0.2), S(-0.3)));
  const Quat<S> one = propagate_attitude(q0, w, n, S(10));
  Quat<S> many = q0;
  for (int k = 0; k < 100; ++k) many = propagate_attitude(many, w, n, S(0.1));
  EXPECT_LE(boxminus(one, many).norm(), S(200) * Tol<S>::so3);
}
