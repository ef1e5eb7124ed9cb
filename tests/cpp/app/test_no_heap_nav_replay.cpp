// The log replay (fsw/app/nav_replay.hpp) allocates nothing: a whole log
// with a run start (a fresh filter), late and gated poses and a lost IMU
// tick, float and double. Built with EIGEN_RUNTIME_NO_MALLOC.
#include <gtest/gtest.h>

#include <memory>

#include "fsw/app/nav_replay.hpp"
#include "nav_replay_util.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;
using namespace nav_replay_test;

namespace {

template <typename S>
void replay_without_heap() {
  NavConfig<S> cfg;
  cfg.gate_chi2 = S(22.46);
  const Log<S> log;
  Result<S> out(log);
  const NavReplayLog<S> in = log.view();
  const NavReplayOutput<S> o = out.view();
  auto rep = std::make_unique<NavReplay<S>>(cfg);  // construction may allocate (heap-held, as in the bindings)
  NavReplaySummary s;
  {
    NoHeapGuard guard;
    s = rep->run(in, o);
    EXPECT_EQ(guard.allocations(), 0);
  }
  EXPECT_TRUE(s.ok());
  EXPECT_EQ(s.poses_fused, 5);
}

}  // namespace

TEST(NoHeapNavReplayTest, Double) { replay_without_heap<double>(); }
TEST(NoHeapNavReplayTest, Float) { replay_without_heap<float>(); }
