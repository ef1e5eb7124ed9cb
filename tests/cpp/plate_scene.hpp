// The range-image paper's plate vibrating (bench/sim/structure.py's Plate, 10 modes), seen
// as range images for the modal tests: random amplitudes in [0, 1] and
// phases, n x n points over the central quarter, 3 % range noise at 600 m.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "fsw/math/so3.hpp"
#include "fsw/modal/plate_modes.hpp"

namespace plate_scene {

using fsw::PlateModes;
using fsw::Vec3;

constexpr int kM = 10;
constexpr double kDt = 60.0;           // one image per minute
constexpr double kSigma = 0.03 * 600;  // 3 % range noise at 600 m [m]

struct PlateScene {
  PlateModes<double, kM> truth;
  double amp[kM], phase[kM];
  std::mt19937_64 rng;
  std::normal_distribution<double> nd{0.0, 1.0};

  explicit PlateScene(unsigned seed) : rng(seed) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int i = 0; i < kM; ++i) {
      amp[i] = u(rng);
      phase[i] = 2.0 * 3.14159265358979323846 * u(rng);
    }
  }
  double coeff(int i, double t) const { return amp[i] * std::sin(truth.omega_radps(i) * t + phase[i]); }
  void image(double t, std::vector<Vec3<double>>& p, std::vector<double>& sig, int n_side = 30) {
    p.clear();
    sig.clear();
    const double lx = truth.config().lx_m, ly = truth.config().ly_m;
    double phi[kM] = {};
    for (int r = 0; r < n_side; ++r)
      for (int c = 0; c < n_side; ++c) {
        const double x = lx * (0.25 + 0.5 * (c + 0.5) / n_side), y = ly * (0.25 + 0.5 * (r + 0.5) / n_side);
        truth.phi(x, y, phi);
        double z = 0.0;
        for (int i = 0; i < kM; ++i) z += coeff(i, t) * phi[i];
        p.emplace_back(x, y, z + kSigma * nd(rng));
        sig.push_back(kSigma);
      }
  }
};

}  // namespace plate_scene
