// CW propagation and quaternion operations, double and float.
#include <benchmark/benchmark.h>

#include "fsw/dynamics/cw.hpp"
#include "fsw/dynamics/hill_attitude.hpp"
#include "fsw/math/so3.hpp"

using namespace fsw;

template <typename S>
static void BM_CwStepWithAccel(benchmark::State& st) {
  const S n = orbit_rate<S>(S(kEarthRadius + 500e3));
  const CwPropagator<S> prop(n, S(0.1));
  Vec6<S> x = Vec6<S>::Constant(S(0.1));
  const Vec3<S> a(S(1e-3), S(-2e-3), S(5e-4));
  for (auto _ : st) {
    x = prop.step(x, a);
    benchmark::DoNotOptimize(x.data());
    benchmark::ClobberMemory();
  }
}
BENCHMARK_TEMPLATE(BM_CwStepWithAccel, double);
BENCHMARK_TEMPLATE(BM_CwStepWithAccel, float);

template <typename S>
static void BM_CwStmClosedForm(benchmark::State& st) {
  const S n = orbit_rate<S>(S(kEarthRadius + 500e3));
  S t = S(0.1);
  for (auto _ : st) {
    benchmark::DoNotOptimize(t);
    Mat6<S> phi = cw_stm(n, t);
    benchmark::DoNotOptimize(phi.data());
  }
}
BENCHMARK_TEMPLATE(BM_CwStmClosedForm, double);
BENCHMARK_TEMPLATE(BM_CwStmClosedForm, float);

template <typename S>
static void BM_So3Exp(benchmark::State& st) {
  Vec3<S> v(S(0.1), S(-0.2), S(0.3));
  for (auto _ : st) {
    benchmark::DoNotOptimize(v.data());
    Quat<S> q = fsw::exp(v);
    benchmark::DoNotOptimize(q.coeffs().data());
  }
}
BENCHMARK_TEMPLATE(BM_So3Exp, double);
BENCHMARK_TEMPLATE(BM_So3Exp, float);

template <typename S>
static void BM_So3Log(benchmark::State& st) {
  Quat<S> q = fsw::exp(Vec3<S>(S(0.1), S(-0.2), S(0.3)));
  for (auto _ : st) {
    benchmark::DoNotOptimize(q.coeffs().data());
    Vec3<S> v = fsw::log(q);
    benchmark::DoNotOptimize(v.data());
  }
}
BENCHMARK_TEMPLATE(BM_So3Log, double);
BENCHMARK_TEMPLATE(BM_So3Log, float);

template <typename S>
static void BM_Boxplus(benchmark::State& st) {
  Quat<S> q = fsw::exp(Vec3<S>(S(0.1), S(-0.2), S(0.3)));
  const Vec3<S> d(S(1e-3), S(2e-3), S(-1e-3));
  for (auto _ : st) {
    q = boxplus(q, d);
    benchmark::DoNotOptimize(q.coeffs().data());
  }
}
BENCHMARK_TEMPLATE(BM_Boxplus, double);
BENCHMARK_TEMPLATE(BM_Boxplus, float);

template <typename S>
static void BM_Boxminus(benchmark::State& st) {
  const Quat<S> q0 = fsw::exp(Vec3<S>(S(0.1), S(-0.2), S(0.3)));
  Quat<S> q1 = fsw::exp(Vec3<S>(S(0.11), S(-0.19), S(0.31)));
  for (auto _ : st) {
    benchmark::DoNotOptimize(q1.coeffs().data());
    Vec3<S> d = boxminus(q1, q0);
    benchmark::DoNotOptimize(d.data());
  }
}
BENCHMARK_TEMPLATE(BM_Boxminus, double);
BENCHMARK_TEMPLATE(BM_Boxminus, float);

template <typename S>
static void BM_PropagateAttitude(benchmark::State& st) {
  const S n = orbit_rate<S>(S(kEarthRadius + 500e3));
  const Quat<S> hill = hill_frame_step(n, S(0.1));
  Quat<S> q = Quat<S>::Identity();
  const Vec3<S> w(S(0.01), S(0.02), S(-0.01));
  for (auto _ : st) {
    q = propagate_attitude(q, w, S(0.1), hill);
    benchmark::DoNotOptimize(q.coeffs().data());
  }
}
BENCHMARK_TEMPLATE(BM_PropagateAttitude, double);
BENCHMARK_TEMPLATE(BM_PropagateAttitude, float);
