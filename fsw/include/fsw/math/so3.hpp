// SO(3) on unit quaternions: exp, log, boxplus, boxminus, rotation matrices.
//
// Convention (docs/CONVENTIONS.md): Hamilton product; q rotates body vectors into the
// Hill frame (v_H = q * v_B * q^-1). Scalar-first [w, x, y, z] at every
// boundary; Eigen's coeffs() order [x, y, z, w] never leaves this header
// (to_wxyz / from_wxyz are the only conversions).
//
// Perturbations are local (body frame):  q [+] d = q * Exp(d),
//                                        q1 [-] q0 = Log(q0^-1 * q1).
// Real-time core: no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <limits>

namespace fsw {

template <typename S>
using Vec3 = Eigen::Matrix<S, 3, 1>;
template <typename S>
using Vec4 = Eigen::Matrix<S, 4, 1>;
template <typename S>
using Mat3 = Eigen::Matrix<S, 3, 3>;
template <typename S>
using Quat = Eigen::Quaternion<S>;

namespace so3_detail {
// Below this angle (rad) the series branches are used: the truncated terms are
// below machine epsilon relative to the kept ones.
template <typename S>
constexpr S small_angle() {
  return std::numeric_limits<S>::epsilon() > S(1e-10) ? S(1e-2) : S(1e-4);
}
}  // namespace so3_detail

template <typename S>
inline Mat3<S> skew(const Vec3<S>& v) {
  Mat3<S> m;
  m << S(0), -v.z(), v.y(), v.z(), S(0), -v.x(), -v.y(), v.x(), S(0);
  return m;
}

// Restores unit norm and picks the w >= 0 hemisphere. The one place where
// quaternions are normalised.
template <typename S>
inline Quat<S> normalized(const Quat<S>& q) {
  Quat<S> out = q;
  out.normalize();
  if (out.w() < S(0)) out.coeffs() = -out.coeffs();
  return out;
}

// Exp: rotation vector (rad) -> unit quaternion. The paper's eq. 3.
template <typename S>
inline Quat<S> exp(const Vec3<S>& phi) {
  const S theta2 = phi.squaredNorm();
  const S theta = std::sqrt(theta2);
  S w, k;  // k = sin(theta/2) / theta
  if (theta < so3_detail::small_angle<S>()) {
    w = S(1) - theta2 / S(8) + theta2 * theta2 / S(384);
    k = S(0.5) - theta2 / S(48) + theta2 * theta2 / S(3840);
  } else {
    w = std::cos(theta / S(2));
    k = std::sin(theta / S(2)) / theta;
  }
  return Quat<S>(w, k * phi.x(), k * phi.y(), k * phi.z());
}

// Log: unit quaternion -> rotation vector (rad), angle in [0, pi].
template <typename S>
inline Vec3<S> log(const Quat<S>& q_in) {
  Quat<S> q = q_in;
  if (q.w() < S(0)) q.coeffs() = -q.coeffs();  // shortest rotation
  const Vec3<S> v = q.vec();
  const S s = v.norm();
  S k;  // theta / sin(theta/2)
  if (s < so3_detail::small_angle<S>()) {
    // theta = 2 atan2(s, w); series in s with w ~ 1.
    const S w = q.w();
    k = S(2) / w - S(2) * s * s / (S(3) * w * w * w);
  } else {
    k = S(2) * std::atan2(s, q.w()) / s;
  }
  return k * v;
}

template <typename S>
inline Quat<S> boxplus(const Quat<S>& q, const Vec3<S>& d) {
  return normalized(Quat<S>(q * exp(d)));
}

template <typename S>
inline Vec3<S> boxminus(const Quat<S>& q1, const Quat<S>& q0) {
  return log(Quat<S>(q0.conjugate() * q1));
}

// Rotation matrix taking body vectors into the Hill frame.
template <typename S>
inline Mat3<S> rotation_matrix(const Quat<S>& q) {
  return q.toRotationMatrix();
}

// Boundary conversions, scalar first.
template <typename S>
inline Vec4<S> to_wxyz(const Quat<S>& q) {
  return Vec4<S>(q.w(), q.x(), q.y(), q.z());
}

template <typename S>
inline Quat<S> from_wxyz(const Vec4<S>& wxyz) {
  return Quat<S>(wxyz(0), wxyz(1), wxyz(2), wxyz(3));
}

// True when |q| is within tol of 1 and every component is finite.
template <typename S>
inline bool is_unit(const Vec4<S>& wxyz, S tol) {
  if (!wxyz.allFinite()) return false;
  return std::abs(wxyz.norm() - S(1)) <= tol;
}

}  // namespace fsw
