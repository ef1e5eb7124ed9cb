// Built with EIGEN_RUNTIME_NO_MALLOC (CMakeLists.txt): Eigen aborts on any
// allocation while it is forbidden, and the global operator new below counts
// every other heap allocation. Each step function runs inside a guard that
// forbids both.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "fsw/cw.hpp"
#include "fsw/hill_attitude.hpp"
#include "fsw/so3.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;

TEST(NoHeapTest, GuardDetectsAnAllocation) {
  // The detector itself must work, or every other test here means nothing.
  NoHeapGuard guard(/*eigen_forbid=*/false);
  static int* volatile sink = nullptr;  // escapes, so the pair cannot be elided
  sink = new int(3);
  delete sink;
  EXPECT_GE(guard.allocations(), 1);
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
