// Cost of the modal frequency acquisition on board: storing one image (the
// information of its coarse covariance), the search over the stored history
// (grid start plus 3 RELAX cycles, 201-point grids), and the replay of the
// joint filter over that history. 10 and 50 modes, float and double, at the
// image counts of two lowest-mode periods in the bench's runs (80 images at
// 10 modes, 241 at 50).
//
//   build/cpp/bench_modal_acquisition --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <random>

#include "fsw/modal/modal_acquisition.hpp"

using namespace fsw;

namespace {

constexpr int kH = 256;

// Coarse amplitudes of undamped modes with a random, well-conditioned
// covariance per image (as the points seen change).
template <typename S, int M>
struct History {
  std::unique_ptr<ModalAcquisition<S, M, kH>> acq;
  std::unique_ptr<ModalDecompositionRecord<S, M>[]> recs;
  ModalFilterConfig<S, M> cfg;
  int n;
  explicit History(int n_images) : recs(new ModalDecompositionRecord<S, M>[n_images]), n(n_images) {
    std::mt19937 rng(5);
    std::normal_distribution<double> g(0.0, 1.0);
    ModalAcquisitionConfig<S, M> ac;
    for (int i = 0; i < M; ++i) {
      const double w = 0.0026 * (1 + i);
      ac.omega_prior_radps[i] = S(w * 1.05);
      ac.sigma_omega_radps[i] = S(0.105 * w);
      cfg.mode[i].omega_radps = S(w);
      cfg.mode[i].sigma_v0_ps = S(w);
      cfg.mode[i].sigma_alpha0_ps = S(1e-6);
    }
    acq = std::make_unique<ModalAcquisition<S, M, kH>>(ac);
    for (int k = 0; k < n; ++k) {
      Eigen::Matrix<double, M, M> A;
      for (int r = 0; r < M; ++r)
        for (int c = 0; c < M; ++c) A(r, c) = (r == c ? 0.3 : 0.0) + 0.02 * g(rng);
      const Eigen::Matrix<double, M, M> cov = A * A.transpose();
      Eigen::Matrix<double, M, 1> a;
      for (int i = 0; i < M; ++i) a(i) = 0.5 * std::cos(0.0026 * (1 + i) * 20.0 * k + i) + 0.3 * g(rng);
      recs[k].status = ModalStatus::Ok;
      recs[k].a_coarse = a.template cast<S>();
      recs[k].cov_a = cov.template cast<S>();
      acq->add(S(20.0 * k), recs[k]);
    }
  }
};

template <typename S, int M>
void BM_AcquisitionAdd(benchmark::State& state) {
  History<S, M> h(kH);
  int k = 0;
  for (auto _ : state) {
    if (h.acq->images() == kH) {
      state.PauseTiming();
      h.acq->reset(h.acq->config());
      k = 0;
      state.ResumeTiming();
    }
    benchmark::DoNotOptimize(h.acq->add(S(20.0 * k), h.recs[k]));
    ++k;
  }
}

template <typename S, int M>
void BM_AcquisitionSearch(benchmark::State& state) {
  History<S, M> h(static_cast<int>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(h.acq->search());
  state.counters["images"] = h.acq->images();
}

template <typename S, int M>
void BM_AcquisitionReplayJoint(benchmark::State& state) {
  History<S, M> h(static_cast<int>(state.range(0)));
  h.acq->search();
  auto filter = std::make_unique<ModalUkfJoint<S, M>>(h.cfg);
  typename ModalUkfJoint<S, M>::Record rec;
  h.acq->apply(h.cfg, S(0.01));
  for (auto _ : state) benchmark::DoNotOptimize(h.acq->replay_into(*filter, h.cfg, rec));
}

}  // namespace

BENCHMARK_TEMPLATE(BM_AcquisitionAdd, double, 10)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_AcquisitionAdd, double, 50)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_AcquisitionAdd, float, 50)->Unit(benchmark::kMicrosecond);
BENCHMARK_TEMPLATE(BM_AcquisitionSearch, double, 10)->Arg(80)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_AcquisitionSearch, float, 10)->Arg(80)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_AcquisitionSearch, double, 50)->Arg(241)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_AcquisitionSearch, float, 50)->Arg(241)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_AcquisitionReplayJoint, double, 10)->Arg(80)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_AcquisitionReplayJoint, double, 50)->Arg(241)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_AcquisitionReplayJoint, float, 50)->Arg(241)->Unit(benchmark::kMillisecond);
