// The thruster learner's step functions (add, remove, refresh, predict) run
// under a guard that aborts on any Eigen allocation and counts every other
// heap allocation (EIGEN_RUNTIME_NO_MALLOC build).
#include <gtest/gtest.h>

#include <limits>

#include "fsw/thrusters/blr.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;

namespace {
template <typename Blr>
void learn_without_heap() {
  using S = typename Blr::VecX::Scalar;
  using Feat = ValveFeatures<S, (Blr::kInputs > 9)>;
  static Blr blr;  // constructed before the guard; the steps must not allocate
  blr.reset();
  typename Blr::VecY y;
  NoHeapGuard guard;
  std::uint8_t mask = 1;
  S sum = S(0);
  for (int k = 0; k < 500; ++k) {
    mask = std::uint8_t(mask * 37u + 11u);
    for (int j = 0; j < Blr::kOutputs; ++j) y(j) = S(0.01) * S((k + j) % 7);
    const auto rec = blr.add(Feat::from_mask(mask), y);
    EXPECT_TRUE(rec.entered);
    if (k % 13 == 0) blr.remove_oldest();
    const auto p = blr.predict(Feat::from_mask(std::uint8_t(mask ^ 0x5A)));
    sum += p.mean(0) + p.variance(0);
  }
  y(0) = std::numeric_limits<S>::quiet_NaN();
  EXPECT_EQ(blr.add(Feat::from_mask(3), y).status, BlrStatus::BadInput);
  EXPECT_EQ(guard.allocations(), 0);
  EXPECT_TRUE(std::isfinite(double(sum)));
}
}  // namespace

TEST(NoHeapBlr, ValvesDouble) { learn_without_heap<ThrusterBlr<double, 30>>(); }
TEST(NoHeapBlr, ValvesFloat) { learn_without_heap<ThrusterBlr<float, 30>>(); }
TEST(NoHeapBlr, ValvePairsDouble) { learn_without_heap<ThrusterBlrPairs<double, 30>>(); }
TEST(NoHeapBlr, ValvePairsFloat) { learn_without_heap<ThrusterBlrPairs<float, 30>>(); }
