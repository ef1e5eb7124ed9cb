// Thruster learner timing: 9 inputs (8 valves + bias), 6 outputs, window 30,
// double and float. "AddRemove" is one add to a full window (one add and one
// eviction). "PredictThenAdd" is the learner's per-sample step: a prediction
// right after the window changed (Cholesky of A, C = L^-1 B, noise estimate,
// then the prediction), then the add; the cost of a prediction after a window
// change is PredictThenAdd - AddRemove (timing pauses cost more than the
// step). "PredictCached" is a further prediction on an unchanged window.
#include <benchmark/benchmark.h>

#include <cstdint>
#include <random>

#include "fsw/thrusters/blr.hpp"

namespace {

constexpr int kTable = 1024;

template <typename S>
struct Data {
  Eigen::Matrix<S, 9, kTable> x;
  Eigen::Matrix<S, 6, kTable> y;
  Data() {
    std::mt19937_64 rng(11);
    std::normal_distribution<double> nd;
    std::uint8_t mask = 0;
    for (int i = 0; i < kTable; ++i) {
      mask ^= std::uint8_t(1u << (rng() % 8));
      x.col(i) = fsw::ValveFeatures<S>::from_mask(mask);
      for (int j = 0; j < 6; ++j) y(j, i) = S(1e-3 * nd(rng));
    }
  }
};

template <typename S>
void BM_AddRemove(benchmark::State& state) {
  static const Data<S> d;
  fsw::ThrusterBlr<S, 30> blr;
  for (int i = 0; i < 30; ++i) blr.add(d.x.col(i), d.y.col(i));
  int i = 0;
  for (auto _ : state) {
    auto rec = blr.add(d.x.col(i), d.y.col(i));
    benchmark::DoNotOptimize(rec);
    i = (i + 1) & (kTable - 1);
  }
}

template <typename S>
void BM_PredictCached(benchmark::State& state) {
  static const Data<S> d;
  fsw::ThrusterBlr<S, 30> blr;
  for (int i = 0; i < 30; ++i) blr.add(d.x.col(i), d.y.col(i));
  blr.refresh_posterior();
  int i = 0;
  for (auto _ : state) {
    auto p = blr.predict(d.x.col(i));
    benchmark::DoNotOptimize(p);
    i = (i + 1) & (kTable - 1);
  }
}

// The full per-sample step of the learner: predict before the sample, then add it.
template <typename S>
void BM_PredictThenAdd(benchmark::State& state) {
  static const Data<S> d;
  fsw::ThrusterBlr<S, 30> blr;
  for (int i = 0; i < 30; ++i) blr.add(d.x.col(i), d.y.col(i));
  int i = 0;
  for (auto _ : state) {
    auto p = blr.predict(d.x.col(i));
    benchmark::DoNotOptimize(p);
    auto rec = blr.add(d.x.col(i), d.y.col(i));
    benchmark::DoNotOptimize(rec);
    i = (i + 1) & (kTable - 1);
  }
}

}  // namespace

BENCHMARK_TEMPLATE(BM_AddRemove, double);
BENCHMARK_TEMPLATE(BM_AddRemove, float);
BENCHMARK_TEMPLATE(BM_PredictCached, double);
BENCHMARK_TEMPLATE(BM_PredictCached, float);
BENCHMARK_TEMPLATE(BM_PredictThenAdd, double);
BENCHMARK_TEMPLATE(BM_PredictThenAdd, float);
