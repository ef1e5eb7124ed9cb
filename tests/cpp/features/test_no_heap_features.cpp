// The feature filters' step functions allocate nothing: init, predict,
// update (EKF and UKF, float and double), rejected and masked inputs.
// Built with EIGEN_RUNTIME_NO_MALLOC.
#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <type_traits>

#include "feature_scenario.hpp"
#include "no_heap_guard.hpp"

using namespace fsw;
using namespace feature_scenario;

namespace {
template <typename Filter, typename S>
void run_without_heap() {
  // Construction may allocate (a heap-held filter, as in the bindings).
  auto cfg = config<S>();
  auto f = std::make_unique<Filter>(cfg, features<S>());
  ASSERT_TRUE(f->config_ok());
  auto truth = truth0<double>();
  double nu = 0.0;
  std::mt19937 rng(5);
  typename Filter::MeasVec z[6];
  for (int k = 0; k < 6; ++k) {
    truth_step<double>(truth, nu, 1.0);
    z[k] = measure<double>(truth, features<double>(), rng).template cast<S>();
  }
  auto x0 = truth0<S>();
  x0.r_l_m += Vec3<S>(S(0.3), S(-0.2), S(0.3));
  const auto P = P0<S>(S(0.5), S(0.01));
  int ok = 0, rejected = 0;
  {
    NoHeapGuard guard;
    ok += f->init(0.0, S(0), x0, P).ok();
    for (int k = 1; k <= 5; ++k) {
      ok += f->predict(double(k)).ok();
      ok += f->update(z[k - 1]).ok();
    }
    typename Filter::MeasVec bad = z[5];
    bad(4) = std::numeric_limits<S>::quiet_NaN();
    rejected += f->update(bad).status == StepStatus::BadInput;
    rejected += f->predict(1.0).status == StepStatus::BadInput;
    ok += f->update(bad, Filter::kAllSlots & ~(1u << 2)).ok();  // the NaN slot unmeasured
    EXPECT_EQ(guard.allocations(), 0);
  }
  EXPECT_EQ(ok, 1 + 10 + 1);
  EXPECT_EQ(rejected, 2);
}
}  // namespace

TEST(NoHeapFeaturesTest, EkfDouble) { run_without_heap<Ekf<double>, double>(); }
TEST(NoHeapFeaturesTest, EkfFloat) { run_without_heap<Ekf<float>, float>(); }
TEST(NoHeapFeaturesTest, UkfDouble) { run_without_heap<Ukf<double>, double>(); }
TEST(NoHeapFeaturesTest, UkfFloat) { run_without_heap<Ukf<float>, float>(); }
