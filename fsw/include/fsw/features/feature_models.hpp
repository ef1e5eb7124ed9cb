// Image-feature observation models of the dual-quaternion
// feature paper (section 3): points (eq. 4),
// lines through the line point (eqs. 5-9), circles through the twist
// (eqs. 10-11), on a pinhole camera of focal length f.
//
// Frames (docs/FEATURES.md):
//   leader frame L  : the host's orbit (Hill) frame at its centre of mass;
//                     the leader body is held aligned with it (as in the paper).
//   lP              : the leader's feature frame, axes parallel to L, origin
//                     at p_l (leader frame) from the leader's centre of mass.
//                     Points, lines and circles are given in lP.
//   follower body F : principal axes at the follower's centre of mass.
//   camera fP       : axes parallel to F (x image horizontal, y image
//                     vertical, z optical axis), origin at the lens centre,
//                     p_f (body frame) from the follower's centre of mass.
// The relative pose is the dual quaternion Q_lf of the follower body in the
// leader frame: rotation q_lf (body vectors into L, the project's "q rotates
// body into Hill"), translation r_l = follower centre of mass in L. The
// camera sees the features through
//   Q_cl = (Q_lf (x) Q(p_f))^-1 (x) Q(p_l),
// so a camera away from the centre of mass couples rotation into
// translation: turning the follower about its centre of mass moves the
// camera by R dtheta x p_f (the paper's kinematic coupling).
//
// Models (d = point in the camera frame):
//   point  : d = Q_cl (1 + eps D) Q_cl_eps^*,   z = f [d_x / d_z, d_y / d_z]
//   line   : (l, m) Pluecker in lP (m = p x l), into the camera by
//            Q_cl (l + eps m) Q_cl^*; its image is the line m . [x, y, f] = 0
//            and the line point (foot of the perpendicular from the image
//            origin) is  z = -f m_z [m_x, m_y] / (m_x^2 + m_y^2).
//            The paper's eqs. 6 and 9 have +f m_z: that is the mirror image of
//            the foot through the origin (errata in docs/FEATURES.md).
//   circle : S_phi = q_phi (1 + eps S0) q_phi_eps^* with the zero-pitch screw
//            q_phi about the twist line (l_t, m_t), then the point model.
//
// Jacobians are analytic, with respect to the error
//   e = [dtheta (follower body, q_true = q_lf (x) Exp(dtheta)); dr (leader frame)]
// and, for circles, the circle angle phi. A model returns false (outputs
// unspecified) when the feature is not imageable: depth d_z <= min_depth, or
// a line whose plane through the lens centre is parallel to the image plane.
// Real-time core: fixed-size Eigen, no heap, no exceptions, no I/O.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "fsw/math/dual_quaternion.hpp"
#include "fsw/math/so3.hpp"

