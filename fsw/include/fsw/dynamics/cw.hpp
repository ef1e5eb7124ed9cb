// Clohessy-Wiltshire relative dynamics in the Hill frame
// (docs/CONVENTIONS.md): x radial (away from Earth), y along-track, z orbit normal.
//
//   xdd =  3 n^2 x + 2 n yd + ax
//   ydd = -2 n xd          + ay
//   zdd = -n^2 z           + az
//
// State [x y z xd yd zd]. Over a step t with acceleration a held constant:
//   s(t) = Phi(t) s(0) + Gamma(t) a,   Gamma(t) = int_0^t Phi(t - tau) B dtau.
// Phi is the closed form of eq. 6 of "Online Dynamic Modeling and Localization for Small-Spacecraft
// Proximity Operations" (Rogers-Marcovitz), with its two wrong entries
// corrected (xd row: 2 sin(nt) on yd0; yd row: 4 cos(nt) - 3 on yd0).
//
// Every coefficient is written through the cancellation-free functions
// below, so the float build keeps its accuracy when n t is small (n t is
// about 1e-4 at 10 Hz in low Earth orbit, where 1 - cos(n t) vanishes in
// float). Real-time core: no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <limits>

namespace fsw {

template <typename S>
using Vec6 = Eigen::Matrix<S, 6, 1>;
template <typename S>
using Mat6 = Eigen::Matrix<S, 6, 6>;
template <typename S>
using Mat63 = Eigen::Matrix<S, 6, 3>;

// Earth's gravitational parameter [m^3/s^2] (EGM96 / WGS-84).
constexpr double kMuEarth = 3.986004418e14;
// Earth's equatorial radius [m] (WGS-84).
constexpr double kEarthRadius = 6378137.0;

// Orbit rate [rad/s] of a circular orbit of radius a [m] (radius, not altitude).
template <typename S>
inline S orbit_rate(S radius_m, S mu = S(kMuEarth)) {
  return std::sqrt(mu / (radius_m * radius_m * radius_m));
}

namespace cw_detail {
// sin(x)/x
template <typename S>
inline S sinc(S x) {
  const S x2 = x * x;
  if (std::abs(x) < S(1e-2)) return S(1) - x2 / S(6) + x2 * x2 / S(120) - x2 * x2 * x2 / S(5040);
  return std::sin(x) / x;
}
// (1 - cos x) / x^2 = (sin(x/2) / (x/2))^2 / 2
template <typename S>
inline S one_minus_cos_x2(S x) {
  const S h = sinc(x / S(2));
  return h * h / S(2);
}
// (x - sin x) / x^3
template <typename S>
inline S x_minus_sin_x3(S x) {
  const S x2 = x * x;
  if (std::abs(x) < S(0.1)) {
    return S(1) / S(6) - x2 / S(120) + x2 * x2 / S(5040) - x2 * x2 * x2 / S(362880) + x2 * x2 * x2 * x2 / S(39916800);
  }
  return (x - std::sin(x)) / (x2 * x);
}
}  // namespace cw_detail

// Closed-form state transition matrix Phi(t) for orbit rate n [rad/s], t [s].
template <typename S>
inline Mat6<S> cw_stm(S n, S t) {
  using namespace cw_detail;
  const S x = n * t;
  const S c = std::cos(x);
  const S s = std::sin(x);
  const S omc = x * x * one_minus_cos_x2(x);             // 1 - cos(nt)
  const S s_over_n = t * sinc(x);                        // sin(nt)/n
  const S omc_over_n = n * t * t * one_minus_cos_x2(x);  // (1 - cos(nt))/n
  Mat6<S> P = Mat6<S>::Zero();
  // position rows
  P(0, 0) = S(1) + S(3) * omc;                      // 4 - 3C
  P(0, 3) = s_over_n;                               // S/n
  P(0, 4) = S(2) * omc_over_n;                      // 2(1-C)/n
  P(1, 0) = -S(6) * x * x * x * x_minus_sin_x3(x);  // 6(S - nt)
  P(1, 1) = S(1);
  P(1, 3) = -S(2) * omc_over_n;          // -2(1-C)/n
  P(1, 4) = S(4) * s_over_n - S(3) * t;  // 4S/n - 3t
  P(2, 2) = c;
  P(2, 5) = s_over_n;
  // velocity rows
  P(3, 0) = S(3) * n * s;  // 3 n S
  P(3, 3) = c;
  P(3, 4) = S(2) * s;         // 2 S (erratum of eq. 6)
  P(4, 0) = -S(6) * n * omc;  // -6 n (1-C)
  P(4, 3) = -S(2) * s;
  P(4, 4) = S(1) - S(4) * omc;  // 4C - 3 (erratum of eq. 6)
  P(5, 2) = -n * s;
  P(5, 5) = c;
  return P;
}

// Exact response Gamma(t) of the state to a Hill-frame acceleration [m/s^2]
// held constant over [0, t].
template <typename S>
inline Mat63<S> cw_accel_response(S n, S t) {
  using namespace cw_detail;
  const S x = n * t;
  const S t2 = t * t;
  const S f2 = one_minus_cos_x2(x);  // (1-C)/(nt)^2
  const S f3 = x_minus_sin_x3(x);    // (nt - S)/(nt)^3
  Mat63<S> G = Mat63<S>::Zero();
  // radial acceleration
  G(0, 0) = t2 * f2;                  // (1-C)/n^2
  G(1, 0) = -S(2) * n * t2 * t * f3;  // -2 (nt - S)/n^2
  G(3, 0) = t * sinc(x);              // S/n
  G(4, 0) = -S(2) * n * t2 * f2;      // -2 (1-C)/n
  // along-track acceleration
  G(0, 1) = S(2) * n * t2 * t * f3;         // 2 (nt - S)/n^2
  G(1, 1) = S(4) * t2 * f2 - S(1.5) * t2;   // 4(1-C)/n^2 - 3t^2/2
  G(3, 1) = S(2) * n * t2 * f2;             // 2 (1-C)/n
  G(4, 1) = S(4) * t * sinc(x) - S(3) * t;  // 4S/n - 3t
  // cross-track acceleration
  G(2, 2) = t2 * f2;      // (1-C)/n^2
  G(5, 2) = t * sinc(x);  // S/n
  return G;
}

// Fixed-step propagator: Phi and Gamma computed once at construction, so a
// step is two small matrix-vector products.
template <typename S>
class CwPropagator {
 public:
  using Vec3Type = Eigen::Matrix<S, 3, 1>;

  CwPropagator(S n_radps, S dt_s)
      : n_(n_radps), dt_(dt_s), phi_(cw_stm(n_radps, dt_s)), gamma_(cw_accel_response(n_radps, dt_s)) {}

  // State [r_hill_m; v_hill_mps], acceleration a_hill_mps2 held over the step.
  Vec6<S> step(const Vec6<S>& state, const Vec3Type& a_hill_mps2) const { return phi_ * state + gamma_ * a_hill_mps2; }
  Vec6<S> step(const Vec6<S>& state) const { return phi_ * state; }

  const Mat6<S>& stm() const { return phi_; }
  const Mat63<S>& accel_response() const { return gamma_; }
  S orbit_rate_radps() const { return n_; }
  S dt_s() const { return dt_; }

 private:
  S n_;
  S dt_;
  Mat6<S> phi_;
  Mat63<S> gamma_;
};

}  // namespace fsw
