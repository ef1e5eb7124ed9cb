// Built with EIGEN_RUNTIME_NO_MALLOC (CMakeLists.txt). no_heap_guard.hpp
// counts every allocation in the process while a guard is alive (the
// executable interposes malloc), and Eigen code compiled here aborts on one.
// Each step function runs inside a guard.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cstdlib>
#include <cstring>
#include <string>

#include "fsw/dynamics/cw.hpp"
#include "fsw/dynamics/hill_attitude.hpp"
#include "fsw/math/so3.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;

// The detector itself must work, or every other no-heap test means nothing.
// The flight code it guards is compiled in fsw_core, not in the test, so it
// must see allocations made outside the test's own code.
TEST(NoHeapTest, GuardCountsOperatorNew) {
  NoHeapGuard guard(/*eigen_forbid=*/false);
  static int* volatile sink = nullptr;  // escapes, so the pair cannot be elided
  sink = new int(3);
  delete sink;
  EXPECT_GE(guard.allocations(), 1);
}

TEST(NoHeapTest, GuardCountsAllocationsInsideOtherLibraries) {
  static const char* volatile text = "an allocation made by the C library";
  long by_libc = 0, by_libstdcxx = 0;
  {
    NoHeapGuard guard(/*eigen_forbid=*/false);
    char* copy = strdup(text);  // malloc called from inside libc
    by_libc = guard.allocations();
    std::free(copy);
  }
  {
    NoHeapGuard guard(/*eigen_forbid=*/false);
    std::string s(200, 'x');  // operator new in libstdc++, then malloc
    by_libstdcxx = guard.allocations();
    EXPECT_EQ(s.size(), 200u);
  }
  EXPECT_GE(by_libc, 1);
  EXPECT_GE(by_libstdcxx, 1);
}

TEST(NoHeapTest, GuardCountsEigenAlignedAllocations) {
  NoHeapGuard guard(/*eigen_forbid=*/false);
  Eigen::MatrixXd m = Eigen::MatrixXd::Identity(64, 64);  // Eigen's aligned_malloc
  EXPECT_GE(guard.allocations(), 1);
  EXPECT_EQ(m.trace(), 64.0);
}

TEST(NoHeapTest, GuardCountsNothingWithoutAllocation) {
  NoHeapGuard guard;
  Eigen::Matrix<double, 15, 15> a = Eigen::Matrix<double, 15, 15>::Identity();
  const Eigen::Matrix<double, 15, 15> b = a * a.transpose() + a;
  EXPECT_EQ(guard.allocations(), 0);
  EXPECT_EQ(b.trace(), 30.0);
}

template <typename S>
void propagate_without_heap() {
  const S n = orbit_rate<S>(S(kEarthRadius + 500e3));
  CwPropagator<S> prop(n, S(0.1));
  Vec6<S> x = Vec6<S>::Constant(S(0.1));
  const Vec3<S> a(S(1e-3), S(0), S(-1e-3));
  Quat<S> q = Quat<S>::Identity();
  const Vec3<S> w(S(0.01), S(0.02), S(-0.01));
  NoHeapGuard guard;
  for (int k = 0; k < 100; ++k) {
    x = prop.step(x, a);
    q = propagate_attitude(q, w, n, S(0.1));
    const Vec3<S> d = boxminus(boxplus(q, w), q);
    x(0) += d(0) * S(0);
  }
  const Mat6<S> phi = cw_stm(n, S(1));
  const Mat63<S> gam = cw_accel_response(n, S(1));
  x = phi * x + gam * a;
  EXPECT_EQ(guard.allocations(), 0);
  EXPECT_TRUE(x.allFinite());
}

TEST(NoHeapTest, CwAndAttitudeStepsDouble) { propagate_without_heap<double>(); }
TEST(NoHeapTest, CwAndAttitudeStepsFloat) { propagate_without_heap<float>(); }
