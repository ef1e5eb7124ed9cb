// Properties of the dual quaternion type, float and double, each checked
// against an independent rotation-matrix (SE(3)) computation.
#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <vector>

#include "fsw/math/dual_quaternion.hpp"

using namespace fsw;

template <typename S>
class DualQuatTest : public ::testing::Test {};
using Scalars = ::testing::Types<double, float>;
TYPED_TEST_SUITE(DualQuatTest, Scalars);

namespace {
template <typename S>
S tol() {
  return std::is_same<S, float>::value ? S(2e-5) : S(1e-12);
}

struct Motion {
  Eigen::Quaterniond q;
  Eigen::Vector3d t;
};

std::vector<Motion> sample_motions(unsigned seed, int n = 60) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Motion> out;
  const double mags[] = {0.0, 1e-7, 1e-3, 0.5, 2.0, 3.1};
  for (int k = 0; k < n; ++k) {
    Eigen::Vector3d axis(g(rng), g(rng), g(rng));
    const double ang = mags[k % 6];
    Motion m;
    m.q = Eigen::Quaterniond(Eigen::AngleAxisd(ang, axis.normalized()));
    m.t = Eigen::Vector3d(g(rng), g(rng), g(rng)) * 3.0;
    out.push_back(m);
  }
  return out;
}

template <typename S>
DualQuat<S> dq(const Motion& m) {
  return DualQuat<S>::from_rotation_translation(m.q.cast<S>(), m.t.cast<S>());
}
}  // namespace

TYPED_TEST(DualQuatTest, RotationTranslationRoundTrip) {
  using S = TypeParam;
  for (const auto& m : sample_motions(1)) {
    const DualQuat<S> Q = dq<S>(m);
    EXPECT_LE((Q.translation() - m.t.cast<S>()).norm(), tol<S>() * 10);
    EXPECT_LE(Q.rotation().angularDistance(m.q.cast<S>()), tol<S>() * 10);
  }
}

TYPED_TEST(DualQuatTest, TransformPointEqualsRotationMatrixPlusTranslation) {
  using S = TypeParam;
  std::mt19937 rng(2);
  std::normal_distribution<double> g(0.0, 2.0);
  for (const auto& m : sample_motions(3)) {
    const Eigen::Vector3d x(g(rng), g(rng), g(rng));
    const Eigen::Vector3d expect = m.q.toRotationMatrix() * x + m.t;
    const Vec3<S> got = transform_point(dq<S>(m), Vec3<S>(x.cast<S>()));
    EXPECT_LE((got.template cast<double>() - expect).norm(), 40 * double(tol<S>()) * (1 + expect.norm()));
  }
}

TYPED_TEST(DualQuatTest, CompositionEqualsSe3Composition) {
  using S = TypeParam;
  const auto a = sample_motions(4), b = sample_motions(5);
  std::mt19937 rng(6);
  std::normal_distribution<double> g(0.0, 2.0);
  for (size_t i = 0; i < a.size(); ++i) {
    Eigen::Isometry3d Ta = Eigen::Isometry3d::Identity(), Tb = Eigen::Isometry3d::Identity();
    Ta.linear() = a[i].q.toRotationMatrix();
    Ta.translation() = a[i].t;
    Tb.linear() = b[i].q.toRotationMatrix();
    Tb.translation() = b[i].t;
    const Eigen::Vector3d x(g(rng), g(rng), g(rng));
    const Eigen::Vector3d expect = Ta * (Tb * x);
    const DualQuat<S> Qab = dq<S>(a[i]) * dq<S>(b[i]);
    const Vec3<S> got = transform_point(Qab, Vec3<S>(x.cast<S>()));
    EXPECT_LE((got.template cast<double>() - expect).norm(), 80 * double(tol<S>()) * (1 + expect.norm()));
    EXPECT_LE((Qab.translation().template cast<double>() - (Ta * Tb).translation()).norm(),
              80 * double(tol<S>()) * (1 + expect.norm()));
  }
}

TYPED_TEST(DualQuatTest, ConjugateIsInverse) {
  using S = TypeParam;
  for (const auto& m : sample_motions(7)) {
    const DualQuat<S> Q = dq<S>(m);
    const DualQuat<S> I = Q * inverse(Q);
    EXPECT_LE((to_wxyz8(I) - to_wxyz8(DualQuat<S>::identity())).norm(), 20 * tol<S>() * (1 + S(m.t.norm())));
  }
}

TYPED_TEST(DualQuatTest, TransformLineEqualsPlueckerOfTransformedPoints) {
  using S = TypeParam;
  std::mt19937 rng(8);
  std::normal_distribution<double> g(0.0, 2.0);
  for (const auto& m : sample_motions(9)) {
    const Eigen::Vector3d p(g(rng), g(rng), g(rng));
    const Eigen::Vector3d l = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    const Eigen::Vector3d mom = p.cross(l);
    const Eigen::Vector3d p2 = m.q * p + m.t;
    const Eigen::Vector3d l2 = m.q * l;
    Vec3<S> lo, mo;
    transform_line(dq<S>(m), Vec3<S>(l.cast<S>()), Vec3<S>(mom.cast<S>()), lo, mo);
    EXPECT_LE((lo.template cast<double>() - l2).norm(), 20 * double(tol<S>()));
    EXPECT_LE((mo.template cast<double>() - p2.cross(l2)).norm(), 80 * double(tol<S>()) * (1 + p2.norm()));
  }
}

