// The flight app's range-image path: one 900-point plate image as 38
// range_image_segment frames through on_bytes (deframe, decode, mode shapes
// per point, streaming decomposition, joint modal step, tm_modal out),
// beside the same decomposition and joint step called directly with
// precomputed mode shapes (the library alone).
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "fsw/app/flight_app.hpp"
#include "fsw/link/framer.hpp"
#include "fsw/modal/modal_decomposition.hpp"
#include "fsw/modal/modal_tracker.hpp"
#include "fsw/modal/modal_ukf.hpp"
#include "fsw/modal/plate_modes.hpp"

using namespace fsw;

namespace {

constexpr int kM = 10;
constexpr int kSide = 30;

struct Image {
  std::vector<Vec3<double>> p;
  double sigma = 18.0;
};

Image make_image(std::mt19937_64& rng, double t) {
  PlateModes<double, kM> model;
  std::normal_distribution<double> nd(0.0, 1.0);
  Image im;
  double phi[kM] = {};
  for (int r = 0; r < kSide; ++r)
    for (int c = 0; c < kSide; ++c) {
      const double x = 2000.0 * (0.25 + 0.5 * (c + 0.5) / kSide), y = 1732.0 * (0.25 + 0.5 * (r + 0.5) / kSide);
      model.phi(x, y, phi);
      double z = 0.0;
      for (int i = 0; i < kM; ++i) z += 0.5 * std::sin(model.omega_radps(i) * t + i) * phi[i];
      im.p.emplace_back(x, y, z + im.sigma * nd(rng));
    }
  return im;
}

// Frames of one image (image_id k, time t).
std::vector<std::uint8_t> frames(Framer& fr, const Image& im, std::uint32_t k, double t) {
  std::vector<std::uint8_t> out;
  const std::size_t n = im.p.size(), n_seg = (n + kRangePointsPerSegment - 1) / kRangePointsPerSegment;
  for (std::size_t s = 0; s < n_seg; ++s) {
    RangeImageSegmentMsg<double> m;
    m.image_id = k;
    m.points_total = std::uint16_t(n);
    m.first_point = std::uint16_t(s * kRangePointsPerSegment);
    m.n_points = std::uint16_t(std::min(kRangePointsPerSegment, n - s * kRangePointsPerSegment));
    for (std::size_t j = 0; j < m.n_points; ++j) {
      m.points[j].p_m = im.p[s * kRangePointsPerSegment + j];
      m.points[j].sigma_m = im.sigma;
    }
    const SeqFlags f = s == 0 ? SeqFlags::First : s + 1 == n_seg ? SeqFlags::Last : SeqFlags::Continuation;
    std::uint8_t buf[kMaxFrameBytes];
    const std::size_t nb = fr.frame_message(Apid::RangeImageSegment, m, t, buf, sizeof(buf), f);
    out.insert(out.end(), buf, buf + nb);
  }
  return out;
}

// Images 0..n-1 a minute apart, framed once; the app is rebuilt (untimed)
// when they run out so every timed image is a regular step.
void BM_FlightAppRangeImage(benchmark::State& st) {
  std::mt19937_64 rng(1);
  constexpr int kImages = 64;
  Framer fr(Direction::ToFlight);
  std::vector<std::vector<std::uint8_t>> bytes;
  for (int k = 0; k < kImages; ++k) bytes.push_back(frames(fr, make_image(rng, 60.0 * k), std::uint32_t(k), 60.0 * k));
  auto app = std::make_unique<FlightApp<double>>();
  std::uint8_t out[4096];
  int k = 0;
  for (auto _ : st) {
    if (k == kImages) {
      st.PauseTiming();
      app = std::make_unique<FlightApp<double>>();
      k = 0;
      st.ResumeTiming();
    }
    app->on_bytes(bytes[std::size_t(k)].data(), bytes[std::size_t(k)].size());
    while (app->tx_pending() > 0) app->take_tx(out, sizeof(out));
    ++k;
  }
  st.SetLabel("900 points, 38 frames, 10 modes, joint");
}
BENCHMARK(BM_FlightAppRangeImage)->Unit(benchmark::kMicrosecond);

void BM_LibraryRangeImage(benchmark::State& st) {
  std::mt19937_64 rng(1);
  constexpr int kImages = 64;
  PlateModes<double, kM> model;
  std::vector<std::vector<double>> phi(kImages), z(kImages);
  for (int k = 0; k < kImages; ++k) {
    const Image im = make_image(rng, 60.0 * k);
    double row[kM];
    for (const auto& p : im.p) {
      model.phi(p.x(), p.y(), row);
      phi[std::size_t(k)].insert(phi[std::size_t(k)].end(), row, row + kM);
      z[std::size_t(k)].push_back(p.z());
    }
  }
  const auto cfg = ModalTracker<double, kM>::filter_config(model, ModalTrackerConfig());
  auto filt = std::make_unique<ModalUkfJoint<double, kM>>(cfg);
  ModalDecomposition<double, kM> dec;
  ModalDecompositionRecord<double, kM> drec;
  ModalStepRecord<double, kM> srec;
  const double var = 18.0 * 18.0;
  int k = 0;
  for (auto _ : st) {
    if (k == kImages) {
      st.PauseTiming();
      filt->reset(cfg);
      k = 0;
      st.ResumeTiming();
    }
    dec.reset();
    const auto& ph = phi[std::size_t(k)];
    for (std::size_t j = 0; j < z[std::size_t(k)].size(); ++j)
      dec.add_point(ph.data() + j * kM, z[std::size_t(k)][j], var);
    dec.solve(drec);
    filt->step(60.0, drec, srec);
    benchmark::DoNotOptimize(srec.nis);
    ++k;
  }
  st.SetLabel("900 points, mode shapes given, 10 modes, joint");
}
BENCHMARK(BM_LibraryRangeImage)->Unit(benchmark::kMicrosecond);

}  // namespace
