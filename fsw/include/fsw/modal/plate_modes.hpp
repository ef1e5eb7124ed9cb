// Mode shapes and frequencies of a simply supported rectangular plate: the
// structure model the flight modal estimator evaluates at each range-image
// point (the same model as the bench's Plate, bench/sim/structure.py).
//
//   Phi_pq(x, y) = s_pq sin(p pi x / Lx) sin(q pi y / Ly)        [m per unit coefficient]
//   omega_pq     = omega_11 k_pq / k_11,  k_pq = (p / Lx)^2 + (q / Ly)^2
//   s_pq         = peak_11 omega_11 / omega_pq   (energy normalised: omega^2 s^2 equal)
//
// The M modes kept are the M lowest in k (ties in p-major order, p, q <=
// kMaxIndex), chosen once at configuration. x, y in the structure frame
// (origin at a corner, plate in the x-y plane), deflection along z.
// Real-time core: fixed-size, no heap, no exceptions, no I/O; phi() is
// bounded by M.
#pragma once

#include <cmath>
#include <cstdint>

namespace fsw {

struct PlateModelConfig {
  double lx_m = 2000.0;       // plate side along x [m]
  double ly_m = 1732.0;       // plate side along y [m]
  double period1_s = 2400.0;  // period of the lowest mode [s]
  double peak1_m = 25.0;      // peak deflection of the lowest mode at coefficient 1 [m]
};

// Name of the first invalid field, or nullptr.
inline const char* plate_config_invalid_field(const PlateModelConfig& c) {
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!pos(c.lx_m)) return "lx_m";
  if (!pos(c.ly_m)) return "ly_m";
  if (!pos(c.period1_s)) return "period1_s";
  if (!pos(c.peak1_m)) return "peak1_m";
  return nullptr;
}

template <typename S, int M>
class PlateModes {
  static_assert(M >= 1, "at least one mode");

 public:
  static constexpr int kMaxIndex = 39;  // p, q in 1..kMaxIndex (1521 candidates)
  static_assert(M <= kMaxIndex * kMaxIndex, "more modes than candidates");

  // Returns false (and keeps the previous model) for an invalid config.
  bool configure(const PlateModelConfig& cfg) {
    if (plate_config_invalid_field(cfg) != nullptr) return false;
    cfg_ = cfg;
    const double ilx2 = 1.0 / (cfg.lx_m * cfg.lx_m), ily2 = 1.0 / (cfg.ly_m * cfg.ly_m);
    auto k_of = [&](int p, int q) { return double(p) * double(p) * ilx2 + double(q) * double(q) * ily2; };
    // The next mode is the smallest k above the previous one (ties: the next
    // candidate after it in p-major order). M passes over the candidates.
    double k_prev = -1.0;
    int idx_prev = -1;
    for (int m = 0; m < M; ++m) {
      double k_best = 0.0;
      int idx_best = -1;
      for (int idx = 0; idx < kMaxIndex * kMaxIndex; ++idx) {
        const double k = k_of(idx / kMaxIndex + 1, idx % kMaxIndex + 1);
        const bool after_prev = k > k_prev || (k == k_prev && idx > idx_prev);
        if (after_prev && (idx_best < 0 || k < k_best)) {
          k_best = k;
          idx_best = idx;
        }
      }
      p_[m] = idx_best / kMaxIndex + 1;
      q_[m] = idx_best % kMaxIndex + 1;
      k_[m] = k_best;
      k_prev = k_best;
      idx_prev = idx_best;
    }
    p_max_ = q_max_ = 1;
    for (int m = 0; m < M; ++m) {
      p_max_ = p_[m] > p_max_ ? p_[m] : p_max_;
      q_max_ = q_[m] > q_max_ ? q_[m] : q_max_;
    }
    const double w1 = 2.0 * 3.14159265358979323846 / cfg.period1_s;
    for (int m = 0; m < M; ++m) {
      omega_[m] = w1 * k_[m] / k_[0];
      scale_[m] = cfg.peak1_m * w1 / omega_[m];
    }
    return true;
  }

  PlateModes() { configure(PlateModelConfig()); }

  const PlateModelConfig& config() const { return cfg_; }
  int p(int m) const { return p_[m]; }
  int q(int m) const { return q_[m]; }
  S omega_radps(int m) const { return S(omega_[m]); }
  S scale_m(int m) const { return S(scale_[m]); }

  bool inside(S x, S y) const { return x >= S(0) && x <= S(cfg_.lx_m) && y >= S(0) && y <= S(cfg_.ly_m); }

  // Mode-shape values at (x, y) into phi[0..M). False (phi untouched) when
  // the point is not finite or off the plate.
  bool phi(S x, S y, S* phi_out) const {
    if (!std::isfinite(x) || !std::isfinite(y) || !inside(x, y)) return false;
    const S pi = S(3.14159265358979323846);
    S sx[kMaxIndex + 1], sy[kMaxIndex + 1];
    harmonics(pi * x / S(cfg_.lx_m), p_max_, sx);
    harmonics(pi * y / S(cfg_.ly_m), q_max_, sy);
    for (int m = 0; m < M; ++m) phi_out[m] = S(scale_[m]) * sx[p_[m]] * sy[q_[m]];
    return true;
  }

 private:
  // s[k] = sin(k u) for k = 1..n by the Chebyshev recurrence
  // sin((k+1) u) = 2 cos(u) sin(k u) - sin((k-1) u): two library calls per
  // axis instead of one per mode and axis (the image's cost was in std::sin).
  static void harmonics(S u, int n, S* s) {
    const S c2 = S(2) * std::cos(u);
    s[0] = S(0);
    s[1] = std::sin(u);
    for (int k = 1; k < n; ++k) s[k + 1] = c2 * s[k] - s[k - 1];
  }

  PlateModelConfig cfg_;
  int p_[M] = {};
  int p_max_ = 1, q_max_ = 1;  // highest p and q among the modes kept
  int q_[M] = {};
  double k_[M] = {};
  double omega_[M] = {};
  double scale_[M] = {};
};

}  // namespace fsw
