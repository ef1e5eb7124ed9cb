// Six-degree-of-freedom relative motion of a follower with respect to a
// leader on an eccentric orbit (section 2 of the dual-quaternion paper on kinematically
// coupled relative dynamics and feature-based pose estimation), as the feature filters
// propagate it.
//
// The leader's body frame is held aligned with its orbit frame L (x radial,
// y along-track, z orbit normal; the Hill frame of docs/CONVENTIONS.md), which turns
// at the true-anomaly rate:
//   omega_l = [0, 0, nu_dot],  omega_l_dot = [0, 0, nu_ddot],
//   nu_dot = sqrt(mu / p^3) (1 + e cos nu)^2,  p = a (1 - e^2),
//   nu_ddot = -2 e sin(nu) nu_dot^2 / (1 + e cos nu),  r_L = p / (1 + e cos nu).
// State (follower centre of mass; the camera and feature points are placed
// by their offsets in feature_models.hpp, which is where the paper's
// kinematic rotation-translation coupling enters):
//   q_lf   follower body -> L (Hamilton),       q_dot = 1/2 q (x) w
//   w      omega_FL in the body frame [rad/s], the paper's relative rate
//          w_dot = omega_f_dot - R^T omega_l_dot + w x (R^T omega_l)
//          omega_f = w + R^T omega_l,  omega_f_dot = J^-1 (-omega_f x J omega_f)
//          (torque free: the paper's dual force holds gravity only)
//   r, v   follower centre of mass in L and its rate in L [m, m/s]: the
//          nonlinear equations of relative motion on an eccentric orbit,
//          gravity of both bodies (two-body), no linearisation:
//     x'' = 2 nu' y' + nu'' y + nu'^2 x - mu (r_L + x) / g^3 + mu / r_L^2
//     y'' = -2 nu' x' - nu'' x + nu'^2 y - mu y / g^3
//     z'' = -mu z / g^3,           g = |(r_L + x, y, z)|
// This is the paper's dual-number dynamics (eq. 3 onwards) written at the
// centres of mass: the dual velocity of a point frame is the centre-of-mass
// motion transported to the point, so the two carry the same physics.
// The differential gravity is evaluated without cancellation (float build).
// Integration: classical RK4 on [q, w, r, v, nu], q renormalised once per
// step. Jacobian: analytic continuous-time A over the error state
// [dtheta (body), dw, dr, dv] (q_true = q (x) Exp(dtheta)).
// Real-time core: fixed-size Eigen, no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "fsw/dynamics/cw.hpp"
#include "fsw/math/so3.hpp"

