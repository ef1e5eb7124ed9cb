// Attitude kinematics of q_HB (body -> Hill) from gyro samples.
//
// Gyros measure omega_BI_B, the body rate with respect to inertial space.
// The Hill frame turns at the orbit rate n about its own z axis, so
//   q_HB(t + dt) = Exp(-n z_H dt) * q_HB(t) * Exp(omega_BI_B dt),
// which is exact when omega_BI_B is constant over the step (the two
// rotations act on opposite sides and commute). It replaces eq. 7 of
// "Online Dynamic Modeling and Localization for Small-Spacecraft Proximity Operations" (Rogers-Marcovitz),
// which applies a 3x3 skew matrix to a 4-component quaternion.
#pragma once

#include "fsw/math/so3.hpp"

namespace fsw {

// Rotation over one step of the Hill frame with respect to inertial space.
template <typename S>
inline Quat<S> hill_frame_step(S n_radps, S dt_s) {
  return exp(Vec3<S>(S(0), S(0), -n_radps * dt_s));
}

template <typename S>
inline Quat<S> propagate_attitude(const Quat<S>& q_hb, const Vec3<S>& omega_bi_b_rps, S dt_s,
                                  const Quat<S>& hill_step) {
  return normalized(Quat<S>(hill_step * q_hb * exp(Vec3<S>(omega_bi_b_rps * dt_s))));
}

template <typename S>
inline Quat<S> propagate_attitude(const Quat<S>& q_hb, const Vec3<S>& omega_bi_b_rps, S n_radps, S dt_s) {
  return propagate_attitude(q_hb, omega_bi_b_rps, dt_s, hill_frame_step(n_radps, dt_s));
}

}  // namespace fsw
