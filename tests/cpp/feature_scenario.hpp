// The feature paper's scenario shared by the feature-filter tests: leader orbit
// a = 7200 km, e = 0.02; follower J = diag(522, 420, 600) kg m^2; f = 0.5 m;
// the feature paper's points D1-D4, lines L1-L4 and circles 1-2; a camera 1 m off the
// follower's centre of mass. Truth is stepped with a finer RK4 than the
// filters' and the image coordinates come from the models plus seeded noise.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "fsw/features/feature_filter.hpp"

namespace feature_scenario {

using namespace fsw;

template <typename S>
using Ekf = FeatureEkf<S, 4, 4, 2>;
template <typename S>
using Ukf = FeatureUkf<S, 4, 4, 2>;

template <typename S>
FeatureFilterConfig<S> config() {
  FeatureFilterConfig<S> c;
  c.camera.focal_m = S(0.5);
  c.camera.camera_offset_f_m = Vec3<S>(S(0.3), S(-0.2), S(1.0));
  c.camera.feature_origin_l_m = Vec3<S>(S(0), S(0), S(0.8));
  c.image_sigma_m = S(1e-5);
  return c;
}

// which: bit 0 points, bit 1 lines, bit 2 circles.
template <typename S>
typename Ekf<S>::Features features(int which = 7) {
  typename Ekf<S>::Features fs;
  const S h = S(std::sqrt(0.5));
  if (which & 1) {
    fs.n_points = 4;
    fs.point_lp_m = {Vec3<S>(1, 1, 0), Vec3<S>(-1, 1, 0), Vec3<S>(-1, -1, 0), Vec3<S>(1, -1, 0)};
  }
  if (which & 2) {
    fs.n_lines = 4;
    fs.line_dir_lp = {Vec3<S>(-1, 0, 0), Vec3<S>(0, -1, 0), Vec3<S>(1, 0, 0), Vec3<S>(0, 1, 0)};
    for (auto& m : fs.line_moment_lp_m) m = Vec3<S>(0, 0, 1);
  }
  if (which & 4) {
    fs.n_circles = 2;
    fs.circle_axis_lp = {Vec3<S>(0, h, h), Vec3<S>(1, 0, 0)};
    fs.circle_moment_lp_m = {Vec3<S>(-3, 1, -1), Vec3<S>(0, 1, 0)};
    fs.circle_start_lp_m = {Vec3<S>(1, 3, -2), Vec3<S>(2, 1, -1)};
  }
  return fs;
}

// True initial state: the leader feature origin seen at [-20, 35, 60] m in
// the camera, attitude 5.5 deg from the feature paper's first guess.
template <typename S>
typename Ekf<S>::State truth0() {
  const auto cfg = config<S>();
  typename Ekf<S>::State x;
  x.q_lf = fsw::exp(Vec3<S>(S(0.03), S(-0.05), S(0.08)));
  const Vec3<S> t_c(S(-20), S(35), S(60));
  x.r_l_m = cfg.camera.feature_origin_l_m - x.q_lf.toRotationMatrix() * (t_c + cfg.camera.camera_offset_f_m);
  x.w_fl_f_rps = Vec3<S>(S(2e-4), S(-1e-4), S(3e-4));
  const S n = cfg.leader.nu_dot(S(0));
  x.v_l_mps = Vec3<S>(S(0.01), S(-2) * n * x.r_l_m.x(), S(0.02));
  x.phi_rad << S(0.5), S(2.0), S(4.0), S(1.0), S(3.0), S(5.0);
  return x;
}

// The feature paper's first initial guess: identity attitude, leader origin at
// [-30, 45, 50] m in the camera, zero rates; circle angles 0.3 rad off.
template <typename S>
typename Ekf<S>::State guess1() {
  const auto cfg = config<S>();
  typename Ekf<S>::State x;
  x.q_lf = Quat<S>::Identity();
  const Vec3<S> t_c(S(-30), S(45), S(50));
  x.r_l_m = cfg.camera.feature_origin_l_m - (t_c + cfg.camera.camera_offset_f_m);
  x.phi_rad = truth0<S>().phi_rad + Eigen::Matrix<S, 6, 1>::Constant(S(0.3));
  return x;
}

// The feature paper's second (larger) initial guess.
template <typename S>
typename Ekf<S>::State guess2() {
  const auto cfg = config<S>();
  typename Ekf<S>::State x;
  x.q_lf = Quat<S>(S(0.9197), S(0.0265), S(0.0654), S(0.3861)).normalized();
  const Vec3<S> t_c(S(-60), S(80), S(100));
  x.r_l_m = cfg.camera.feature_origin_l_m - x.q_lf.toRotationMatrix() * (t_c + cfg.camera.camera_offset_f_m);
  x.phi_rad = truth0<S>().phi_rad + Eigen::Matrix<S, 6, 1>::Constant(S(0.3));
  return x;
}

template <typename S>
typename Ekf<S>::Cov P0(S pos_sigma = S(20), S att_sigma = S(0.2)) {
  typename Ekf<S>::Cov P = Ekf<S>::Cov::Zero();
  P.diagonal().template segment<3>(0).setConstant(att_sigma * att_sigma);
  P.diagonal().template segment<3>(3).setConstant(S(1e-6));
  P.diagonal().template segment<3>(6).setConstant(pos_sigma * pos_sigma);
  P.diagonal().template segment<3>(9).setConstant(S(1e-2));
  P.diagonal().template segment<6>(12).setConstant(S(0.25));
  return P;
}

// Truth stepper: RK4 at 0.05 s.
template <typename S>
void truth_step(typename Ekf<S>::State& x, S& nu, S dt) {
  const auto cfg = config<S>();
  const Mat3<S> J = cfg.inertia_f_kgm2.asDiagonal();
  const Mat3<S> Ji = cfg.inertia_f_kgm2.cwiseInverse().asDiagonal();
  RelVec<S> v;
  v << x.q_lf.w(), x.q_lf.x(), x.q_lf.y(), x.q_lf.z(), x.w_fl_f_rps, x.r_l_m, x.v_l_mps, nu;
  const int n = int(std::lround(double(dt) / 0.05));
  for (int k = 0; k < n; ++k) v = relative_rk4(v, dt / S(n), cfg.leader, J, Ji);
  x.q_lf = Quat<S>(v(0), v(1), v(2), v(3));
  x.w_fl_f_rps = v.template segment<3>(4);
  x.r_l_m = v.template segment<3>(7);
  x.v_l_mps = v.template segment<3>(10);
  nu = v(13);
}

// Noisy image coordinates of every configured feature at the true state.
template <typename S>
typename Ekf<S>::MeasVec measure(const typename Ekf<S>::State& x, const typename Ekf<S>::Features& fs,
                                 std::mt19937& rng) {
  const auto cfg = config<S>();
  std::normal_distribution<double> g(0.0, double(cfg.image_sigma_m));
  typename Ekf<S>::MeasVec z = Ekf<S>::MeasVec::Zero();
  const DualQuat<S> pose = x.pose_lf();
  Vec2<S> zz;
  for (int i = 0; i < fs.n_points; ++i) {
    point_model(pose, cfg.camera, fs.point_lp_m[i], zz, static_cast<Mat26<S>*>(nullptr));
    z.template segment<2>(2 * i) = zz;
  }
  for (int i = 0; i < fs.n_lines; ++i) {
    line_model(pose, cfg.camera, fs.line_dir_lp[i], fs.line_moment_lp_m[i], zz, static_cast<Mat26<S>*>(nullptr));
    z.template segment<2>(8 + 2 * i) = zz;
  }
  for (int c = 0; c < fs.n_circles; ++c)
    for (int s = 0; s < 3; ++s) {
      circle_model(pose, cfg.camera, fs.circle_axis_lp[c], fs.circle_moment_lp_m[c], fs.circle_start_lp_m[c],
                   x.phi_rad(3 * c + s), zz, static_cast<Mat26<S>*>(nullptr), static_cast<Vec2<S>*>(nullptr));
      z.template segment<2>(16 + 6 * c + 2 * s) = zz;
    }
  for (int i = 0; i < z.size(); ++i) z(i) += S(g(rng));
  return z;
}

}  // namespace feature_scenario