namespace fsw {

template <typename S>
struct LeaderOrbit {
  S a_m = S(7.2e6);  // semi-major axis [m] (the paper's: 7,200 km)
  S e = S(0.02);     // eccentricity (the paper's: 0.02)
  S mu_m3ps2 = S(kMuEarth);
  S p_m() const { return a_m * (S(1) - e * e); }
  S radius_m(S nu) const { return p_m() / (S(1) + e * std::cos(nu)); }
  S nu_dot(S nu) const {
    const S k = S(1) + e * std::cos(nu);
    const S p = p_m();
    return std::sqrt(mu_m3ps2 / (p * p * p)) * k * k;
  }
  S nu_ddot(S nu) const {
    const S nd = nu_dot(nu);
    return S(-2) * e * std::sin(nu) * nd * nd / (S(1) + e * std::cos(nu));
  }
  bool valid() const {
    return std::isfinite(a_m) && a_m > S(0) && std::isfinite(e) && e >= S(0) && e < S(1) && std::isfinite(mu_m3ps2) &&
           mu_m3ps2 > S(0);
  }
};

// Packed propagation vector [q_wxyz (4), w (3), r (3), v (3), nu (1)].
template <typename S>
using RelVec = Eigen::Matrix<S, 14, 1>;
template <typename S>
using Mat12 = Eigen::Matrix<S, 12, 12>;

// What the derivative and its Jacobian both read off the packed state: the
// leader frame's rate nd and acceleration ndd (true anomaly rates), and
// those rates in the follower body, b and c, with the inertial body rate wf.
template <typename S>
struct RelativeFrameTerms {
  Quat<S> q;
  Vec3<S> w, r;
  S nu = S(0), nd = S(0), ndd = S(0);
  Vec3<S> b, c, wf;
};

template <typename S>
inline RelativeFrameTerms<S> relative_frame_terms(const RelVec<S>& x, const LeaderOrbit<S>& orb) {
  RelativeFrameTerms<S> t;
  t.q = Quat<S>(x(0), x(1), x(2), x(3));
  t.w = x.template segment<3>(4);
  t.r = x.template segment<3>(7);
  t.nu = x(13);
  t.nd = orb.nu_dot(t.nu);
  t.ndd = orb.nu_ddot(t.nu);
  const Mat3<S> Rt = t.q.toRotationMatrix().transpose();
  t.b = Rt * Vec3<S>(S(0), S(0), t.nd);
  t.c = Rt * Vec3<S>(S(0), S(0), t.ndd);
  t.wf = t.w + t.b;
  return t;
}

template <typename S>
inline RelVec<S> relative_derivative(const RelVec<S>& x, const LeaderOrbit<S>& orb, const Mat3<S>& J,
                                     const Mat3<S>& J_inv) {
  const RelativeFrameTerms<S> t = relative_frame_terms(x, orb);
  const Quat<S>& q = t.q;
  const Vec3<S>& w = t.w;
  const Vec3<S>& r = t.r;
  const Vec3<S> v = x.template segment<3>(10);
  const S nu = t.nu, nd = t.nd, ndd = t.ndd;
  const Vec3<S>& b = t.b;
  const Vec3<S>& c = t.c;
  const Vec3<S>& wf = t.wf;
  const Vec3<S> wf_dot = -(J_inv * wf.cross(J * wf));
  RelVec<S> d;
  const Quat<S> qd = q * Quat<S>(S(0), w.x(), w.y(), w.z());
  d(0) = S(0.5) * qd.w();
  d(1) = S(0.5) * qd.x();
  d(2) = S(0.5) * qd.y();
  d(3) = S(0.5) * qd.z();
  d.template segment<3>(4) = wf_dot - c + w.cross(b);
  d.template segment<3>(7) = v;
  // Differential gravity without cancellation (the float build): with
  // u = r / r_L, s = 2 u_x + |u|^2 and f = (1 + s)^(-3/2) - 1,
  //   -mu (r_L + x) / g^3 + mu / r_L^2 = -(mu / r_L^2) (u_x + f + u_x f),
  //   -mu y / g^3 = -(mu / r_L^3) y (1 + f).
  const S rL = orb.radius_m(nu);
  const Vec3<S> u = r / rL;
  const S sdev = S(2) * u.x() + u.squaredNorm();
  const S f = std::expm1(S(-1.5) * std::log1p(sdev));
  const S k2 = orb.mu_m3ps2 / (rL * rL);
  const S k3 = k2 / rL;
  Vec3<S> a;
  a.x() = S(2) * nd * v.y() + ndd * r.y() + nd * nd * r.x() - k2 * (u.x() + f + u.x() * f);
  a.y() = S(-2) * nd * v.x() - ndd * r.x() + nd * nd * r.y() - k3 * r.y() * (S(1) + f);
  a.z() = -k3 * r.z() * (S(1) + f);
  d.template segment<3>(10) = a;
  d(13) = nd;
  return d;
}

// One RK4 step of length h [s]; the quaternion is renormalised at the end.
template <typename S>
inline RelVec<S> relative_rk4(const RelVec<S>& x, S h, const LeaderOrbit<S>& orb, const Mat3<S>& J,
                              const Mat3<S>& J_inv) {
  const RelVec<S> k1 = relative_derivative(x, orb, J, J_inv);
  const RelVec<S> k2 = relative_derivative(RelVec<S>(x + S(0.5) * h * k1), orb, J, J_inv);
  const RelVec<S> k3 = relative_derivative(RelVec<S>(x + S(0.5) * h * k2), orb, J, J_inv);
  const RelVec<S> k4 = relative_derivative(RelVec<S>(x + h * k3), orb, J, J_inv);
  RelVec<S> out = x + (h / S(6)) * (k1 + S(2) * k2 + S(2) * k3 + k4);
  Vec4<S> qv = out.template head<4>();
  qv /= qv.norm();
  if (qv(0) < S(0)) qv = -qv;
  out.template head<4>() = qv;
  return out;
}

// Continuous-time Jacobian over [dtheta, dw, dr, dv] at x.
template <typename S>
inline Mat12<S> relative_jacobian(const RelVec<S>& x, const LeaderOrbit<S>& orb, const Mat3<S>& J,
                                  const Mat3<S>& J_inv) {
  const RelativeFrameTerms<S> t = relative_frame_terms(x, orb);
  const Vec3<S>& w = t.w;
  const Vec3<S>& r = t.r;
  const S nu = t.nu, nd = t.nd, ndd = t.ndd;
  const Vec3<S>& b = t.b;
  const Vec3<S>& c = t.c;
  const Vec3<S>& wf = t.wf;
  const Mat3<S> E = J_inv * (skew(Vec3<S>(J * wf)) - skew(wf) * J);  // d omega_f_dot / d omega_f
  const Mat3<S> I = Mat3<S>::Identity();
  Mat12<S> A = Mat12<S>::Zero();
  A.template block<3, 3>(0, 0) = -skew(w);
  A.template block<3, 3>(0, 3) = I;
  A.template block<3, 3>(3, 0) = E * skew(b) - skew(c) + skew(w) * skew(b);
  A.template block<3, 3>(3, 3) = E - skew(b);
  A.template block<3, 3>(6, 9) = I;
  const S rL = orb.radius_m(nu);
  const Vec3<S> rho(rL + r.x(), r.y(), r.z());
  const S g2 = rho.squaredNorm();
  const S g = std::sqrt(g2);
  const S mg3 = orb.mu_m3ps2 / (g2 * g);
  Mat3<S> G = -mg3 * (I - S(3) * rho * rho.transpose() / g2);
  G(0, 0) += nd * nd;
  G(1, 1) += nd * nd;
  G(0, 1) += ndd;
  G(1, 0) -= ndd;
  A.template block<3, 3>(9, 6) = G;
  A(9, 10) = S(2) * nd;
  A(10, 9) = S(-2) * nd;
  return A;
}

}  // namespace fsw
