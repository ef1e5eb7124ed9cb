// State layout of the navigation filter, as data.
//
// Stored (nominal) state: r_hill_m (3), v_hill_mps (3), q_hb (4, [w x y z])
// and, with the bias option, gyro bias (3) and accelerometer bias (3).
// Error state (covariance): dr (3), dv (3), dtheta (3, body-frame attitude
// error, q_true = q_est * Exp(dtheta)) and the optional biases (3 + 3).
// The stored size keeps the quaternion's 4 numbers, the error size its 3
// degrees of freedom; both are static_asserted below.
// Real-time core: no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>

#include "fsw/math/so3.hpp"

namespace fsw {

struct StateBlock {
  int index;
  int size;
  constexpr int end() const { return index + size; }
};

template <bool kWithBias>
struct NavLayout {
  static constexpr int kBiasSize = kWithBias ? 3 : 0;

  // Stored state.
  static constexpr StateBlock kPos{0, 3};
  static constexpr StateBlock kVel{kPos.end(), 3};
  static constexpr StateBlock kQuat{kVel.end(), 4};
  static constexpr StateBlock kGyroBias{kQuat.end(), kBiasSize};
  static constexpr StateBlock kAccelBias{kGyroBias.end(), kBiasSize};
  static constexpr int kStoredSize = kAccelBias.end();

  // Error state (covariance).
  static constexpr StateBlock kDPos{0, 3};
  static constexpr StateBlock kDVel{kDPos.end(), 3};
  static constexpr StateBlock kDTheta{kDVel.end(), 3};
  static constexpr StateBlock kDGyroBias{kDTheta.end(), kBiasSize};
  static constexpr StateBlock kDAccelBias{kDGyroBias.end(), kBiasSize};
  static constexpr int kErrorSize = kDAccelBias.end();

  static_assert(kStoredSize == (kWithBias ? 16 : 10), "stored state: r, v, q(4) [, b_g, b_a]");
  static_assert(kErrorSize == (kWithBias ? 15 : 9), "error state: dr, dv, dtheta(3) [, db_g, db_a]");
  static_assert(kStoredSize == kErrorSize + 1, "only the quaternion differs: 4 stored, 3 in covariance");
  static_assert(kQuat.size == 4 && kDTheta.size == 3, "attitude: quaternion stored, rotation vector error");
};

// Nominal state. Without the bias option the bias members stay zero and are
// not part of the error state.
template <typename S, bool kWithBias>
struct NavState {
  using Layout = NavLayout<kWithBias>;
  using ErrVec = Eigen::Matrix<S, Layout::kErrorSize, 1>;
  using StoredVec = Eigen::Matrix<S, Layout::kStoredSize, 1>;

  Vec3<S> r_hill_m = Vec3<S>::Zero();
  Vec3<S> v_hill_mps = Vec3<S>::Zero();
  Quat<S> q_hb = Quat<S>::Identity();
  Vec3<S> gyro_bias_rps = Vec3<S>::Zero();
  Vec3<S> accel_bias_mps2 = Vec3<S>::Zero();

  // x [+] dx: additive on vectors, q * Exp(dtheta) on the attitude.
  NavState plus(const ErrVec& dx) const {
    NavState out = *this;
    out.r_hill_m += dx.template segment<3>(Layout::kDPos.index);
    out.v_hill_mps += dx.template segment<3>(Layout::kDVel.index);
    out.q_hb = boxplus(q_hb, Vec3<S>(dx.template segment<3>(Layout::kDTheta.index)));
    if constexpr (kWithBias) {
      out.gyro_bias_rps += dx.template segment<3>(Layout::kDGyroBias.index);
      out.accel_bias_mps2 += dx.template segment<3>(Layout::kDAccelBias.index);
    }
    return out;
  }

  // plus() without the attitude (the caller sets q_hb).
  NavState plus_vectors(const ErrVec& dx) const {
    NavState out = *this;
    out.r_hill_m += dx.template segment<3>(Layout::kDPos.index);
    out.v_hill_mps += dx.template segment<3>(Layout::kDVel.index);
    if constexpr (kWithBias) {
      out.gyro_bias_rps += dx.template segment<3>(Layout::kDGyroBias.index);
      out.accel_bias_mps2 += dx.template segment<3>(Layout::kDAccelBias.index);
    }
    return out;
  }

  // x [-] x0, so that x0.plus(x.minus(x0)) == x.
  ErrVec minus(const NavState& x0) const {
    ErrVec d;
    d.template segment<3>(Layout::kDPos.index) = r_hill_m - x0.r_hill_m;
    d.template segment<3>(Layout::kDVel.index) = v_hill_mps - x0.v_hill_mps;
    d.template segment<3>(Layout::kDTheta.index) = boxminus(q_hb, x0.q_hb);
    if constexpr (kWithBias) {
      d.template segment<3>(Layout::kDGyroBias.index) = gyro_bias_rps - x0.gyro_bias_rps;
      d.template segment<3>(Layout::kDAccelBias.index) = accel_bias_mps2 - x0.accel_bias_mps2;
    }
    return d;
  }

  // Stored layout, quaternion scalar first.
  StoredVec stored() const {
    StoredVec s;
    s.template segment<3>(Layout::kPos.index) = r_hill_m;
    s.template segment<3>(Layout::kVel.index) = v_hill_mps;
    s.template segment<4>(Layout::kQuat.index) = to_wxyz(q_hb);
    if constexpr (kWithBias) {
      s.template segment<3>(Layout::kGyroBias.index) = gyro_bias_rps;
      s.template segment<3>(Layout::kAccelBias.index) = accel_bias_mps2;
    }
    return s;
  }

  bool all_finite() const {
    return r_hill_m.allFinite() && v_hill_mps.allFinite() && q_hb.coeffs().allFinite() && gyro_bias_rps.allFinite() &&
           accel_bias_mps2.allFinite();
  }
};

}  // namespace fsw
