// The navigation filter's step functions allocate nothing: predict, on-time
// and delayed pose updates (with replay), gated and rejected inputs, in
// float and double, 9 and 15 states. Built with EIGEN_RUNTIME_NO_MALLOC.
#include <gtest/gtest.h>

#include <limits>
#include <memory>

#include "fsw/nav/nav_ukf.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;

namespace {

template <typename S, bool B>
void run_without_heap() {
  // Construction may allocate (here: a heap-held filter, as in the bindings).
  auto f = std::make_unique<NavUkf<S, B>>(NavConfig<S>());
  ASSERT_TRUE(f->config_ok());
  typename NavUkf<S, B>::State x;
  x.r_hill_m = Vec3<S>(S(0.75), S(0), S(0));
  typename NavUkf<S, B>::Cov P0 = NavUkf<S, B>::Cov::Identity() * S(1e-3);
  Eigen::Matrix<S, 6, 6> R = Eigen::Matrix<S, 6, 6>::Identity() * S(1e-3);
  const Vec3<S> a(S(1e-3), S(0), S(-1e-3));
  const Vec3<S> w(S(0.01), S(0.02), S(-0.01));
  int ok = 0, rejected = 0;
  {
    NoHeapGuard guard;
    ok += f->init(0.0, x, P0).ok();
    for (int k = 1; k <= 10; ++k) ok += f->predict(0.1 * k, a, w).ok();
    ok += f->update_pose(1.0, f->state().r_hill_m, f->state().q_hb, R).ok();  // on time
    for (int k = 11; k <= 15; ++k) ok += f->predict(0.1 * k, a, w).ok();
    ok += f->update_pose(1.2, f->state().r_hill_m, f->state().q_hb, R).ok();  // 0.3 s late, 3 replays
    const Vec3<S> far = f->state().r_hill_m + Vec3<S>(S(10), S(0), S(0));
    rejected += f->update_pose(1.5, far, f->state().q_hb, R).status == StepStatus::Gated;
    Vec3<S> bad = a;
    bad(1) = std::numeric_limits<S>::quiet_NaN();
    rejected += f->predict(1.6, bad, w).status == StepStatus::BadInput;
    rejected += f->update_pose(0.1, f->state().r_hill_m, f->state().q_hb, R).status == StepStatus::BadInput;
    ok += f->predict(1.9, a, w).ok();                                         // 1.6 to 1.8 lost: three ticks bridged
    ok += f->update_pose(1.7, f->state().r_hill_m, f->state().q_hb, R).ok();  // captured at a bridged tick
    ok += f->predict(21.9, a, w).ok();                                        // a 20 s outage coasted through
    EXPECT_EQ(guard.allocations(), 0);
  }
  EXPECT_EQ(ok, 1 + 10 + 1 + 5 + 1 + 3);
  EXPECT_EQ(rejected, 3);
}

}  // namespace

TEST(NoHeapNavTest, NineStatesDouble) { run_without_heap<double, false>(); }
TEST(NoHeapNavTest, NineStatesFloat) { run_without_heap<float, false>(); }
TEST(NoHeapNavTest, FifteenStatesDouble) { run_without_heap<double, true>(); }
TEST(NoHeapNavTest, FifteenStatesFloat) { run_without_heap<float, true>(); }
