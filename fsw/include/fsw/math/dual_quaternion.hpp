// Unit dual quaternions for rigid motions (section 2 of the
// dual-quaternion paper on kinematically coupled relative dynamics and
// feature-based pose estimation).
//
//   Q = r + eps d,   d = 1/2 t (x) r,
//
// r a unit Hamilton quaternion, t the translation as a pure quaternion, both
// in the parent frame: Q maps child-frame points x to parent-frame points
// R(r) x + t. Products compose like frame transforms: Q_ab (x) Q_bc = Q_ac.
// Scalar-first [w, x, y, z] at every boundary (to_wxyz8 / from_wxyz8 only);
// Eigen's coeffs() order never leaves this header.
//
// Two conjugates (both needed, and easy to confuse):
//   conjugate(Q)      = r* + eps d*     the inverse of a unit Q; transforms
//                                       lines:  Q (l + eps m) conjugate(Q)
//   dual_conjugate(Q) = r* - eps d*     with conjugate(): transforms points
//                                       Q (1 + eps x) conjugate(dual_conjugate(Q))
//                                       (the paper's eq. 4 q_eps^*).
// Lines are Pluecker pairs (l unit direction, m = p x l for any point p on
// the line); a zero-pitch screw about such a line by an angle phi is
//   cos(phi/2) + sin(phi/2) (l + eps m)          (the paper's eq. 10)
// in this convention (d = sin(phi/2) m is 1/2 (p - R p) r written out).
// exp / log map twists xi = [omega; v] (rad, m; parent frame, the motion
// exp(xi) = pure rotation by omega about the origin after its screw motion)
// with small-angle branches.
// Real-time core: fixed-size Eigen, no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "fsw/math/so3.hpp"

namespace fsw {

template <typename S>
using Vec8 = Eigen::Matrix<S, 8, 1>;

template <typename S>
struct DualQuat {
  Quat<S> real = Quat<S>::Identity();              // rotation part r (unit)
  Quat<S> dual = Quat<S>(S(0), S(0), S(0), S(0));  // d = 1/2 t r

  static DualQuat identity() { return DualQuat(); }

  // Rigid motion x -> R(q) x + t.
  static DualQuat from_rotation_translation(const Quat<S>& q, const Vec3<S>& t) {
    DualQuat out;
    out.real = q;
    const Quat<S> tq(S(0), t.x(), t.y(), t.z());
    out.dual.coeffs() = S(0.5) * (tq * q).coeffs();
    return out;
  }

  // Zero-pitch screw: rotation by angle about the line (l unit, m = p x l).
  static DualQuat from_screw_zero_pitch(const Vec3<S>& l, const Vec3<S>& m, S angle) {
    const S c = std::cos(angle / S(2));
    const S s = std::sin(angle / S(2));
    DualQuat out;
    out.real = Quat<S>(c, s * l.x(), s * l.y(), s * l.z());
    out.dual = Quat<S>(S(0), s * m.x(), s * m.y(), s * m.z());
    return out;
  }

  Quat<S> rotation() const { return real; }

  // t = 2 d r*
  Vec3<S> translation() const { return S(2) * Quat<S>(dual * real.conjugate()).vec(); }