namespace fsw {

template <typename S>
using Vec2 = Eigen::Matrix<S, 2, 1>;
template <typename S>
using Mat26 = Eigen::Matrix<S, 2, 6>;

template <typename S>
struct CameraMount {
  S focal_m = S(0.5);                            // focal length f [m] (the paper's: 0.5 m)
  Vec3<S> camera_offset_f_m = Vec3<S>::Zero();   // p_f: lens centre from follower c.m., body frame [m]
  Vec3<S> feature_origin_l_m = Vec3<S>::Zero();  // p_l: lP origin from leader c.m., leader frame [m]
  S min_depth_m = S(1e-3);                       // a feature nearer the lens plane is not imageable [m]
};

// Q_cl: camera frame from the leader feature frame lP.
template <typename S>
inline DualQuat<S> camera_from_features(const DualQuat<S>& pose_lf, const CameraMount<S>& cam) {
  const DualQuat<S> Q_lc = pose_lf * DualQuat<S>::from_rotation_translation(Quat<S>::Identity(), cam.camera_offset_f_m);
  const DualQuat<S> Q_l_lp = DualQuat<S>::from_rotation_translation(Quat<S>::Identity(), cam.feature_origin_l_m);
  return inverse(Q_lc) * Q_l_lp;
}

// Pinhole projection z = f [x/z, y/z] and its derivative with respect to d.
template <typename S>
inline bool project(const Vec3<S>& d, S f, S min_depth, Vec2<S>& z, Eigen::Matrix<S, 2, 3>* dz_dd) {
  if (!(d.z() > min_depth)) return false;
  const S iz = S(1) / d.z();
  z << f * d.x() * iz, f * d.y() * iz;
  if (dz_dd != nullptr) {
    *dz_dd << f * iz, S(0), -f * d.x() * iz * iz, S(0), f * iz, -f * d.y() * iz * iz;
  }
  return true;
}

// Point feature D (lP frame) -> image coordinates z [m on the image plane].
// H: dz/de (2 x 6).
template <typename S>
inline bool point_model(const DualQuat<S>& pose_lf, const CameraMount<S>& cam, const Vec3<S>& D_lp, Vec2<S>& z,
                        Mat26<S>* H) {
  const DualQuat<S> Q_cl = camera_from_features(pose_lf, cam);
  const Vec3<S> d = transform_point(Q_cl, D_lp);
  Eigen::Matrix<S, 2, 3> J;
  if (!project(d, cam.focal_m, cam.min_depth_m, z, &J)) return false;
  if (H != nullptr) {
    const Mat3<S> Rt = pose_lf.real.toRotationMatrix().transpose();  // leader -> body
    H->template leftCols<3>() = J * skew(Vec3<S>(d + cam.camera_offset_f_m));
    H->template rightCols<3>() = -J * Rt;
  }
  return true;
}

// Line point of a Pluecker line in the camera frame, and dz/dm.
template <typename S>
inline bool line_point(const Vec3<S>& m, S f, Vec2<S>& z, Eigen::Matrix<S, 2, 3>* dz_dm) {
  const S rho = m.x() * m.x() + m.y() * m.y();
  if (!(rho > S(1e-6) * m.squaredNorm()) || !(rho > S(0))) return false;
  const S ir = S(1) / rho;
  z << -f * m.z() * m.x() * ir, -f * m.z() * m.y() * ir;
  if (dz_dm != nullptr) {
    const S ir2 = ir * ir;
    *dz_dm << -f * m.z() * ir + S(2) * f * m.x() * m.x() * m.z() * ir2, S(2) * f * m.x() * m.y() * m.z() * ir2,
        -f * m.x() * ir,  //
        S(2) * f * m.x() * m.y() * m.z() * ir2, -f * m.z() * ir + S(2) * f * m.y() * m.y() * m.z() * ir2,
        -f * m.y() * ir;
  }
  return true;
}

// Line feature (l unit direction, m = p x l; lP frame) -> line point z.
template <typename S>
inline bool line_model(const DualQuat<S>& pose_lf, const CameraMount<S>& cam, const Vec3<S>& l_lp, const Vec3<S>& m_lp,
                       Vec2<S>& z, Mat26<S>* H) {
  const DualQuat<S> Q_cl = camera_from_features(pose_lf, cam);
  Vec3<S> l_c, m_c;
  transform_line(Q_cl, l_lp, m_lp, l_c, m_c);
  Eigen::Matrix<S, 2, 3> J;
  if (!line_point(m_c, cam.focal_m, z, &J)) return false;
  if (H != nullptr) {
    // m_c = R^T u - p_f x l_c,  u = m + p_l x l - r x l  (moment about the camera, leader axes)
    const Mat3<S> Rt = pose_lf.real.toRotationMatrix().transpose();
    const Vec3<S> r = pose_lf.translation();
    const Vec3<S> u = m_lp + cam.feature_origin_l_m.cross(l_lp) - r.cross(l_lp);
    const Mat3<S> dm_dth = skew(Vec3<S>(Rt * u)) - skew(cam.camera_offset_f_m) * skew(l_c);
    const Mat3<S> dm_dr = Rt * skew(l_lp);
    H->template leftCols<3>() = J * dm_dth;
    H->template rightCols<3>() = J * dm_dr;
  }
  return true;
}

// Point of a circle: S0 turned by phi about the twist line (l_t unit, m_t = p x l_t),
// all in lP (the paper's eq. 10).
template <typename S>
inline Vec3<S> circle_point(const Vec3<S>& l_t, const Vec3<S>& m_t, const Vec3<S>& S0, S phi) {
  return transform_point(DualQuat<S>::from_screw_zero_pitch(l_t, m_t, phi), S0);
}

// Circle feature point at angle phi -> image coordinates (the paper's eq. 11).
// H: dz/de (2 x 6), h_phi: dz/dphi.
template <typename S>
inline bool circle_model(const DualQuat<S>& pose_lf, const CameraMount<S>& cam, const Vec3<S>& l_t, const Vec3<S>& m_t,
                         const Vec3<S>& S0, S phi, Vec2<S>& z, Mat26<S>* H, Vec2<S>* h_phi) {
  const Vec3<S> Sphi = circle_point(l_t, m_t, S0, phi);
  if (!point_model(pose_lf, cam, Sphi, z, H)) return false;
  if (h_phi != nullptr) {
    const DualQuat<S> Q_cl = camera_from_features(pose_lf, cam);
    const Vec3<S> d = transform_point(Q_cl, Sphi);
    Eigen::Matrix<S, 2, 3> J = Eigen::Matrix<S, 2, 3>::Zero();
    Vec2<S> zz;
    if (!project(d, cam.focal_m, cam.min_depth_m, zz, &J)) return false;
    const Vec3<S> axis_point = l_t.cross(m_t);  // foot of the axis from the lP origin
    const Vec3<S> dS_dphi = l_t.cross(Vec3<S>(Sphi - axis_point));
    *h_phi = J * (Q_cl.real.toRotationMatrix() * dS_dphi);
  }
  return true;
}

}  // namespace fsw