TYPED_TEST(DualQuatTest, ZeroPitchScrewRotatesAboutTheLine) {
  using S = TypeParam;
  std::mt19937 rng(10);
  std::normal_distribution<double> g(0.0, 2.0);
  for (int k = 0; k < 50; ++k) {
    const Eigen::Vector3d p(g(rng), g(rng), g(rng));
    const Eigen::Vector3d l = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    const double phi = g(rng) * 2.0;
    const Eigen::Vector3d x(g(rng), g(rng), g(rng));
    const Eigen::Vector3d expect = p + Eigen::AngleAxisd(phi, l) * (x - p);  // Rodrigues about the line
    const DualQuat<S> Q = DualQuat<S>::from_screw_zero_pitch(l.cast<S>(), p.cross(l).cast<S>(), S(phi));
    const Vec3<S> got = transform_point(Q, Vec3<S>(x.cast<S>()));
    EXPECT_LE((got.template cast<double>() - expect).norm(), 80 * double(tol<S>()) * (1 + expect.norm()));
  }
}

TYPED_TEST(DualQuatTest, LogOfExpIsIdentity) {
  using S = TypeParam;
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  const double mags[] = {0.0, 1e-8, 1e-4, 5e-3, 0.3, 1.5, 3.0};
  for (int k = 0; k < 70; ++k) {
    Eigen::Matrix<double, 6, 1> xi;
    for (int i = 0; i < 6; ++i) xi(i) = g(rng);
    xi.head<3>() = xi.head<3>().normalized() * mags[k % 7];
    const Eigen::Matrix<S, 6, 1> back = fsw::log(fsw::exp(Eigen::Matrix<S, 6, 1>(xi.cast<S>())));
    EXPECT_LE((back.template cast<double>() - xi).norm(), 200 * double(tol<S>()) * (1 + xi.norm())) << xi.transpose();
  }
}

TYPED_TEST(DualQuatTest, ExpOfRotationFreeTwistIsTranslation) {
  using S = TypeParam;
  Eigen::Matrix<S, 6, 1> xi;
  xi << S(0), S(0), S(0), S(1), S(-2), S(3);
  const DualQuat<S> Q = fsw::exp(xi);
  EXPECT_LE((Q.translation() - Vec3<S>(S(1), S(-2), S(3))).norm(), 10 * tol<S>());
  EXPECT_NEAR(Q.real.w(), S(1), tol<S>());
}

TYPED_TEST(DualQuatTest, NormalizedRestoresUnitAndOrthogonality) {
  using S = TypeParam;
  for (const auto& m : sample_motions(12)) {
    DualQuat<S> Q = dq<S>(m);
    Q.real.coeffs() *= S(1.01);  // a scalar multiple of a unit Q, plus a dual part along r
    Q.dual.coeffs() *= S(1.01);
    Q.dual.coeffs() += S(1e-3) * Q.real.coeffs();
    const DualQuat<S> N = normalized(Q);
    EXPECT_NEAR(N.real.norm(), S(1), 10 * tol<S>());
    EXPECT_NEAR(N.real.coeffs().dot(N.dual.coeffs()), S(0), 100 * tol<S>() * (1 + S(m.t.norm())));
    EXPECT_GE(N.real.w(), S(0));
    EXPECT_LE((N.translation() - m.t.template cast<S>()).norm(), S(200) * tol<S>() * (1 + S(m.t.norm())));
  }
}

TYPED_TEST(DualQuatTest, WxyzBoundaryIsScalarFirst) {
  using S = TypeParam;
  const DualQuat<S> Q =
      DualQuat<S>::from_rotation_translation(Quat<S>(S(0.5), S(0.5), S(0.5), S(0.5)), Vec3<S>(S(1), S(0), S(0)));
  const Vec8<S> v = to_wxyz8(Q);
  EXPECT_EQ(v(0), S(0.5));
  const DualQuat<S> back = from_wxyz8(v);
  EXPECT_EQ((to_wxyz8(back) - v).norm(), S(0));
}

// -Q is the same motion as Q: normalized() returns the representative with a
// non-negative scalar part and the same translation; all_finite() sees a NaN
// in either part.
TYPED_TEST(DualQuatTest, NormalizedTakesTheNonNegativeScalarHemisphere) {
  using S = TypeParam;
  for (const auto& m : sample_motions(13, 12)) {
    const DualQuat<S> Q = dq<S>(m);
    DualQuat<S> neg = Q;
    neg.real.coeffs() = -neg.real.coeffs();
    neg.dual.coeffs() = -neg.dual.coeffs();
    if (Q.real.w() == S(0)) continue;  // both representatives on the boundary
    const DualQuat<S> N = normalized(neg);
    EXPECT_GT(N.real.w(), S(0));
    EXPECT_LE((N.real.coeffs() - Q.real.coeffs()).norm(), 10 * tol<S>());
    EXPECT_LE((N.translation() - m.t.template cast<S>()).norm(), S(200) * tol<S>() * (1 + S(m.t.norm())));
    EXPECT_TRUE(N.all_finite());
  }
  DualQuat<S> bad = DualQuat<S>::identity();
  EXPECT_TRUE(bad.all_finite());
  bad.dual.x() = std::numeric_limits<S>::quiet_NaN();
  EXPECT_FALSE(bad.all_finite());
  bad = DualQuat<S>::identity();
  bad.real.w() = std::numeric_limits<S>::infinity();
  EXPECT_FALSE(bad.all_finite());
}