  bool all_finite() const { return real.coeffs().allFinite() && dual.coeffs().allFinite(); }
};

template <typename S>
inline DualQuat<S> operator*(const DualQuat<S>& a, const DualQuat<S>& b) {
  DualQuat<S> out;
  out.real = a.real * b.real;
  out.dual.coeffs() = (a.real * b.dual).coeffs() + (a.dual * b.real).coeffs();
  return out;
}

// r* + eps d*: the inverse of a unit dual quaternion.
template <typename S>
inline DualQuat<S> conjugate(const DualQuat<S>& a) {
  DualQuat<S> out;
  out.real = a.real.conjugate();
  out.dual = a.dual.conjugate();
  return out;
}

// r - eps d (the dual-number conjugate; sign flip of the dual part).
template <typename S>
inline DualQuat<S> dual_conjugate(const DualQuat<S>& a) {
  DualQuat<S> out;
  out.real = a.real;
  out.dual.coeffs() = -a.dual.coeffs();
  return out;
}

template <typename S>
inline DualQuat<S> inverse(const DualQuat<S>& a) {
  return conjugate(a);
}

// x -> R x + t by the sandwich Q (1 + eps x) (r* - eps d*).
template <typename S>
inline Vec3<S> transform_point(const DualQuat<S>& Q, const Vec3<S>& x) {
  DualQuat<S> X;
  X.real = Quat<S>::Identity();
  X.dual = Quat<S>(S(0), x.x(), x.y(), x.z());
  const DualQuat<S> out = Q * X * conjugate(dual_conjugate(Q));
  return out.dual.vec();
}

// Pluecker line (l, m = p x l) into the parent frame: Q (l + eps m) Q*.
// Result: l' = R l, m' = R m + t x R l.
template <typename S>
inline void transform_line(const DualQuat<S>& Q, const Vec3<S>& l, const Vec3<S>& m, Vec3<S>& l_out, Vec3<S>& m_out) {
  DualQuat<S> L;
  L.real = Quat<S>(S(0), l.x(), l.y(), l.z());
  L.dual = Quat<S>(S(0), m.x(), m.y(), m.z());
  const DualQuat<S> out = Q * L * conjugate(Q);
  l_out = out.real.vec();
  m_out = out.dual.vec();
}

// Restores |r| = 1, r . d = 0 and the w >= 0 hemisphere (the one place).
template <typename S>
inline DualQuat<S> normalized(const DualQuat<S>& a) {
  DualQuat<S> out;
  const S n = a.real.norm();
  out.real.coeffs() = a.real.coeffs() / n;
  out.dual.coeffs() = a.dual.coeffs() / n;
  // Remove the component of d along r (keeps the translation of the unit part).
  out.dual.coeffs() -= out.real.coeffs().dot(out.dual.coeffs()) * out.real.coeffs();
  if (out.real.w() < S(0)) {
    out.real.coeffs() = -out.real.coeffs();
    out.dual.coeffs() = -out.dual.coeffs();
  }
  return out;
}

// Exp of a twist xi = [omega; v]: r = Exp(omega), t = V(omega) v with
// V = I + (1 - cos th)/th^2 [w]x + (th - sin th)/th^3 [w]x^2 (SE(3) exp).
template <typename S>
inline DualQuat<S> exp(const Eigen::Matrix<S, 6, 1>& xi) {
  const Vec3<S> w = xi.template head<3>();
  const Vec3<S> v = xi.template tail<3>();
  const S th2 = w.squaredNorm();
  const S th = std::sqrt(th2);
  S a, b;             // (1 - cos th)/th^2, (th - sin th)/th^3
  if (th < S(0.1)) {  // series: the closed forms cancel badly for small th
    const S th4 = th2 * th2;
    a = S(0.5) - th2 / S(24) + th4 / S(720) - th4 * th2 / S(40320) + th4 * th4 / S(3628800);
    b = S(1) / S(6) - th2 / S(120) + th4 / S(5040) - th4 * th2 / S(362880) + th4 * th4 / S(39916800);
  } else {
    a = (S(1) - std::cos(th)) / th2;
    b = (th - std::sin(th)) / (th2 * th);
  }
  const Mat3<S> W = skew(w);
  const Vec3<S> t = v + a * (W * v) + b * (W * (W * v));
  return DualQuat<S>::from_rotation_translation(fsw::exp(w), t);
}

// Log: inverse of exp for rotation angles in [0, pi).
template <typename S>
inline Eigen::Matrix<S, 6, 1> log(const DualQuat<S>& Q) {
  const Vec3<S> w = fsw::log(Q.real);
  const Vec3<S> t = Q.translation();
  const S th2 = w.squaredNorm();
  const S th = std::sqrt(th2);
  S c;  // V^-1 = I - 1/2 [w]x + c [w]x^2, c = (1 - th sin th / (2 (1 - cos th))) / th^2
  if (th < S(0.1)) {
    c = S(1) / S(12) + th2 / S(720) + th2 * th2 / S(30240) + th2 * th2 * th2 / S(1209600);
  } else {
    c = (S(1) - th * std::sin(th) / (S(2) * (S(1) - std::cos(th)))) / th2;
  }
  const Mat3<S> W = skew(w);
  Eigen::Matrix<S, 6, 1> xi;
  xi.template head<3>() = w;
  xi.template tail<3>() = t - S(0.5) * (W * t) + c * (W * (W * t));
  return xi;
}

// Boundary conversions: [rw, rx, ry, rz, dw, dx, dy, dz].
template <typename S>
inline Vec8<S> to_wxyz8(const DualQuat<S>& Q) {
  Vec8<S> out;
  out << Q.real.w(), Q.real.x(), Q.real.y(), Q.real.z(), Q.dual.w(), Q.dual.x(), Q.dual.y(), Q.dual.z();
  return out;
}

template <typename S>
inline DualQuat<S> from_wxyz8(const Vec8<S>& v) {
  DualQuat<S> Q;
  Q.real = Quat<S>(v(0), v(1), v(2), v(3));
  Q.dual = Quat<S>(v(4), v(5), v(6), v(7));
  return Q;
}

}  // namespace fsw
